"""The actuator modes of fourbar_node: served commands and antenna trajectories become motion of the driven joint.

trajectory mode
  sub  antenna_trajectory                       trajectory_msgs/JointTrajectory  joint [antenna_joint]: theta rad,
                                                optional velocities rad/s, accelerations rad/s^2
  pub  <trajectory_controller>/joint_trajectory trajectory_msgs/JointTrajectory  joint [<driven joint>]: positions
                                                rad, velocities rad/s, accelerations rad/s^2, effort N m (feed-forward)
forward mode
  pub  <forward_controller>/commands            std_msgs/Float64MultiArray       one position rad, every
                                                1/control_rate s while a planned motion runs
both
  sub  joint_states                             sensor_msgs/JointState           the measured driven joint's
                                                position: where a command's motion starts when none is running

A served command (after the node's accept/clamp/reject policy) is planned from the state of the motion being
followed at the current time (position, velocity, acceleration: no jump), else from the measured position at rest.
What a message becomes is ``fourbar_ros.rules.actuation``; this module only adapts messages, clocks and timers.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from typing import Any

from builtin_interfaces.msg import Duration, Time
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from fourbar_ros.config.antenna_config import AntennaConfig
from fourbar_ros.config.interface import ANTENNA_TRAJECTORY, JOINT_STATES, Topic, forward_topic, trajectory_topic
from fourbar_ros.core.errors import FourBarError, one_line
from fourbar_ros.motion.planner import JointMotionState, Setpoints
from fourbar_ros.motion.trajectory import DrivenTrajectory
from fourbar_ros.rules.actuation import (
    ActuationCounters,
    Motion,
    convert,
    plan_command,
    planned_points,
    planned_setpoints,
    point_values,
    problem_of,
)

WARN_THROTTLE_S = 1.0
#: Setpoints kept in ``recent_setpoints`` (the last seconds of the stream at the default rate).
RECENT_SETPOINTS = 1000

_qos_profile: Callable[..., QoSProfile] = QoSProfile  # rclpy's constructor is unannotated


def _qos(topic: Topic) -> QoSProfile:
    return _qos_profile(depth=topic.depth, reliability=ReliabilityPolicy[topic.reliability.name])


def trajectory_message(joint: str, traj: DrivenTrajectory, stamp_ns: int) -> JointTrajectory:
    """The JointTrajectory of a driven-joint trajectory starting at ``stamp_ns`` (node clock)."""
    points = [JointTrajectoryPoint(positions=p, velocities=v, accelerations=a, effort=e,
                                   time_from_start=Duration(sec=sec, nanosec=nanosec))
              for p, v, a, e, (sec, nanosec) in point_values(traj)]
    msg = JointTrajectory(joint_names=[joint], points=points)
    msg.header.stamp = Time(sec=stamp_ns // 1_000_000_000, nanosec=stamp_ns % 1_000_000_000)
    return msg


class Actuation:
    """The trajectory or forward mode of a node (``cfg.mode``); ``config`` returns the node's running
    configuration. ``subscribe_measured``: read the measured driven joint from joint_states here (a component that
    already does can call ``note_measured`` instead)."""

    def __init__(self, node: Node, config: Callable[[], AntennaConfig], warn: Callable[..., object],
                 subscribe_measured: bool = True) -> None:
        cfg = config()
        self._config = config
        self._warn = warn
        self._clock: Any = node.get_clock()
        self.mode = cfg.mode
        self.counters = ActuationCounters()
        self.motion: Motion | None = None
        self.measured: float | None = None
        self._setpoints: Setpoints | None = None
        #: (time on the node clock the setpoint stands for, ns; position rad) of the setpoints published
        self.recent_setpoints: deque[tuple[int, float]] = deque(maxlen=RECENT_SETPOINTS)
        if self.mode == 'trajectory':
            out = trajectory_topic(cfg.trajectory_controller)
            self._trajectory_pub = node.create_publisher(JointTrajectory, out.name, _qos(out))
            node.create_subscription(JointTrajectory, ANTENNA_TRAJECTORY.name, self._on_antenna_trajectory,
                                     _qos(ANTENNA_TRAJECTORY))
        elif self.mode == 'forward':
            out = forward_topic(cfg.forward_controller)
            self._setpoint_pub = node.create_publisher(Float64MultiArray, out.name, _qos(out))
            self._setpoint_msg = Float64MultiArray()
            node.create_timer(1.0 / cfg.control_rate, self._on_control_timer)
        else:
            raise ValueError(f'mode {self.mode!r} is not an actuator mode')
        if subscribe_measured:
            node.create_subscription(JointState, JOINT_STATES.name, self._on_measured, _qos(JOINT_STATES))

    def _now_ns(self) -> int:
        ns: int = self._clock.now().nanoseconds
        return ns

    # ------------------------------------------------------------------ measured driven joint

    def _on_measured(self, msg: JointState) -> None:
        joint = self._config().driven_joint
        if joint in msg.name:
            i = list(msg.name).index(joint)
            if i < len(msg.position):
                self.note_measured(float(msg.position[i]))

    def note_measured(self, position: float, velocity: float | None = None) -> None:
        """The measured driven joint: position rad, velocity rad/s (None: not measured); a non-finite position is
        ignored."""
        if position - position == 0.0:  # finite
            self.measured = position

    def start_state(self, now_ns: int) -> JointMotionState | None:
        """Where a new motion starts: the running motion's state now, else the measured position at rest, else
        the end of the last motion; None before any of them exists."""
        motion = self.motion
        if motion is not None and not motion.done(now_ns):
            return motion.state_at(now_ns)
        if self.measured is not None:
            return JointMotionState(self.measured)
        return None if motion is None else motion.state_at(now_ns)

    # ------------------------------------------------------------------ plain commands

    def command(self, theta: float) -> None:
        """Plan and send the motion to a served antenna angle theta (rad)."""
        cfg = self._config()
        now_ns = self._now_ns()
        start = self.start_state(now_ns)
        if start is None:
            self.counters.commands_not_planned += 1
            self._warn(f'command theta = {theta!r} rad not planned: no measured {cfg.driven_joint} on '
                       f'{JOINT_STATES.name} yet', throttle_duration_sec=WARN_THROTTLE_S)
            return
        try:
            plan = plan_command(cfg, start, theta)
            points = planned_points(cfg, plan) if self.mode == 'trajectory' else None
            stream = planned_setpoints(cfg, plan) if points is None else None
        except FourBarError as exc:
            self.counters.commands_not_planned += 1
            self._warn(f'command theta = {theta!r} rad not planned: {one_line(exc)}',
                       throttle_duration_sec=WARN_THROTTLE_S)
            return
        self.counters.commands_planned += 1
        self.motion = Motion(now_ns, plan=plan)
        if points is not None:
            self._send(cfg, points, now_ns)
        else:
            self._setpoints = stream
            self._on_control_timer()  # the first setpoint now, not one period later

    def _send(self, cfg: AntennaConfig, traj: DrivenTrajectory, stamp_ns: int) -> None:
        self._trajectory_pub.publish(trajectory_message(cfg.driven_joint, traj, stamp_ns))
        self.counters.trajectories_sent += 1
        self.counters.trajectory_points_sent += len(traj)

    def _on_control_timer(self) -> None:
        stream, motion = self._setpoints, self.motion
        if stream is None or motion is None:
            return
        t = motion.elapsed(self._now_ns())
        i = int(stream.times.searchsorted(t, side='right')) - 1  # the latest setpoint due: never ahead of the plan
        i = max(i, 0)
        if i == stream.times.size - 1:
            self._setpoints = None  # the last one goes out once; the controller holds it
        position = float(stream.positions[i])
        self._setpoint_msg.data = [position]
        self._setpoint_pub.publish(self._setpoint_msg)
        self.recent_setpoints.append((motion.start_ns + round(float(stream.times[i]) * 1e9), position))
        self.counters.setpoints_published += 1

    # ------------------------------------------------------------------ antenna trajectories

    def _on_antenna_trajectory(self, msg: JointTrajectory) -> None:
        cfg = self._config()
        self.counters.trajectories_received += 1
        try:
            converted = convert(cfg, msg.joint_names, msg.points)
        except FourBarError as exc:
            problem = problem_of(exc)
            self.counters.rejected[problem] += 1
            self._warn(f'antenna trajectory refused ({problem.value}): {one_line(exc)}',
                       throttle_duration_sec=WARN_THROTTLE_S)
            return
        stamp = msg.header.stamp
        stamp_ns = stamp.sec * 1_000_000_000 + stamp.nanosec or self._now_ns()  # 0: start on arrival
        traj = converted.trajectory
        self.counters.trajectory_points_inserted += converted.inserted
        self.counters.trajectories_retimed += converted.retimed
        self._send(cfg, traj, stamp_ns)
        self.motion = Motion(stamp_ns, trajectory=traj)

    # ------------------------------------------------------------------ diagnostics

    def diagnostic_values(self) -> list[tuple[str, str]]:
        """Key/value pairs for the node's status: the mode and the counters."""
        return [('mode', self.mode), *((k, str(v)) for k, v in self.counters.as_dict().items())]
