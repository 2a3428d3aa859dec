"""The actuator modes of fourbar_node: the rclpy side of ``fourbar_ros.rules.serve``.

That module says what a served command or an antenna trajectory becomes; this one adapts messages, clocks, timers
and publishers. Topics per mode: docs/reference/topics.md; the motion: docs/explanation/motion.md."""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable
from typing import Any

from builtin_interfaces.msg import Duration, Time
from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool, Float64MultiArray, Header
from std_srvs.srv import Trigger  # type: ignore[import-untyped,unused-ignore]
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from fourbar_ros.config.antenna_config import AntennaConfig
from fourbar_ros.config.controllers import ForwardControllerSettings, TrajectoryControllerSettings
from fourbar_ros.core.errors import one_line
from fourbar_ros.interface.joint_trajectory import TYPE_NAMES, joint_trajectory
from fourbar_ros.interface.stamps import ns_to_seconds, seconds_to_ns, to_ns
from fourbar_ros.interface.topics import (
    ANTENNA_TRAJECTORY,
    HALT_SERVICE,
    HALT_TOPIC,
    MEASURED_JOINT_STATES,
    RESUME_SERVICE,
    Mode,
    forward_topic,
    trajectory_topic,
)
from fourbar_ros.motion.planner import JointMotionState, Setpoints
from fourbar_ros.node.controller_watch import ControllerWatch
from fourbar_ros.node.qos import qos
from fourbar_ros.node.timers import periodic_timer
from fourbar_ros.node.trajectory_goals import TrajectoryGoals
from fourbar_ros.rules.command_fate import CommandFates, Fate, FateSettings, Readiness
from fourbar_ros.rules.controller_contract import check_forward_command
from fourbar_ros.rules.diagnostics import Level
from fourbar_ros.rules.follow_check import LIKELY_CAUSES, FollowCheck
from fourbar_ros.rules.goal_outcomes import GoalOutcome
from fourbar_ros.rules.halt import Halt
from fourbar_ros.rules.model_check import SlipEvent
from fourbar_ros.rules.motion_plan import Motion
from fourbar_ros.rules.serve import (
    ActuationCounters,
    Drive,
    Outgoing,
    Refused,
    serve_antenna_trajectory,
    serve_brake,
    serve_command,
)
from fourbar_ros.rules.takeover import rest_speed
from fourbar_ros.runtime.problem_log import ProblemLog

#: Setpoints kept in ``recent_setpoints`` (the last seconds of the stream at the default rate).
RECENT_SETPOINTS = 1000
#: Period (s, node clock) of the check for a held command that expired or a sent one not reached.
FATE_CHECK_S = 0.1
#: rclpy's classes of the JointTrajectory sent (``joint_trajectory``).
MESSAGE_CLASSES = dict(zip(TYPE_NAMES, (JointTrajectory, JointTrajectoryPoint, Header, Time, Duration), strict=True))


