"""sim_actuator: a simulated drive of the linkage's driven joint, standing in for ros2_control's hardware, its
joint_trajectory_controller, its forward_command_controller and its joint_state_broadcaster.

Interface (relative names, so namespaces and remapping apply; ``<joint>`` is the ``joint`` parameter):
  sub  <trajectory_controller>/joint_trajectory  trajectory_msgs/JointTrajectory   followed from its start (header
                                                 stamp, or on arrival when 0), as joint_trajectory_controller does
  sub  <forward_controller>/commands             std_msgs/Float64MultiArray        one position (rad) to go to
  pub  joint_states                              sensor_msgs/JointState            every 1/publish_rate s: name
                                                 [<joint>], measured position (rad), velocity (rad/s), effort (N m:
                                                 the torque the linkage needs at the true pose, plus noise)
The latest command wins, whichever controller it came for. A bad message (joint missing, mismatched arrays, NaN,
times not increasing, too many points, not one value) is counted, logged in one throttled line and ignored.
The behaviour is in ``fourbar_ros.node.sim_actuator_model``; this module only adapts messages and time.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from rclpy.impl.rcutils_logger import RcutilsLogger
from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from trajectory_msgs.msg import JointTrajectory

from fourbar_ros.config.antenna_config import ConfigError, config_from_values, declared_values
from fourbar_ros.config.interface import JOINT_STATES
from fourbar_ros.config.params import PARAMETERS_BY_NAME
from fourbar_ros.config.robot_model import driven_angle, joint_limits
from fourbar_ros.config.sim_actuator_params import NODE_NAME, SIM_PARAMETERS, sim_settings
from fourbar_ros.core.errors import FourBarError
from fourbar_ros.node.fourbar_node import destroy_node
from fourbar_ros.node.param_descriptors import declarations
from fourbar_ros.node.sim_actuator_model import (
    DriveLimits,
    Encoder,
    LagActuator,
    Setpoint,
    Trajectory,
    TrajectoryError,
    effort_at,
    waypoints,
)

#: Keep-last depth of the command subscriptions and of joint_states (joint_state_broadcaster's is 10).
DEPTH = 10
WARN_THROTTLE_S = 1.0


@dataclass
class SimCounters:
    """What the node did, for tests and diagnostics."""

    trajectories_accepted: int = 0
    trajectories_rejected: int = 0
    commands_accepted: int = 0
    commands_rejected: int = 0
    joint_states_published: int = 0
    joint_states_skipped: int = 0


class SimActuator(Node):
    """The simulated drive. Raises ConfigError from the constructor if its parameters are invalid."""

    def __init__(self, node_name: str = NODE_NAME, **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        get_logger: Callable[[], RcutilsLogger] = self.get_logger
        self._warn: Callable[..., object] = get_logger().warning
        startup = {name: p.value for name, p in self._parameter_overrides.items()}  # see FourBarNode._startup_values
        try:
            self.config = config_from_values(declared_values(startup))
            self.settings = sim_settings(startup, self.config)
        except ConfigError:
            destroy_node(self)
            raise
        self.declare_parameters('', list(declarations(self.config.as_values(), read_only=True)))
        # The controller names are also the linkage table's (declared just above, one value serves both).
        own = [spec for spec in SIM_PARAMETERS if spec.name not in PARAMETERS_BY_NAME]
        self.declare_parameters('', list(declarations(self.settings.as_values(), own, read_only=True)))
        cfg, s = self.config, self.settings
        lim = joint_limits(cfg)[cfg.driven_joint]
        self.drive = LagActuator(DriveLimits(lim.lower, lim.upper, s.max_velocity, s.max_acceleration,
                                             s.time_constant), driven_angle(cfg, s.initial_theta))
        self.encoder = Encoder(s.encoder_counts_per_rev, cfg.reducer_ratio, s.position_offset, s.position_noise,
                               s.velocity_noise, s.effort_noise, s.noise_seed)
        self.counters = SimCounters()
        self._clock: Any = self.get_clock()
        self._hold = Setpoint(self.drive.position, 0.0, 0.0)  # the forward command (or the start), held
        self._trajectory: Trajectory | None = None
        self._last_tick_ns: int | None = None
        self._msg = JointState()
        self._msg.name = [s.joint]
        self._pub = self.create_publisher(JointState, JOINT_STATES.name, DEPTH)
        self.create_subscription(JointTrajectory, f'{self.config.trajectory_controller}/joint_trajectory',
                                 self._on_trajectory, DEPTH)
        self.create_subscription(Float64MultiArray, f'{self.config.forward_controller}/commands', self._on_forward,
                                 DEPTH)
        self.create_timer(1.0 / s.publish_rate, self._on_tick)

    def _now(self) -> float:
        return float(self._clock.now().nanoseconds) * 1e-9

    def reference(self, now: float) -> Setpoint:
        """The position reference at ``now`` (s, node clock): the running trajectory's sample, else the hold."""
        return self._trajectory.sample(now) if self._trajectory is not None else self._hold

    def _refuse(self, kind: str, why: str) -> None:
        self._warn(f'{kind} ignored: {why}', throttle_duration_sec=WARN_THROTTLE_S)

    def _on_trajectory(self, msg: JointTrajectory) -> None:
        try:
            points = waypoints(msg.joint_names, self.settings.joint, msg.points)
        except TrajectoryError as exc:
            self.counters.trajectories_rejected += 1
            self._refuse('trajectory', str(exc))
            return
        now = self._now()
        stamp = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
        self._trajectory = Trajectory(stamp if stamp > 0.0 else now, self.reference(now), tuple(points))
        self.counters.trajectories_accepted += 1

    def _on_forward(self, msg: Float64MultiArray) -> None:
        data = msg.data
        if len(data) != 1 or not math.isfinite(data[0]):
            self.counters.commands_rejected += 1
            self._refuse('forward command', f'expected one finite position for {self.settings.joint!r}, '
                                            f'got {list(data)[:4]}{" ..." if len(data) > 4 else ""}')
            return
        self._hold = Setpoint(float(data[0]), 0.0, 0.0)
        self._trajectory = None
        self.counters.commands_accepted += 1

    def _on_tick(self) -> None:
        now = self._clock.now()
        ns = now.nanoseconds
        last, self._last_tick_ns = self._last_tick_ns, ns
        dt = 0.0 if last is None or ns < last else (ns - last) * 1e-9  # a clock jumping back restarts the steps
        drive = self.drive
        drive.advance(dt, self.reference(ns * 1e-9).position)
        try:
            effort = effort_at(self.config, drive.position)
        except FourBarError as exc:  # the drive stays in the tilt range's rocker range: a core bug if here
            effort = math.nan
            self._warn(f'no effort at {drive.position!r} rad: {exc}', throttle_duration_sec=WARN_THROTTLE_S)
        measured = self.encoder.measure(drive.position, drive.velocity, effort)
        if not all(math.isfinite(v) for v in measured):
            self.counters.joint_states_skipped += 1
            return
        msg = self._msg
        msg.header.stamp = now.to_msg()
        msg.position, msg.velocity, msg.effort = [measured[0]], [measured[1]], [measured[2]]
        self._pub.publish(msg)
        self.counters.joint_states_published += 1

