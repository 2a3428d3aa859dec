"""The fourbar_node parameter table: the one definition the node declares and the YAML loader checks (no ROS).

Metres, radians, N m, kg, s; docs/reference/parameters.md is generated from it."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

from fourbar_ros.core.antenna import Branch, Driven
from fourbar_ros.interface.topics import (
    DEFAULT_CONTROLLER_MANAGER,
    DEFAULT_FORWARD_CONTROLLER,
    DEFAULT_TRAJECTORY_CONTROLLER,
    Mode,
)

ParamValue = float | int | str | bool | list[str]

#: The smallest |reducer_ratio| accepted (the ratio's sign gives the motor's direction).
MIN_REDUCTION = 1e-6

#: rclpy accepts a double at a range edge when ``math.isclose(value, edge, rel_tol=1e-6)``
#: (``Node.PARAM_REL_TOL``); the config loader uses the same tolerance at the spec's edges.
RANGE_REL_TOL = 1e-6


@dataclass(frozen=True)
class ParamSpec:
    """One node parameter: ROS name, Python type, default, unit, description and allowed values.

    ``minimum``/``maximum`` are inclusive bounds for numbers (``None``: unbounded);
    ``choices`` lists the allowed strings of an enumeration (empty: any non-empty string).
    ``read_only`` parameters can only be set at startup.
    ``field`` names the ``AntennaConfig`` attribute holding the value (default: the parameter's name);
    ``decode``/``encode`` convert between the ROS value and that attribute's type (default: the same value).
    """

    name: str
    type: type
    default: ParamValue
    unit: str
    description: str
    minimum: float | None = None
    maximum: float | None = None
    choices: tuple[str, ...] = ()
    read_only: bool = False
    field: str = ''
    decode: Callable[[ParamValue], object] | None = None
    encode: Callable[[object], ParamValue] | None = None

    @property
    def attribute(self) -> str:
        """The ``AntennaConfig`` attribute of this parameter."""
        return self.field or self.name

    def to_attribute(self, value: ParamValue) -> object:
        """The checked ROS value as the configuration holds it (e.g. ``'gamma'`` -> ``Driven.GAMMA``)."""
        return value if self.decode is None else self.decode(value)

    def to_value(self, attribute: object) -> ParamValue:
        """The configuration's attribute as the ROS parameter value (inverse of ``to_attribute``)."""
        return attribute if self.encode is None else self.encode(attribute)  # type: ignore[return-value]

    def describe(self) -> str:
        """One-line description with unit and allowed values (the ROS descriptor's text)."""
        parts = [self.description]
        if self.unit:
            parts.append(f'[{self.unit}]')
        if self.choices:
            parts.append('one of: ' + ', '.join(self.choices))
        return ' '.join(parts)


def _driven(value: ParamValue) -> Driven:
    return Driven(value)


def _driven_value(driven: object) -> ParamValue:
    if not isinstance(driven, Driven):
        raise TypeError(f'expected a Driven, got {driven!r}')
    return driven.value


def _branch(value: ParamValue) -> Branch:
    return Branch[str(value).upper()]


def _branch_value(branch: object) -> ParamValue:
    if not isinstance(branch, Branch):
        raise TypeError(f'expected a Branch, got {branch!r}')
    return branch.name.lower()


def _string_tuple(value: ParamValue) -> tuple[str, ...]:
    return tuple(value) if isinstance(value, list) else (str(value),)


def _string_list(value: object) -> ParamValue:
    if not isinstance(value, tuple):
        raise TypeError(f'expected a tuple of strings, got {value!r}')
    return [str(v) for v in value]


# Angle defaults are the correctly rounded doubles of -6, +7 and 30 degrees.
PARAMETERS: tuple[ParamSpec, ...] = (
    ParamSpec('frame_length', float, 0.180, 'm',
              'Frame AD: distance between the fixed pivots A and D.', 1e-6, 100.0),
    ParamSpec('rocker_ab_length', float, 0.060, 'm',
              'Rocker AB (angle gamma at A, from the frame).', 1e-6, 100.0),
    ParamSpec('coupler_length', float, 0.102, 'm',
              'Coupler BC carrying the antenna (angle theta, positive tilts the antenna down).',
              1e-6, 100.0),
    ParamSpec('rocker_cd_length', float, 0.060, 'm',
              'Rocker CD (angle delta at D, from the frame).', 1e-6, 100.0),
    ParamSpec('theta_min', float, -0.10471975511965978, 'rad',
              'Lowest accepted antenna angle command (must be reachable, < theta_max).',
              -math.pi, math.pi),
    ParamSpec('theta_max', float, 0.12217304763960307, 'rad',
              'Highest accepted antenna angle command (must be reachable, > theta_min).',
              -math.pi, math.pi),
    ParamSpec('driven_rocker', str, 'gamma', '',
              'Rocker driven by the reducer: gamma (AB, at A) or delta (CD, at D).',
              choices=('gamma', 'delta'), field='driven', decode=_driven, encode=_driven_value),
    ParamSpec('branch', str, 'upper', '',
              'Assembly branch: upper (gamma + delta in [0, pi], the Annex A branch) or lower.',
              choices=('upper', 'lower'), decode=_branch, encode=_branch_value),
    ParamSpec('load_torque', float, 3.5, 'N m',
              'Constant load torque about the antenna angle theta that the drive must supply '
              '(positive in the +theta direction); default: design wind load.',
              -1.0e6, 1.0e6),
    ParamSpec('antenna_mass', float, 0.0, 'kg',
              'Antenna mass carried by the coupler, for a gravity load (0: none). '
              'Gravity acts along -y (frame AD horizontal, rockers pointing up).',
              0.0, 1.0e4),
    ParamSpec('com_offset_along', float, 0.0, 'm',
              'Antenna centre of mass from the coupler midpoint, along B->C.', -100.0, 100.0),
    ParamSpec('com_offset_normal', float, 0.0, 'm',
              'Antenna centre of mass from the coupler midpoint, normal to BC '
              '(positive: away from the frame at theta = 0).', -100.0, 100.0),
    ParamSpec('gravity', float, 9.80665, 'm/s^2',
              'Gravitational acceleration for the antenna weight.', 0.0, 100.0),
    ParamSpec('reducer_ratio', float, 500.0, '',
              'Reducer ratio motor:rocker (motor turns per rocker turn), the `<mechanical_reduction>` of the URDF\'s '
              'SimpleTransmission; negative when the motor turns the other way (a reversed motor). Limits and '
              'torques use its magnitude, at least 1e-6.', -1.0e7, 1.0e7),
    ParamSpec('driven_joint_offset', float, 0.0, 'rad',
              'Driven joint position where the motor position reads 0: the `<offset>` of the URDF\'s '
              'SimpleTransmission (ros2_control: joint = motor / reducer_ratio + this); beyond pi for a multi-turn '
              'absolute encoder. Only the URDF uses it.',
              -1.0e6, 1.0e6, read_only=True),
    ParamSpec('reducer_efficiency', float, 1.0, '',
              'Reducer efficiency in (0, 1]; motor torque = rocker torque / (ratio * efficiency).',
              1e-6, 1.0),
    ParamSpec('motor_torque_limit', float, 0.009, 'N m',
              'Torque the motor can hold/deliver before the reducer.', 1e-12, 1.0e6),
    ParamSpec('output_torque_limit', float, 5.0, 'N m',
              'Rated torque of the reducer output at the driven rocker.', 1e-12, 1.0e6),
    # Motion of the driven joint (trajectory conversion, limits, planning). Motor-side limits: the reducer ratio
    # brings them to the rocker. Defaults: a small stepper through the 500:1 reducer, 300 rpm top speed.
    ParamSpec('motor_speed_limit', float, 31.41592653589793, 'rad/s',
              'Motor speed limit, at the motor (rocker limit = this / reducer_ratio); 300 rpm by default.',
              1e-9, 1.0e6),
    ParamSpec('motor_acceleration_limit', float, 100.0, 'rad/s^2',
              'Motor acceleration limit, at the motor (rocker limit = this / reducer_ratio).', 1e-9, 1.0e9),
    ParamSpec('motor_jerk_limit', float, 1000.0, 'rad/s^3',
              'Motor jerk limit, at the motor (rocker limit = this / reducer_ratio).', 1e-9, 1.0e12),
    ParamSpec('trajectory_tolerance', float, 1.0e-4, 'rad',
              'Largest deviation of the antenna angle allowed between the points of a converted trajectory, as '
              'the controller interpolates the driven joint; points are inserted until it holds.', 1e-9, 0.1),
    ParamSpec('limit_policy', str, 'reject', '',
              'Trajectory points over a motor speed, acceleration or jerk limit: reject the trajectory, naming '
              'the worst point, or retime it (slow it down uniformly until every point is within). A static '
              'torque over its limit is always rejected.', choices=('reject', 'retime')),
    ParamSpec('control_rate', float, 100.0, 'Hz',
              'Rate of the setpoint stream of a planned motion (forward command mode).', 0.1, 10000.0),
    ParamSpec('max_trajectory_points', int, 10000, '',
              'Most points a trajectory may have, received or sent (inserted points included): bounds memory.',
              2, 1000000),
    ParamSpec('mode', str, Mode.OPEN_LOOP.value, '',
              'open_loop: commands in, the commanded pose out on joint_states (no hardware). trajectory: commands '
              'and antenna trajectories become driven-joint trajectories for joint_trajectory_controller; '
              'forward: a setpoint stream for forward_command_controller. In both actuator modes the measured '
              'driven joint (measured_joint_states) is completed into the whole linkage on joint_states.',
              choices=tuple(m.value for m in Mode), read_only=True),
    ParamSpec('trajectory_controller', str, DEFAULT_TRAJECTORY_CONTROLLER, '',
              'Controller name (trajectory mode): driven-joint trajectories go to <this>/joint_trajectory.',
              read_only=True),
    ParamSpec('trajectory_interface', str, 'topic', '',
              'Trajectory mode: how trajectories reach the controller: topic (<trajectory_controller>/'
              'joint_trajectory) or action (each a FollowJointTrajectory goal on <trajectory_controller>/'
              'follow_joint_trajectory; '
              'diagnostics count how the controller ends them; needs control_msgs).',
              choices=('topic', 'action'), read_only=True),
    ParamSpec('forward_controller', str, DEFAULT_FORWARD_CONTROLLER, '',
              'Controller name (forward mode): driven-joint setpoints go to <this>/commands.', read_only=True),
    ParamSpec('controllers_file', str, '', '',
              'Actuator modes: the ros2_control controllers YAML the drive runs (the controller\'s joints, command '
              'interfaces and options decide what it accepts); empty: the package\'s config/controllers.yaml.',
              read_only=True),
    ParamSpec('controller_manager', str, DEFAULT_CONTROLLER_MANAGER, '',
              'Actuator modes: the controller manager whose ~/activity says whether the mode\'s controller (and '
              'its hardware) is active; relative names follow the node\'s namespace. A command waits while that '
              'controller is not active; empty: not followed (commands go out as they come, as they also do while '
              'no such manager was ever seen).', read_only=True),
    ParamSpec('command_hold_timeout', float, 15.0, 's',
              'Actuator modes: how long a command waits for its controller to be active (from its arrival, or from '
              'its interruption) before it is dropped; a drive should not move on its own long after it was told.',
              0.0, 86400.0),
    ParamSpec('resume_interrupted', bool, True, '',
              'Actuator modes: a command whose motion was interrupted (its controller deactivated, the controller '
              'manager gone, a hardware component deactivated) waits again and is re-planned from the measured '
              'state when the controller is active; false: it ends interrupted.'),
    ParamSpec('reached_tolerance', float, 0.001, 'rad',
              'Actuator modes: a command is reached when its motion has ended and the measured antenna angle is '
              'within this of it.', 1e-9, 0.5),
    ParamSpec('reach_timeout', float, 2.0, 's',
              'Actuator modes: a sent command not reached this long after its motion\'s planned end ends '
              'interrupted (the drive did not follow).', 0.001, 3600.0),
    ParamSpec('follow_tolerance', float, 0.02, 'rad',
              'Actuator modes, with the controller active: the measured driven joint farther than this from the '
              'reference its controller follows, for follow_timeout, is a drive that does not follow (ERROR; the '
              'command ends interrupted).', 1e-6, 1.0),
    ParamSpec('follow_timeout', float, 1.0, 's',
              'Actuator modes: how long the drive may stay off its reference by more than follow_tolerance '
              '(0: not checked).', 0.0, 3600.0),
    ParamSpec('effort_feedforward', bool, False, '',
              'Trajectory mode: send the static input torque as each point\'s effort (a feed-forward). The '
              'controller must then have an effort command interface ([position, effort]); off: no effort field.',
              read_only=True),
    ParamSpec('replan_tolerance', float, 0.01, 'rad',
              'Actuator modes: a command during a motion plans on from the motion being followed while the '
              'measured driven joint is within this of it at the measurement\'s stamp; otherwise from the measured '
              'state. Below the trajectory controller\'s path tolerance at the driven joint where it checks one '
              '(refused otherwise, at startup and at run time), so a drive the controller holds is planned from where '
              'it is.', 0.0, 3.2),
    ParamSpec('measured_range_tolerance', float, 1e-5, 'rad',
              'Actuator modes: a measured driven joint outside its range for [theta_min, theta_max] by at most this '
              '(an encoder count through the reducer rounds outward) starts a motion from the nearest end of the '
              'range; further out, no motion is planned from it.', 0.0, 0.1),
    ParamSpec('measurement_timeout', float, 0.5, 's',
              'Actuator modes: no measured driven joint for this long makes the diagnostics WARN.', 0.001, 3600.0),
    ParamSpec('tracking_window', float, 5.0, 's',
              'Actuator modes: the window over which diagnostics report the worst commanded-minus-measured '
              'antenna angle, and the RMS of the model mismatch (antenna_sensor_type).', 0.001, 3600.0),
    ParamSpec('antenna_sensor_type', str, 'none', '',
              'Actuator modes: an antenna angle sensor on antenna_angle_sensor for a live check of the model: '
              'float64 (std_msgs/Float64, rad in theta\'s sense) or imu (sensor_msgs/Imu, the tilt from gravity as '
              '`fourbar calibrate` takes it); each reading is compared with the angle completed from the measured '
              'driven joint at its time. none: no subscription.', choices=('none', 'float64', 'imu'), read_only=True),
    ParamSpec('antenna_sensor_offset', float, 0.0, 'rad',
              'The antenna sensor\'s reading when the antenna is level (its mounting error; `fourbar calibrate`\'s '
              'sensor_offset): subtracted from its readings.', -math.pi, math.pi),
    ParamSpec('antenna_imu_yaw', float, 0.0, 'rad',
              'An imu antenna sensor\'s turn about its z axis from the coupler frame (`fourbar calibrate`\'s '
              'imu_yaw_rad): its readings are turned back by it before the tilt is taken.', -math.pi / 2, math.pi / 2),
    ParamSpec('antenna_sensor_latency', float, 0.0, 's',
              'How late the antenna sensor\'s readings are against the measured joint (`fourbar calibrate`\'s '
              'latency_s): a reading timed t is compared with the joint at t minus this.', -1.0, 1.0),
    ParamSpec('antenna_sensor_noise', float, 0.0, 'rad',
              'The sensor\'s noise sd about the calibrated model (`fourbar calibrate`\'s noise_sd_rad). Above 0 the '
              'live check tests the window\'s bias and scatter apart, in sds (model_mismatch_warn_sds, '
              'model_mismatch_error_sds); 0: its RMS against model_mismatch_warn and model_mismatch_error.',
              0.0, math.pi),
    ParamSpec('antenna_sensor_noise_correlation', float, 0.0, '',
              'The lag-1 correlation of that noise between successive readings (`fourbar calibrate`\'s '
              'noise_lag1_correlation; a filtering sensor\'s is near 1): a window of n readings counts as '
              'n (1 - c) / (1 + c) independent ones.', 0.0, 0.999),
    ParamSpec('antenna_sensor_map_sd', float, 0.0, 'rad',
              'The sd of the calibrated joint-to-sensor map (`fourbar calibrate`\'s largest sensor_reading_sd_rad): '
              'with antenna_sensor_noise, the part of the bias\'s sd no window averages away.', 0.0, math.pi),
    ParamSpec('model_mismatch_warn_sds', float, 4.0, '',
              'With antenna_sensor_noise: diagnostics WARN when the window\'s bias is this many of its sds from 0, '
              'or its scatter this many of its sds above the noise (must be below model_mismatch_error_sds).',
              0.0, 1e6),
    ParamSpec('model_mismatch_error_sds', float, 8.0, '',
              'With antenna_sensor_noise: diagnostics ERROR beyond this many sds.', 0.0, 1e6),
    ParamSpec('model_mismatch_warn', float, 0.005, 'rad',
              'Actuator modes, with an antenna sensor and no antenna_sensor_noise: diagnostics WARN when the RMS of '
              'sensor minus model over tracking_window exceeds this (must be below model_mismatch_error).',
              0.0, math.pi),
    ParamSpec('model_mismatch_error', float, 0.02, 'rad',
              'Actuator modes, with an antenna sensor and no antenna_sensor_noise: diagnostics ERROR when that RMS '
              'exceeds this.', 0.0, math.pi),
    ParamSpec('slip_stop_mismatch', float, 0.02, 'rad',
              'Trajectory and forward modes, with an antenna sensor: when the mean of sensor minus model over the '
              'last slip_stop_time stays beyond this, the drive may have slipped (an open-loop stepper counts on '
              'while the antenna stays): the motion stops, the command in force ends interrupted, diagnostics ERROR '
              'and new commands are dropped until the mean is back within it for slip_stop_time. 0: no stop (also '
              'releases one).', 0.0, math.pi),
    ParamSpec('slip_stop_time', float, 0.2, 's',
              'Actuator modes: the time over which the antenna sensor\'s readings (at least two, by their stamps) '
              'are averaged for slip_stop_mismatch; the stop follows the first reading past it within this plus one '
              'reading period.', 0.001, 60.0),
    ParamSpec('gamma_joint', str, 'rocker_ab_joint', '',
              'JointState name of the rocker AB joint (gamma).'),
    ParamSpec('delta_joint', str, 'rocker_cd_joint', '',
              'JointState name of the rocker CD joint (delta).'),
    ParamSpec('coupler_joint', str, 'coupler_joint', '',
              'JointState name of the coupler joint (position gamma + theta: the coupler BC from rocker AB), '
              'so robot_state_publisher can place the coupler of the URDF from `fourbar urdf`.'),
    ParamSpec('hardware_id', str, 'fourbar_antenna_tilt', '',
              'Diagnostics hardware_id: names the hardware (the tilt drive), not a TF frame; also the name of the '
              'URDF\'s `<ros2_control>` block (the hardware component).'),
    ParamSpec('hardware_parameters', list, [], '',
              'The hardware plugin\'s parameters: `name=value` strings, each written by `fourbar urdf` and the '
              'launch file as a `<param name="name">value</param>` of the URDF\'s `<hardware>` block (names '
              'distinct; letters, digits, `_`, `.`, `-`). Only the URDF uses them.', read_only=True,
              decode=_string_tuple, encode=_string_list),
    ParamSpec('frame_id', str, 'fourbar_base', '',
              'Frame of the markers and root link of the URDF: origin at pivot A, x along A->D, z up; '
              'the linkage lies in its x-z plane (REP-103).'),
    ParamSpec('out_of_limits', str, 'reject', '',
              'Policy for finite commands outside [theta_min, theta_max]: reject (drop) or '
              'clamp (to the nearest limit). NaN/inf are always rejected.',
              choices=('reject', 'clamp')),
    ParamSpec('transmission_angle_min', float, 0.5235987755982989, 'rad',
              'Diagnostics warn when the transmission angle leaves [this, pi - this] '
              '(the classical guideline is 40 deg; Turnantenna reaches 147.6 deg at +7 deg).',
              0.0, 0.5 * math.pi),
    ParamSpec('velocity_timeout', float, 0.5, 's',
              'Joint velocities come from successive commands only when they are at most this far '
              'apart; otherwise JointState.velocity is left empty.', 1e-6, 3600.0),
    ParamSpec('marker_period', float, 0.1, 's',
              'Period of the linkage_markers check: markers are published when someone subscribes and the '
              'pose (or the subscriber count) changed since the last ones.', 0.001, 3600.0, read_only=True),
    ParamSpec('diagnostics_period', float, 1.0, 's',
              'Period of the /diagnostics status.', 0.01, 3600.0, read_only=True),
    ParamSpec('joint_state_rate', float, 10.0, 'Hz',
              'Rate at which the last served pose is republished on joint_states with a fresh stamp and zero '
              'velocities (as joint_state_publisher does), so late subscribers get it; 0 turns it off.',
              0.0, 1000.0, read_only=True),
)

PARAMETERS_BY_NAME: dict[str, ParamSpec] = {p.name: p for p in PARAMETERS}

#: Parameters every rclpy node may receive that are not ours (the loader and the node ignore them).
FOREIGN_PARAMETERS: frozenset[str] = frozenset({'use_sim_time', 'start_type_description_service'})
FOREIGN_PREFIXES: tuple[str, ...] = ('qos_overrides.',)


def is_foreign(name: str) -> bool:
    """True for rclpy's own parameters (``use_sim_time``, ``qos_overrides.*``), which we ignore."""
    return name in FOREIGN_PARAMETERS or name.startswith(FOREIGN_PREFIXES)


def defaults() -> dict[str, ParamValue]:
    """Name -> default value for every parameter."""
    return {p.name: p.default for p in PARAMETERS}