class Actuation:
    """The trajectory or forward mode of a node (``cfg.mode``); ``config`` returns the node's running
    configuration, ``contract`` the settings of the controller the mode sends to (``actuation_contract``).
    ``subscribe_measured``: read the measured driven joint on measured_joint_states here (a component that already
    does can call ``note_measured`` instead). Each served command's fate is in ``fates``: it waits while the
    controller (``watch``) is not active or nothing is measured, and is planned from the measured state once it can
    go (``rules.command_fate``)."""

    def __init__(self, node: Node, config: Callable[[], AntennaConfig], problems: ProblemLog,
                 contract: TrajectoryControllerSettings | ForwardControllerSettings,
                 subscribe_measured: bool = True) -> None:
        cfg = config()
        self._config = config
        self._problems = problems
        self._clock: Any = node.get_clock()
        get_logger: Callable[[], Any] = node.get_logger  # rclpy's logger accessor is unannotated
        self._info: Callable[..., object] = get_logger().info
        self._warn: Callable[..., object] = get_logger().warning
        self._told_not_followed = False
        self.mode = cfg.mode
        self.contract = contract
        self.counters = ActuationCounters()
        self.motion: Motion | None = None
        self.measured: JointMotionState | None = None
        self.measured_ns = 0  # when self.measured was measured, node clock
        #: measurements stamped before this (ns, node clock: the controller's latest readiness change, or the
        #: measurements' latest stop) show the drive before it and are not planned from
        self.fresh_ns = 0
        self._measured_at = 0.0  # when it arrived, steady clock (s)
        self._setpoints: Setpoints | None = None
        #: (time on the node clock the setpoint stands for, ns; position rad) of the setpoints published
        self.recent_setpoints: deque[tuple[int, float]] = deque(maxlen=RECENT_SETPOINTS)
        #: trajectory_interface action: the trajectories go out as FollowJointTrajectory goals
        self.goals: TrajectoryGoals | None = None
        self.fates = CommandFates(FateSettings.of(cfg))
        self.theta: float | None = None  # the last measured antenna angle (rad), for the fates
        self.follow = FollowCheck(cfg.follow_tolerance, cfg.follow_timeout)
        self.not_following = ''  # why the drive did not follow the last sent command, until one is reached
        #: why the slip stop holds the drive ('' while it does not): new commands are dropped meanwhile
        self.slipped = ''
        #: the operator's halt (``halt``, ``resume``): new commands are dropped while ``halt.why`` is set
        self.halt = Halt()
        if self.mode == Mode.TRAJECTORY.value and cfg.trajectory_interface == 'action':
            self.goals = TrajectoryGoals(node, cfg.trajectory_controller, problems)
            self.goals.on_end = self._on_goal_end
        elif self.mode == Mode.TRAJECTORY.value:
            out = trajectory_topic(cfg.trajectory_controller)
            self._trajectory_pub = node.create_publisher(JointTrajectory, out.name, qos(out))
        elif self.mode == Mode.FORWARD.value:
            out = forward_topic(cfg.forward_controller)
            self._setpoint_pub = node.create_publisher(Float64MultiArray, out.name, qos(out))
            self._setpoint_msg = Float64MultiArray()
            periodic_timer(node, 1.0 / cfg.control_rate, problems.guard.wrap('control_timer', self._on_control_timer))
        else:
            raise ValueError(f'mode {self.mode!r} is not an actuator mode')
        controller = cfg.forward_controller if self.mode == Mode.FORWARD.value else cfg.trajectory_controller
        #: the controller's command topic (resolved), watched for other senders (the action interface's included: a
        #: bag of a full recording played back publishes it straight to the controller)
        self.command_topic = node.resolve_topic_name((forward_topic(controller) if self.mode == Mode.FORWARD.value
                                                      else trajectory_topic(controller)).name)
        self._node = node
        self.other_senders: list[str] = []
        self.watch = ControllerWatch(node, cfg.controller_manager, controller, problems, self._on_readiness)
        periodic_timer(node, FATE_CHECK_S, problems.guard.wrap('command_fate_timer', self._on_fate_timer))
        wrap = problems.guard.wrap
        node.create_service(Trigger, HALT_SERVICE.name, wrap('srv_halt', self._on_halt_call, _failed))
        node.create_service(Trigger, RESUME_SERVICE.name, wrap('srv_resume', self._on_resume_call, _failed))
        node.create_subscription(Bool, HALT_TOPIC.name, wrap('sub_halt', self._on_halt_msg), qos(HALT_TOPIC))
        node.create_subscription(JointTrajectory, ANTENNA_TRAJECTORY.name,
                                 problems.guard.wrap('sub_antenna_trajectory', self._on_antenna_trajectory),
                                 qos(ANTENNA_TRAJECTORY))
        if subscribe_measured:
            node.create_subscription(JointState, MEASURED_JOINT_STATES.name,
                                     problems.guard.wrap('sub_measured_joint_states', self._on_measured),
                                     qos(MEASURED_JOINT_STATES))

    def _now_ns(self) -> int:
        return int(self._clock.now().nanoseconds)

    # ------------------------------------------------------------------ measured driven joint

    def _on_measured(self, msg: JointState) -> None:
        joint = self._config().driven_joint
        if joint in msg.name:
            i = list(msg.name).index(joint)
            if i < len(msg.position):
                self.note_measured(float(msg.position[i]), float(msg.velocity[i]) if i < len(msg.velocity) else None,
                                   to_ns(msg.header.stamp))

    def note_measured(self, position: float, velocity: float | None = None, stamp_ns: int = 0) -> None:
        """The measured driven joint: position rad, velocity rad/s (None or NaN: not measured), measured at
        ``stamp_ns`` (node clock; 0: on arrival); a non-finite position is ignored."""
        if position - position == 0.0:  # finite
            stamp_ns = stamp_ns or self._now_ns()
            if stamp_ns >= self.fresh_ns and not self.fates.measured:
                self.watch.check()  # a successor manager is noticed (a readiness change, fresh_ns now) first
            if stamp_ns < self.fresh_ns:
                self.counters.measurements_outdated += 1
                return
            v = velocity if velocity is not None and velocity - velocity == 0.0 else 0.0
            self.measured = JointMotionState(position, v)
            self.measured_ns = stamp_ns
            self._measured_at = time.monotonic()
            self._check_follow(position)
            if not self.fates.measured or self.fates.unsettled:  # a command may wait for this measurement
                self.fates.measured, self.fates.unsettled = True, ''
                self._resume()

    def _check_follow(self, position: float) -> None:
        """The measured driven joint against the reference of the sent motion, while the controller is active: a
        drive that does not follow ends the command interrupted, not resumed (ERROR until a command is reached)."""
        cmd, motion = self.fates.current, self.motion
        if (cmd is None or cmd.fate is not Fate.SENT or motion is None
                or self.fates.readiness is not Readiness.ACTIVE):
            self.follow.reset()
            return
        cfg = self._config()
        self.follow.tolerance, self.follow.timeout = cfg.follow_tolerance, cfg.follow_timeout
        line = self.follow.update(motion.state_at(self.measured_ns).position, position, self.measured_ns)
        if line:
            self.not_following = line
            self.fates.interrupt(line, self._now_ns(), resumable=False)
            self._problems.warn('drive does not follow', f'command theta = {cmd.theta!r} rad interrupted: {line} '
                                f'(likely: {LIKELY_CAUSES})')

    def note_theta(self, theta: float) -> None:
        """The measured antenna angle (rad), completed from the measured driven joint: a sent command is reached
        there."""
        self.theta = theta
        cmd = self.fates.current
        if cmd is not None and cmd.fate is Fate.SENT:
            self.fates.reached(theta, self._now_ns())
            if self.fates.current is cmd and cmd.fate.final:  # reached: the drive follows
                self.not_following = ''

    # ------------------------------------------------------------------ served commands and antenna trajectories

    def command(self, theta: float) -> None:
        """Plan and send the motion to a served antenna angle theta (rad), or hold it until it can go."""
        fates, now_ns = self.fates, self._now_ns()
        fates.settings = FateSettings.of(self._config())
        if self.halt.why:
            line = self.halt.dropped_line(f'command theta = {theta!r} rad')
            if fates.receive(theta, now_ns):
                fates.refused(line)
            else:
                fates.drop(line)
            self._problems.warn('command while halted', line)
            return
        if self.slipped:  # the count may be off by the slip: a plan from it would move to a wrong place
            line = f'the motion was stopped: {self.slipped}'
            if fates.receive(theta, now_ns):
                fates.refused(line)
            else:
                fates.drop(line)
            self._problems.warn('command after a slip stop', f'command theta = {theta!r} rad dropped: {line}')
            return
        if fates.repeat(theta, now_ns, self.theta):
            return
        if fates.receive(theta, now_ns):
            self._send(theta)
        else:
            self._said(Fate.SENT)

    def _send(self, theta: float) -> None:
        """Plan the pending or resumed command and send it (its fate: sent, dropped with the refusal, or held
        while the drive is measured moving off the motion sent)."""
        cfg, now_ns = self._config(), self._now_ns()
        if self.fates.readiness is Readiness.NOT_FOLLOWED and not self._told_not_followed:
            self._told_not_followed = True
            self._info(f'controller {self.watch.controller} not followed ('
                       f'{self.watch.why_not_followed or "no controller manager seen on " + self.watch.topic}): '
                       'commands go out as they come')
        out = serve_command(cfg, self.contract, self._drive(), theta, now_ns, self.counters)
        if isinstance(out, Refused) and out.wait:
            pending = self.fates.pending
            self.fates.wait(out.wait)
            if pending is not None and pending.fate is Fate.DROPPED:
                self._problems.warn(out.key, out.line)
            elif pending is not None:  # said once per command, not at every measurement while it waits
                self._said(None)
        elif self._emit(cfg, out):
            assert not isinstance(out, Refused)
            self.fates.sent(out.motion.start_ns + seconds_to_ns(out.motion.duration))
        else:
            self.fates.refused(out.line if isinstance(out, Refused) else 'no action server')

    def _resume(self) -> None:
        """Send a held command that can now go, from the motion the controller still runs where the measured state
        agrees with it (``motion_start``), else from the measured state."""
        if self.fates.due() and not self.slipped and not self.halt.why:
            assert self.fates.current is not None
            self._send(self.fates.current.theta)

    def _on_readiness(self, new: Readiness) -> None:
        """The controller's readiness changed: a motion it no longer runs is forgotten, a held command resumed."""
        before = self.fates.current.fate if self.fates.current is not None else None
        old, now_ns = self.fates.readiness, self._now_ns()
        if old is not new:  # the drive's state is measured again before anything is planned (a manager that
            self.fresh_ns, self.fates.measured = now_ns, False  # restarts starts its hardware afresh)
        self.fates.controller(new, now_ns)
        self._info(f'controller {self.watch.controller}: {old.value} -> {new.value}')
        if new is Readiness.ACTIVE:
            self.not_following = ''  # activated again: the drive is judged afresh
        # An active trajectory controller runs its trajectory on while its hardware is inactive; a controller that
        # leaves active holds the drive where it is, and a stream of setpoints stops here.
        if not new.sendable and (new is not Readiness.HARDWARE_INACTIVE
                                 or isinstance(self.contract, ForwardControllerSettings)):
            self.motion, self._setpoints = None, None
        self._said(before)
        self._resume()

    def on_slip(self, event: SlipEvent, line: str) -> None:
        """The slip stop (``rules.model_check.SlipStop``): STOP (``line``: why) ends the command in force (sent:
        interrupted, not resumed; held: dropped) and holds the drive: in forward mode the stream stops (the controller
        holds its last setpoint), in trajectory mode a motion still running is re-planned to rest at the measured
        angle; new commands are dropped until CLEARED."""
        if event is SlipEvent.CLEARED:
            if self.slipped:
                self._info(f'slip stop cleared (the antenna sensor agrees with the model again); it was: '
                           f'{self.slipped}')
            self.slipped = ''
            return
        self.slipped = line
        fates, now_ns = self.fates, self._now_ns()
        cmd = fates.current
        if cmd is not None and cmd.fate is Fate.HELD:
            fates.drop(line)
        else:
            fates.interrupt(line, now_ns, resumable=False)
        held = self._hold(now_ns)
        self._problems.error('slip stop', f'motion stopped{held}: {line}')

    # ------------------------------------------------------------------ the operator's halt

    def on_halt(self, why: str) -> tuple[bool, str]:
        """Halt (``why``: who asked): the command in force ends (held: dropped; sent: interrupted, not resumed),
        a running motion brakes to rest within the limits (``serve_brake``; at rest nothing is sent), and new
        commands and antenna trajectories are dropped until ``on_resume``. (False, the state) if already halted;
        else (True, what was done), one line."""
        now_ns = self._now_ns()
        if not self.halt.halt(why, now_ns):
            return False, f'already halted ({self.halt.since(now_ns)})'
        line = f'halted {why}'
        cmd = self.fates.current
        if cmd is not None and cmd.fate is Fate.HELD:
            self.fates.drop(line)
        else:
            self.fates.interrupt(line, now_ns, resumable=False)
        done = self._brake(now_ns)
        self._problems.warn('halt', f'{line}: {done}; commands are dropped until ~/resume')
        return True, f'halted: {done}'

    def on_resume(self) -> tuple[bool, str]:
        """Clear the halt; nothing moves (the next command does). (False, why not) if not halted."""
        was = self.halt.resume()
        if not was:
            return False, 'not halted: nothing to resume'
        self._info(f'halt cleared (it was {was}): the next command moves the drive')
        return True, f'resumed (halted {was}): the next command moves the drive'

    def _brake(self, now_ns: int) -> str:
        """Stop a running motion (``on_halt``), or in trajectory mode a drive measured moving after the node's motion
        ended or was forgotten (another sender's, a controller's own); what was done, for the log line and the
        answer."""
        forward = self.mode == Mode.FORWARD.value
        motion, cfg, drive = self.motion, self._config(), self._drive()
        running = motion is not None and (self._setpoints is not None if forward else not motion.done(now_ns))
        moving = not forward and drive.measured is not None and abs(drive.measured.velocity) > rest_speed(cfg)
        if not running and not moving:
            return 'at rest, nothing sent'
        from_measured = self.counters.brakes_from_measured
        out = serve_brake(cfg, self.contract, drive, now_ns, self.counters)
        if isinstance(out, Refused):
            if forward:  # the stream stops: the controller holds its last setpoint
                self.motion, self._setpoints = None, None
            self._problems.error(out.key, f'halt: {out.line}')
            return out.line + (' (setpoints stopped: the controller holds the last)' if forward else '')
        if not self._emit(cfg, out):
            return 'no brake sent (no action server)'
        end = out.motion.state_at(out.motion.start_ns + seconds_to_ns(out.motion.duration)).position
        how = (' from the measured state (measured moving off the motion sent)'
               if self.counters.brakes_from_measured > from_measured else '')
        return (f'braking to rest at {cfg.driven_joint} = {end:.6g} rad{how}, '
                f'{ns_to_seconds(out.motion.start_ns - now_ns) + out.motion.duration:.3g} s from now')

    def _on_halt_call(self, _request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        _, response.message = self.on_halt('by the ~/halt service')
        response.success = True  # halted, whether now or before
        return response

    def _on_resume_call(self, _request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        response.success, response.message = self.on_resume()
        return response

    def _on_halt_msg(self, msg: Bool) -> None:
        if msg.data:  # false does nothing: a bouncing button never resumes
            self.on_halt('by the ~/halt topic')

    def _hold(self, now_ns: int) -> str:
        """Stop a running motion where the drive is measured (see ``on_slip``); what was done, for the log line."""
        if self.mode == Mode.FORWARD.value:
            running = self._setpoints is not None
            self.motion, self._setpoints = None, None
            return ' (setpoints stopped: the controller holds the last)' if running else ''
        motion, theta, cfg = self.motion, self.theta, self._config()
        if motion is None or motion.done(now_ns) or theta is None:
            return ''
        theta = min(max(theta, cfg.theta_min), cfg.theta_max)
        out = serve_command(cfg, self.contract, self._drive(), theta, now_ns, self.counters)
        if isinstance(out, Refused):
            return f' (no hold planned: {out.line})'
        if not self._emit(cfg, out):
            return ' (no hold sent)'
        return f' (held at the measured theta = {theta:.6g} rad)'

    def _on_goal_end(self, how: GoalOutcome, line: str) -> None:
        """The latest action goal ended otherwise than succeeded: its command is dropped (rejected) or
        interrupted (aborted or canceled, not resumed: the controller said why)."""
        if how is GoalOutcome.REJECTED:  # the goal's line is logged already
            self.fates.drop(line)
        else:
            self.fates.interrupt(line, self._now_ns(), resumable=False)

    def _on_fate_timer(self) -> None:
        fates = self.fates
        if fates.current is None or fates.current.fate.final:
            return
        before, cfg, now_ns = fates.current.fate, self._config(), self._now_ns()
        fates.settings = FateSettings.of(cfg)
        age = time.monotonic() - self._measured_at
        if fates.readiness is Readiness.ACTIVE and fates.measured and age > cfg.measurement_timeout:
            fates.unmeasured(f'no measured driven joint for {age:.3g} s', now_ns)
            self.fresh_ns = now_ns
        fates.tick(now_ns, self.theta)
        self._said(before)

    def _said(self, before: Fate | None) -> None:
        """A WARN (one line) when the current command's fate moved from ``before`` to held, dropped or
        interrupted."""
        cmd = self.fates.current
        if cmd is None or cmd.fate is before or cmd.fate not in (Fate.HELD, Fate.DROPPED, Fate.INTERRUPTED):
            return
        self._problems.warn(f'command {cmd.fate.value}', f'command theta = {cmd.theta!r} rad {cmd.fate.value}: '
                            f'{cmd.reason}')

    def _on_antenna_trajectory(self, msg: JointTrajectory) -> None:
        self.counters.trajectories_received += 1
        if self.halt.why:
            self._problems.warn('antenna trajectory while halted', self.halt.dropped_line('antenna trajectory'))
            return
        if self.slipped:
            self._problems.warn('antenna trajectory after a slip stop',
                                f'antenna trajectory dropped: the motion was stopped: {self.slipped}')
            return
        cfg, now_ns = self._config(), self._now_ns()
        out = serve_antenna_trajectory(cfg, self.contract, self._drive(), msg, now_ns, self.counters)
        if self._emit(cfg, out):
            self.fates.supersede('by an antenna trajectory')

    def _drive(self) -> Drive:
        fresh = self.measured_ns >= self.fresh_ns
        setpoint_ns = self.recent_setpoints[-1][0] if self.recent_setpoints else None
        return Drive(self.motion, self.measured if fresh else None, self.measured_ns, setpoint_ns)

    def _emit(self, cfg: AntennaConfig, out: Outgoing | Refused) -> bool:
        """Publish what goes out and follow its motion, or log the refusal (one line); False if nothing went out
        (a refusal, or no action server)."""
        if isinstance(out, Refused):
            self._problems.warn(out.key, out.line)
            return False
        if out.setpoints is None:
            msg = joint_trajectory(MESSAGE_CLASSES, cfg.driven_joint, out.points, out.stamp_ns)
            if self.goals is not None:
                if not self.goals.send(msg):
                    return False
            else:
                self._trajectory_pub.publish(msg)
        self.motion = out.motion
        if out.setpoints is not None:
            self._stream(out.setpoints)
        return True

    def _stream(self, stream: Setpoints) -> None:
        """Start a setpoint stream (forward mode): the first setpoint now, not one period later; one that continues
        a running stream (from its next setpoint, ``takeover``) at the next tick, when that one would have gone."""
        running, self._setpoints = self._setpoints is not None, stream
        if not running:
            self._on_control_timer()

    def _on_control_timer(self) -> None:
        stream, motion = self._setpoints, self.motion
        if stream is None or motion is None:
            return
        t = motion.elapsed(self._now_ns())
        i = max(int(stream.times.searchsorted(t, side='right')) - 1, 0)  # the latest setpoint due, never ahead
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
        self.recent_setpoints.append((motion.start_ns + seconds_to_ns(float(stream.times[i])), position))
        self.counters.setpoints_published += 1

    # ------------------------------------------------------------------ diagnostics

    def check_senders(self) -> list[str]:
        """Other nodes publishing on ``command_topic`` (their full names), logged as a warning when they change."""
        me = (self._node.get_name(), self._node.get_namespace())
        senders = sorted(f'{i.node_namespace.rstrip("/")}/{i.node_name}'
                         for i in self._node.get_publishers_info_by_topic(self.command_topic)
                         if (i.node_name, i.node_namespace) != me)
        if senders and senders != self.other_senders:
            self._warn(f'{", ".join(senders)} publish on {self.command_topic}: what they send reaches the drive '
                       f'without this node (a bag of a full recording played back? play only the command topic)')
        self.other_senders = senders
        return senders

    def diagnostics(self) -> tuple[Level, str, list[tuple[str, str]]]:
        """(level, message, key/value pairs) for the node's status: the mode, the controller's readiness and the
        current command's fate, the counters (and the goals', action interface), the halt, other senders to the
        controller. ERROR while the controller manager has deactivated the controller (with its reason), while the
        drive does not follow; WARN while another node sends to the controller, while halted, while a command is
        held, or when the latest one was dropped or interrupted."""
        senders = self.check_senders()
        values = [('mode', self.mode), ('controller', self.watch.controller),
                  ('controller_activity', self.watch.topic or f'not followed: {self.watch.why_not_followed}'),
                  *self.fates.values(), *((k, str(v)) for k, v in self.counters.as_dict().items())]
        if self.goals is not None:
            values += self.goals.diagnostic_values()
        values.append(('drive_follows', 'no: ' + self.not_following if self.not_following else 'yes'))
        deactivated = self.watch.deactivation()
        values.append(('controller_deactivated', deactivated or 'no'))
        values.append(('other_senders', ', '.join(senders) or 'none'))
        values += self.halt.values(self._now_ns())
        if deactivated:
            return Level.ERROR, (f'controller {self.watch.controller} deactivated by the controller manager: '
                                 f'{deactivated}'), values
        if self.not_following:
            return Level.ERROR, f'{self.not_following}; likely: {LIKELY_CAUSES}', values
        if senders:
            return Level.WARN, f'{", ".join(senders)} also send to the controller on {self.command_topic}', values
        if self.halt.why:
            return Level.WARN, f'halted {self.halt.since(self._now_ns())}: call ~/resume', values
        cmd = self.fates.current
        if cmd is not None and cmd.fate in (Fate.HELD, Fate.DROPPED, Fate.INTERRUPTED):
            return Level.WARN, f'command theta = {cmd.theta!r} rad {cmd.fate.value}: {cmd.reason}', values
        return Level.OK, 'ok', values


def _failed(exc: Exception) -> Trigger.Response:
    """What a halt or resume call whose callback raised answers (the exception counted and logged by the guard)."""
    return Trigger.Response(success=False, message=f'{type(exc).__name__}: {one_line(exc)}')
