"""The sim_actuator node's own parameters (it also reads the linkage's, ``fourbar_ros.config.params``). No ROS.

Angles, speeds and accelerations are the driven joint's (rad, rad/s, rad/s^2: the reducer's output side), times in
seconds, torques in N m. Every parameter is read once, at startup, but ``controller_active`` (settable at run time).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

from fourbar_ros.config.antenna_config import AntennaConfig, ConfigError, check_value
from fourbar_ros.config.params import PARAMETERS_BY_NAME, ParamSpec, ParamValue

NODE_NAME = 'sim_actuator'


def _default(name: str) -> float:
    """A number parameter's default."""
    value = PARAMETERS_BY_NAME[name].default
    assert isinstance(value, float)
    return value


_RATIO = abs(_default('reducer_ratio'))
#: The default drive is the motor the linkage's parameters describe (its speed and acceleration limits, motor side).
_MOTOR_SPEED = _default('motor_speed_limit')
_MOTOR_ACCELERATION = _default('motor_acceleration_limit')

SIM_PARAMETERS: tuple[ParamSpec, ...] = (
    ParamSpec('joint', str, str(PARAMETERS_BY_NAME['gamma_joint'].default), '',
              'Name of the simulated (driven) joint in its commands and joint_states; default: the driven rocker\'s '
              'joint (gamma_joint or delta_joint, as driven_rocker says), the URDF\'s ros2_control joint.'),
    ParamSpec('publish_rate', float, 100.0, 'Hz',
              'Rate of the measured joint_states (and of the simulation step).', 0.1, 10000.0),
    ParamSpec('drive', str, 'lag', '',
              'What follows the controller\'s position command: mujoco, the MuJoCo plant (its servo, the linkage\'s '
              'inertia, the configured load as a wind and gravity; the measured effort is its reducer torque), or lag, '
              'a first-order lag under the limits below whose effort is the load model\'s (the default). Without the '
              'mujoco package (or started other than by the fourbar_sim_actuator script) mujoco falls back to lag, '
              'logged once.',
              choices=('mujoco', 'lag')),
    ParamSpec('time_constant', float, 0.05, 's',
              'First-order lag of the drive behind its position reference (the lag drive).', 1e-4, 100.0),
    ParamSpec('max_velocity', float, _MOTOR_SPEED / _RATIO, 'rad/s',
              'Speed limit of the joint, the lag drive\'s (default: motor_speed_limit\'s default through the default '
              'reducer_ratio).',
              1e-9, 1.0e6),
    ParamSpec('max_acceleration', float, _MOTOR_ACCELERATION / _RATIO, 'rad/s^2',
              'Acceleration limit of the joint, the lag drive\'s (default: motor_acceleration_limit\'s default '
              'through reducer_ratio).',
              1e-9, 1.0e9),
    ParamSpec('initial_theta', float, 0.0, 'rad',
              'Antenna angle the drive starts at (clamped into [theta_min, theta_max]).', -math.pi, math.pi),
    ParamSpec('encoder_counts_per_rev', int, 0, 'counts',
              'Encoder counts per motor turn (through reducer_ratio to the joint); 0: positions are not quantized.',
              0, 2**31 - 1),
    ParamSpec('position_offset', float, 0.0, 'rad',
              'Fixed offset added to every measured position (a homing or encoder zero error).', -math.pi, math.pi),
    ParamSpec('position_noise', float, 0.0, 'rad',
              'Standard deviation of Gaussian noise on the position before quantization (0: none).', 0.0, 1.0),
    ParamSpec('velocity_noise', float, 0.0, 'rad/s',
              'Standard deviation of Gaussian noise on the measured velocity (0: none).', 0.0, 1.0e3),
    ParamSpec('effort_noise', float, 0.0, 'N m',
              'Standard deviation of Gaussian noise on the measured effort (0: none).', 0.0, 1.0e6),
    ParamSpec('noise_seed', int, 0, '',
              'Seed of the noise generator (the same seed gives the same noise).', 0, 2**63 - 1),
    ParamSpec('controller_active', bool, True, '',
              'Whether its controllers (trajectory and forward) are active; settable at run time. False: what is sent '
              'to them is dropped and the drive holds where it is, as deactivated controllers do. Published as a '
              'controller manager\'s controller_manager/activity where controller_manager_msgs is installed.'),
)

SIM_PARAMETERS_BY_NAME: dict[str, ParamSpec] = {p.name: p for p in SIM_PARAMETERS}


@dataclass(frozen=True)
class SimSettings:
    """The validated sim_actuator parameters (fields as in SIM_PARAMETERS)."""

    joint: str
    publish_rate: float
    drive: str
    time_constant: float
    max_velocity: float
    max_acceleration: float
    initial_theta: float
    encoder_counts_per_rev: int
    position_offset: float
    position_noise: float
    velocity_noise: float
    effort_noise: float
    noise_seed: int
    controller_active: bool

    def as_values(self) -> dict[str, ParamValue]:
        """Parameter name -> value."""
        return {spec.name: getattr(self, spec.name) for spec in SIM_PARAMETERS}


def sim_settings(values: Mapping[str, object], cfg: AntennaConfig) -> SimSettings:
    """Check the sim parameters among ``values`` (other names are ignored); missing ones take their defaults,
    ``joint`` that of the driven rocker of ``cfg``. Raises ConfigError (one line naming the parameter)."""
    defaults: dict[str, object] = {spec.name: spec.default for spec in SIM_PARAMETERS}
    defaults['joint'] = cfg.driven_joint
    checked = {spec.name: check_value(spec, values.get(spec.name, defaults[spec.name])) for spec in SIM_PARAMETERS}
    joint = checked['joint']
    if joint in cfg.joint_names and joint != defaults['joint']:
        raise ConfigError(f"joint: {checked['joint']!r} names a joint the linkage moves passively; the driven rocker's "
                          f"is {defaults['joint']!r}", ('joint',))
    return SimSettings(**checked)  # type: ignore[arg-type]
