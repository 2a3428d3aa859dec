"""sim_actuator: a simulated drive standing in for ros2_control's hardware, controllers and broadcaster.

Its behaviour is ``fourbar_ros.rules.simulated_drive``; its topics, what it imitates and what not:
docs/how-to/ros2-control.md#without-hardware-the-simulated-actuator."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, Protocol

from rclpy.impl.rcutils_logger import RcutilsLogger
from rclpy.node import Node
from rclpy.time import Time as RclpyTime
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from trajectory_msgs.msg import JointTrajectory

from fourbar_ros.config.antenna_config import AntennaConfig, ConfigError, config_from_values, declared_values
from fourbar_ros.config.controllers import forward_controller, trajectory_controller
from fourbar_ros.config.robot_model import driven_angle, joint_limits
from fourbar_ros.config.sim_actuator_params import NODE_NAME, SIM_PARAMETERS, sim_settings
from fourbar_ros.core.errors import FourBarError
from fourbar_ros.interface.stamps import ns_to_seconds, seconds_to_ns, to_ns
from fourbar_ros.interface.topics import (
    BROADCASTER_JOINT_STATES,
    DEFAULT_CONTROLLER_MANAGER,
    activity_topic,
    forward_topic,
    trajectory_topic,
)
from fourbar_ros.node.controller_watch import ACTIVITY_QOS, activity_type
from fourbar_ros.node.fourbar_node import destroy_node
from fourbar_ros.node.param_descriptors import declarations
from fourbar_ros.node.qos import qos
from fourbar_ros.node.timers import periodic_timer
from fourbar_ros.rules.command_fate import ACTIVE_LABEL
from fourbar_ros.rules.controller_contract import check_forward_command
from fourbar_ros.rules.simulated_drive import DriveLimits, Encoder, LagActuator, TrajectoryFollower, effort_at
from fourbar_ros.runtime.executor import MessageInfoCallback, arrival_ns
from fourbar_ros.runtime.problem_log import ProblemLog

WARN_THROTTLE_S = 1.0
#: Most controller updates one late tick makes (10 s at 100 Hz): a longer gap is integrated in longer steps.
MAX_CATCH_UP = 1000


class SimDrive(Protocol):
    """What follows the controller's position command (rad at the driven joint): its true state and effort."""

    @property
    def position(self) -> float:
        """The driven joint's angle (rad)."""

    @property
    def velocity(self) -> float:
        """The driven joint's speed (rad/s)."""

    def advance(self, dt: float, reference: float) -> None:
        """Move ``dt`` s (in the drive's whole steps) under the position command ``reference`` (rad), held."""

    def effort(self) -> float:
        """The torque (N m, + increasing joint angle) the drive applies to the driven joint now."""


#: A drive option: (configuration, starting joint angle rad, joint range lower and upper rad) -> the drive.
DriveFactory = Callable[[AntennaConfig, float, float, float], SimDrive]


class LagDrive:
    """The ``lag`` drive: ``LagActuator`` with the load model's torque at its position as the effort."""

    def __init__(self, cfg: AntennaConfig, actuator: LagActuator) -> None:
        self.cfg = cfg
        self.actuator = actuator

    @property
    def position(self) -> float:
        """The driven joint's angle (rad)."""
        return self.actuator.position

    @property
    def velocity(self) -> float:
        """The driven joint's speed (rad/s)."""
        return self.actuator.velocity

    def advance(self, dt: float, reference: float) -> None:
        """``LagActuator.advance``."""
        self.actuator.advance(dt, reference)

    def effort(self) -> float:
        """``effort_at`` the present position (N m; raises the core's FourBarError off the rocker's reach)."""
        return effort_at(self.cfg, self.actuator.position)


@dataclass
class SimCounters:
    """What the node did besides following trajectories (``TrajectoryFollower.counters``), for tests."""

    commands_accepted: int = 0
    commands_rejected: int = 0
    commands_ignored_nan: int = 0  #: forward commands of NaN only: the controller keeps its last command
    #: forward commands of the wrong size: the controller's update fails and the controller manager deactivates it
    forward_deactivations: int = 0
    joint_states_published: int = 0
    joint_states_skipped: int = 0
    #: trajectories and forward commands sent while its controllers are inactive (``controller_active`` false)
    dropped_inactive: int = 0


