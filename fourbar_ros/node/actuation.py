"""The actuator modes of fourbar_node: served commands and antenna trajectories become motion of the driven joint.

Topics per mode: docs/reference/topics.md. Served commands (after the node's accept/clamp/reject policy) are
planned from where ``rules.actuation.motion_start`` says (the motion being followed, or the measured state);
antenna trajectories are served by ``rules.actuation.serve_antenna_trajectory``: trajectory mode sends the driven
joint's trajectory, forward mode streams its spline as setpoints. Nothing leaves before the controller's contract
accepts it (``rules.controller_contract``, with the controller's settings from ``controllers_file``). What a message
becomes is ``fourbar_ros.rules.actuation``; this module only adapts messages, clocks and timers.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from typing import Any

from builtin_interfaces.msg import Duration, Time
from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from fourbar_ros.config.antenna_config import AntennaConfig
from fourbar_ros.config.controllers import ForwardControllerSettings, TrajectoryControllerSettings
from fourbar_ros.core.errors import FourBarError, one_line
from fourbar_ros.interface.topics import (
    ANTENNA_TRAJECTORY,
    MEASURED_JOINT_STATES,
    Mode,
    forward_topic,
    trajectory_topic,
)
from fourbar_ros.motion.planner import JointMotionState, Setpoints
from fourbar_ros.motion.trajectory import DrivenTrajectory
from fourbar_ros.node.qos import qos
from fourbar_ros.node.timers import periodic_timer
from fourbar_ros.rules.actuation import (
    ActuationCounters,
    Motion,
    PointFields,
    Start,
    continued,
    ends_soon,
    motion_start,
    outgoing_refusal,
    outgoing_stamp,
    plan_command,
    planned_points,
    planned_setpoints,
    point_fields,
    problem_of,
    serve_antenna_trajectory,
    takeover_lead,
    trajectory_setpoints,
)
from fourbar_ros.rules.controller_contract import check_forward_command
from fourbar_ros.runtime.problem_log import ProblemLog

#: Setpoints kept in ``recent_setpoints`` (the last seconds of the stream at the default rate).
RECENT_SETPOINTS = 1000

def trajectory_message(joint: str, points: list[PointFields], stamp_ns: int) -> JointTrajectory:
    """The JointTrajectory of ``point_fields`` for ``joint``, header stamp ``stamp_ns`` (0: start on arrival)."""
    msg = JointTrajectory(joint_names=[joint], points=[
        JointTrajectoryPoint(positions=p.positions, velocities=p.velocities, accelerations=p.accelerations,
                             effort=p.effort, time_from_start=Duration(sec=p.time_from_start.sec,
                                                                       nanosec=p.time_from_start.nanosec))
        for p in points])
    msg.header.stamp = Time(sec=stamp_ns // 1_000_000_000, nanosec=stamp_ns % 1_000_000_000)
    return msg


class Actuation:
    """The trajectory or forward mode of a node (``cfg.mode``); ``config`` returns the node's running
    configuration, ``contract`` the settings of the controller the mode sends to (``actuation_contract``).
    ``subscribe_measured``: read the measured driven joint on measured_joint_states here (a component that already
    does can call ``note_measured`` instead)."""

    def __init__(self, node: Node, config: Callable[[], AntennaConfig], problems: ProblemLog,
                 contract: TrajectoryControllerSettings | ForwardControllerSettings,
                 subscribe_measured: bool = True) -> None:
        cfg = config()
        self._config = config
        self._problems = problems
        self._clock: Any = node.get_clock()
        self.mode = cfg.mode
        self.contract = contract
        self.counters = ActuationCounters()
        self.motion: Motion | None = None
        self.measured: JointMotionState | None = None
        self.measured_ns = 0  # when self.measured was measured, node clock
        self._setpoints: Setpoints | None = None
        #: (time on the node clock the setpoint stands for, ns; position rad) of the setpoints published
        self.recent_setpoints: deque[tuple[int, float]] = deque(maxlen=RECENT_SETPOINTS)
        if self.mode == Mode.TRAJECTORY.value:
            out = trajectory_topic(cfg.trajectory_controller)
            self._trajectory_pub = node.create_publisher(JointTrajectory, out.name, qos(out))
        elif self.mode == Mode.FORWARD.value:
            out = forward_topic(cfg.forward_controller)
            self._setpoint_pub = node.create_publisher(Float64MultiArray, out.name, qos(out))
            self._setpoint_msg = Float64MultiArray()
            periodic_timer(node, 1.0 / cfg.control_rate, problems.guard.wrap('control_timer', self._on_control_timer))
        else:
            raise ValueError(f'mode {self.mode!r} is not an actuator mode')
        node.create_subscription(JointTrajectory, ANTENNA_TRAJECTORY.name,
                                 problems.guard.wrap('sub_antenna_trajectory', self._on_antenna_trajectory),
                                 qos(ANTENNA_TRAJECTORY))
        if subscribe_measured:
            node.create_subscription(JointState, MEASURED_JOINT_STATES.name,
                                     problems.guard.wrap('sub_measured_joint_states', self._on_measured),
                                     qos(MEASURED_JOINT_STATES))

    def _now_ns(self) -> int:
        ns: int = self._clock.now().nanoseconds
        return ns

    # ------------------------------------------------------------------ measured driven joint

    def _on_measured(self, msg: JointState) -> None:
        joint = self._config().driven_joint
        if joint in msg.name:
            i = list(msg.name).index(joint)
            if i < len(msg.position):
                stamp = msg.header.stamp
                self.note_measured(float(msg.position[i]), float(msg.velocity[i]) if i < len(msg.velocity) else None,
                                   stamp.sec * 1_000_000_000 + stamp.nanosec)

    def note_measured(self, position: float, velocity: float | None = None, stamp_ns: int = 0) -> None:
        """The measured driven joint: position rad, velocity rad/s (None or NaN: not measured), measured at
        ``stamp_ns`` (node clock; 0: on arrival); a non-finite position is ignored."""
        if position - position == 0.0:  # finite
            v = velocity if velocity is not None and velocity - velocity == 0.0 else 0.0
            self.measured = JointMotionState(position, v)
            self.measured_ns = stamp_ns if stamp_ns else self._now_ns()

    def start_state(self, now_ns: int) -> Start | None:
        """Where a new motion starts (``motion_start``: in trajectory mode ``takeover_lead`` ahead of now when it
        continues the running motion); counts a motion left for the measured state, and a measured start moved
        onto the range."""
        cfg = self._config()
        lead = takeover_lead(cfg) if self.mode == Mode.TRAJECTORY.value else 0.0
        start = motion_start(cfg, self.motion, self.measured, now_ns, lead, self.measured_ns)
        if start is not None:
            self.counters.commands_replanned_from_measured += start.from_measured
            self.counters.measured_start_clamped += start.clamped
        return start

    # ------------------------------------------------------------------ plain commands

    def command(self, theta: float) -> None:
        """Plan and send the motion to a served antenna angle theta (rad)."""
        cfg = self._config()
        now_ns = self._now_ns()
        start = self.start_state(now_ns)
        if start is None:
            self.counters.commands_not_planned += 1
            self._problems.warn('command no start', f'command theta = {theta!r} rad not planned: no measured '
                                f'{cfg.driven_joint} on {MEASURED_JOINT_STATES.name} yet')
            return
        try:
            plan = plan_command(cfg, start.state, theta)
            if start.before is not None and ends_soon(start, plan.duration, now_ns):
                start = start.here(now_ns)  # too short to stamp (``outgoing_stamp``): from the motion's state now
                plan = plan_command(cfg, start.state, theta)
            points = (continued(start, planned_points(cfg, plan)) if self.mode == Mode.TRAJECTORY.value
                      else None)
            stream = planned_setpoints(cfg, plan) if points is None else None
        except FourBarError as exc:
            self.counters.commands_not_planned += 1
            self._problems.warn(f'command {type(exc).__name__}',
                                f'command theta = {theta!r} rad not planned: {one_line(exc)}')
            return
        if points is not None:
            if not self._send(cfg, points, outgoing_stamp(cfg, start, points, now_ns), now_ns, 'trajectory'):
                self.counters.commands_not_planned += 1
                return
            self.motion = Motion(start.origin_ns, trajectory=points)
        else:
            self.motion = Motion(now_ns, plan=plan)
        self.counters.commands_planned += 1
        if stream is not None:
            self._stream(stream)

    def _send(self, cfg: AntennaConfig, traj: DrivenTrajectory, stamp_ns: int, now_ns: int, what: str) -> bool:
        """Send a trajectory stamped ``stamp_ns`` (0: start on arrival) if the controller's contract takes it; else
        count the refusal, log one line naming ``what``, and return False."""
        assert isinstance(self.contract, TrajectoryControllerSettings)
        points = point_fields(traj, cfg.effort_feedforward)
        refusal = outgoing_refusal(self.contract, cfg.driven_joint, points, stamp_ns, now_ns)
        if refusal is not None:
            self.counters.refused[refusal.rule] += 1
            self._problems.warn(f'{what} refused {refusal.rule.value}', f'{what} not sent: the controller would '
                                f'refuse it ({refusal.rule.value}): {refusal.reason}')
            return False
        self._trajectory_pub.publish(trajectory_message(cfg.driven_joint, points, stamp_ns))
        self.counters.trajectories_sent += 1
        self.counters.trajectory_points_sent += len(traj)
        return True

    def _stream(self, stream: Setpoints) -> None:
        """Start a setpoint stream (forward mode): the first setpoint now, not one period later."""
        self._setpoints = stream
        self._on_control_timer()

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
        data = [position]
        assert isinstance(self.contract, ForwardControllerSettings)
        refusal = check_forward_command(self.contract, data)
        if refusal is not None:  # pragma: no cover - one joint by construction (actuation_contract)
            self.counters.refused[refusal.rule] += 1
            self._setpoints = None
            return
        self._setpoint_msg.data = data
        self._setpoint_pub.publish(self._setpoint_msg)
        self.recent_setpoints.append((motion.start_ns + round(float(stream.times[i]) * 1e9), position))
        self.counters.setpoints_published += 1

    # ------------------------------------------------------------------ antenna trajectories

    def _on_antenna_trajectory(self, msg: JointTrajectory) -> None:
        cfg = self._config()
        self.counters.trajectories_received += 1
        now_ns = self._now_ns()
        stamp = msg.header.stamp
        stamp_ns = stamp.sec * 1_000_000_000 + stamp.nanosec  # 0: start on arrival
        allow_moving_end = (isinstance(self.contract, TrajectoryControllerSettings)
                            and self.contract.allow_nonzero_velocity_at_trajectory_end)
        try:
            # Joined to the drive only where it is measured: a model of the motion alone is not where the drive is.
            start = self.start_state(now_ns) if self.measured is not None else None
            converted = serve_antenna_trajectory(cfg, allow_moving_end, msg.joint_names, msg.points, stamp_ns, now_ns,
                                                 start)
            stream = trajectory_setpoints(cfg, converted.trajectory) if self.mode == Mode.FORWARD.value else None
        except FourBarError as exc:
            problem = problem_of(exc)
            self.counters.rejected[problem] += 1
            self._problems.warn(f'antenna trajectory {problem.value}',
                                f'antenna trajectory refused ({problem.value}): {one_line(exc)}')
            return
        traj = converted.trajectory
        if stream is None and not self._send(cfg, traj, converted.stamp_ns, now_ns, 'antenna trajectory'):
            return
        self.counters.trajectory_points_inserted += converted.inserted
        self.counters.trajectories_retimed += converted.retimed
        self.counters.trajectories_connected += start is not None
        self.motion = Motion(converted.stamp_ns or now_ns, trajectory=traj)
        if stream is not None:
            self._stream(stream)

    # ------------------------------------------------------------------ diagnostics

    def diagnostic_values(self) -> list[tuple[str, str]]:
        """Key/value pairs for the node's status: the mode and the counters."""
        return [('mode', self.mode), *((k, str(v)) for k, v in self.counters.as_dict().items())]