class SimActuator(Node):
    """The simulated drive. Raises ConfigError from the constructor if its parameters are invalid.

    ``drives``: the drive options offered besides ``lag`` (name -> factory; the console script offers ``mujoco``,
    ``plant.sim_drive``). A ``drive`` parameter naming one not offered falls back to ``lag``, logged once."""

    def __init__(self, node_name: str = NODE_NAME, drives: Mapping[str, DriveFactory] | None = None,
                 **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        get_logger: Callable[[], RcutilsLogger] = self.get_logger
        self._warn: Callable[..., object] = get_logger().warning
        info: Callable[..., object] = get_logger().info
        #: warnings throttled per problem kind (each refusal rule its own), not per call site
        self._problems = ProblemLog(lambda _level, line: self._warn(line), WARN_THROTTLE_S)
        startup = {name: p.value for name, p in self._parameter_overrides.items()}  # see FourBarNode._startup_values
        try:
            self.config = config_from_values(declared_values(startup))
            self.settings = sim_settings(startup, self.config)
            jtc = trajectory_controller(self.config.controllers_file, self.config.trajectory_controller,
                                        self.get_namespace())
            self._forward = forward_controller(self.config.controllers_file, self.config.forward_controller,
                                               self.get_namespace())
        except ConfigError:
            destroy_node(self)
            raise
        self.declare_parameters('', list(declarations(self.config.as_values(), read_only=True)))
        own = declarations(self.settings.as_values(), SIM_PARAMETERS, read_only=True)
        for name, _, descriptor in own:
            descriptor.read_only = name != 'controller_active'
        self.declare_parameters('', list(own))
        cfg, s = self.config, self.settings
        lim = joint_limits(cfg)[cfg.driven_joint]
        start = driven_angle(cfg, s.initial_theta)
        factory = (drives or {}).get(s.drive)
        self.drive_kind = s.drive if factory is not None else 'lag'
        if s.drive != self.drive_kind:
            info(f'drive {s.drive!r} is not available here (the mujoco package, through the '
                              f'fourbar_sim_actuator script): the lag drive follows the commands')
        self.drive: SimDrive = (
            factory(cfg, start, lim.lower, lim.upper) if factory is not None else
            LagDrive(cfg, LagActuator(DriveLimits(lim.lower, lim.upper, s.max_velocity, s.max_acceleration,
                                                  s.time_constant), start)))
        self.encoder = Encoder(s.encoder_counts_per_rev, cfg.reducer_ratio, s.position_offset, s.position_noise,
                               s.velocity_noise, s.effort_noise, s.noise_seed)
        self.counters = SimCounters()
        self.forward_active = True
        self.controller_active = s.controller_active
        self.follower = TrajectoryFollower(jtc, s.joint, self.drive.position, 1.0 / s.publish_rate)
        self._clock: Any = self.get_clock()
        self._last_tick_ns: int | None = None
        self._last_update_ns: int | None = None  # the last update's time (ns, node clock)
        self._reference = self.drive.position  # the position command the drive follows until the next update
        self._msg = JointState()
        self._msg.name = [s.joint]
        self._pub = self.create_publisher(JointState, BROADCASTER_JOINT_STATES.name, qos(BROADCASTER_JOINT_STATES))
        jt, fw = trajectory_topic(cfg.trajectory_controller), forward_topic(cfg.forward_controller)
        #: the callback boundary: an exception is counted, logged and swallowed
        self.guard = guard = self._problems.guard
        on_trajectory = guard.wrap('sub_trajectory', MessageInfoCallback(self._on_trajectory))
        self.create_subscription(JointTrajectory, jt.name, on_trajectory, qos(jt))
        self.create_subscription(Float64MultiArray, fw.name, guard.wrap('sub_forward', self._on_forward), qos(fw))
        self._tick_clock: Any = periodic_timer(self, 1.0 / s.publish_rate, guard.wrap('tick', self._on_tick)).clock
        self.add_post_set_parameters_callback(guard.wrap('after_set_parameters', self._after_set_parameters))
        # Where controller_manager_msgs is installed, it says what a controller manager would of its controllers.
        self._activity_type, _ = activity_type()
        activity = activity_topic(DEFAULT_CONTROLLER_MANAGER).name
        self._activity_pub = (None if self._activity_type is None else
                              self.create_publisher(self._activity_type, activity, ACTIVITY_QOS))
        self._publish_activity()

    def _after_set_parameters(self, params: list[Any]) -> None:
        for p in params:
            if p.name == 'controller_active' and p.value != self.controller_active:
                self.controller_active = bool(p.value)
                # deactivated or activated, the controller holds the drive where it is
                self.follower.hold(self.drive.position)
                self._publish_activity()

    def _publish_activity(self) -> None:
        """controller_manager/activity as a manager with this node's controllers and one active hardware component."""
        if self._activity_pub is None:
            return
        from controller_manager_msgs.msg import NamedLifecycleState  # type: ignore[import-not-found,unused-ignore]
        from lifecycle_msgs.msg import State  # type: ignore[import-untyped,unused-ignore]

        def named(name: str, active: bool) -> Any:
            return NamedLifecycleState(name=name, state=State(
                id=State.PRIMARY_STATE_ACTIVE if active else State.PRIMARY_STATE_INACTIVE,
                label=ACTIVE_LABEL if active else 'inactive'))
        cfg = self.config
        msg = self._activity_type(controllers=[named(cfg.trajectory_controller, self.controller_active),
                                               named(cfg.forward_controller, self.controller_active)],
                                  hardware_components=[named(cfg.hardware_id, True)])
        msg.header.stamp = self._clock.now().to_msg()
        self._activity_pub.publish(msg)

    def _refuse(self, kind: str, why: str) -> None:
        self._problems.warn(f'{kind} refused', f'{kind} refused: {why}')

    def _on_trajectory(self, msg: JointTrajectory, info: dict[str, Any]) -> None:
        if not self.controller_active:  # an inactive controller drops what it is sent
            self.counters.dropped_inactive += 1
            return
        refusal = self.follower.receive(msg.joint_names, msg.points, to_ns(msg.header.stamp),
                                        arrival_ns(self._clock, info))
        if refusal is not None:
            self._refuse(f'trajectory ({refusal.rule.value})', refusal.reason)

    def _on_forward(self, msg: Float64MultiArray) -> None:
        # forward_command_controller's update (jazzy): a command of NaN only is no command; a wrong size fails the
        # update, and the controller manager deactivates the controller (further commands are not written).
        data = list(msg.data)
        if not self.controller_active:
            self.counters.dropped_inactive += 1
            return
        if not self.forward_active:
            self.counters.commands_rejected += 1
            self._refuse('forward command', 'the forward controller was deactivated by a command of the wrong size')
            return
        if data and all(math.isnan(v) for v in data):
            self.counters.commands_ignored_nan += 1
            return
        refusal = check_forward_command(self._forward, data)
        if refusal is not None:
            self.forward_active = False
            self.counters.forward_deactivations += 1
            self.counters.commands_rejected += 1
            self._refuse('forward command', f'{refusal.reason}: the controller is deactivated')
            return
        if not all(math.isfinite(v) for v in data):  # stricter: the controller would write an infinity
            self.counters.commands_rejected += 1
            self._refuse('forward command', f'not finite: {data}')
            return
        self.follower.hold(float(data[0]))
        self.counters.commands_accepted += 1

    def _on_tick(self) -> None:
        now = self._clock.now()
        tick_ns: int = self._tick_clock.now().nanoseconds  # the drive's steps: the timer's clock, not the stamps'
        last, self._last_tick_ns = self._last_tick_ns, tick_ns
        dt = 0.0 if last is None or tick_ns < last else ns_to_seconds(tick_ns - last)  # sim time jumping back restarts
        reason = self.follower.holding_reason
        # A tick late by whole periods (a busy machine) first makes the updates it missed, as the controller
        # manager's real-time loop would have: the drive keeps following, a trajectory that arrived meanwhile is
        # taken over at the first of them after its arrival, and a late timer is no tolerance violation. Only the
        # tick publishes the measured state. The missed updates' times are spread over the node clock's interval
        # since the last tick (counted back from now if that clock went back).
        updates = min(max(round(dt / self.follower.period), 1), MAX_CATCH_UP)
        step_ns = seconds_to_ns(dt / updates)
        last_ns = self._last_update_ns if self._last_update_ns is not None else now.nanoseconds
        span = now.nanoseconds - last_ns
        for j in range(1, updates):
            at_ns = last_ns + span * j // updates if span >= updates else now.nanoseconds - (updates - j) * step_ns
            self.drive.advance(ns_to_seconds(step_ns), self._reference)
            missed = self.encoder.measure(self.drive.position, self.drive.velocity, 0.0)
            self._reference = self.follower.reference(ns_to_seconds(at_ns), missed[0], missed[1]).position
        self._update(ns_to_seconds(step_ns), now)
        self._last_update_ns = now.nanoseconds
        if self.follower.holding_reason is not None and self.follower.holding_reason != reason:
            self._problems.warn('holding', self.follower.holding_reason)

    def _update(self, dt: float, at: RclpyTime) -> None:
        """The tick's update: the drive moves ``dt`` s under the last command, the broadcaster publishes its state
        stamped ``at``, and the controller writes the command for the next interval."""
        drive = self.drive
        drive.advance(dt, self._reference)  # the position command of the last update, held over the interval
        try:
            effort = drive.effort()
        except FourBarError as exc:  # the drive stays in the tilt range's rocker range: a core bug if here
            effort = math.nan
            self._problems.warn('no effort', f'no effort at {drive.position!r} rad: {exc}')
        measured = self.encoder.measure(drive.position, drive.velocity, effort)
        if not all(math.isfinite(v) for v in measured):
            self.counters.joint_states_skipped += 1
            return
        msg = self._msg
        msg.header.stamp = at.to_msg()
        msg.position, msg.velocity, msg.effort = [measured[0]], [measured[1]], [measured[2]]
        self._pub.publish(msg)
        self.counters.joint_states_published += 1
        self._reference = self.follower.reference(ns_to_seconds(at.nanoseconds), measured[0], measured[1]).position
