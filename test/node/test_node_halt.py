"""fourbar_node's halt over the real middleware, driving the simulated actuator (trajectory and forward mode): a halt
during a motion brakes the drive to rest within the motor's speed, acceleration and jerk limits, short of the
command's target; the command in force ends interrupted; while halted a command and an antenna trajectory are
dropped and nothing is sent, a controller deactivated and activated again moves nothing, a second halt answers
success and says so; resume moves nothing, the next command moves. A halt at rest sends nothing; on the ``~/halt``
topic true halts and false does nothing.

Each test prints the time from the halt call to the drive at rest (the simulated drive's measurement, node clock).
No timing is asserted: each check waits for a state with a deadline."""

from __future__ import annotations

import itertools
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from builtin_interfaces.msg import Duration, Time
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool, Float64, Float64MultiArray
from std_srvs.srv import Trigger
from support.ros_support import Collector, RosSession, wait_for
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from fourbar_ros.config.antenna_config import default_config
from fourbar_ros.interface.joint_trajectory import joint_trajectory
from fourbar_ros.interface.stamps import to_ns
from fourbar_ros.interface.topics import ANTENNA_JOINT, BROADCASTER_JOINT_STATES, MEASURED_JOINT_STATES, NODE_NAME
from fourbar_ros.motion.limits import JointLimits
from fourbar_ros.motion.planner import PLAN_SHRINK, JointMotionState, driven_angles
from fourbar_ros.node.actuation import MESSAGE_CLASSES
from fourbar_ros.node.fourbar_node import FourBarNode
from fourbar_ros.node.sim_actuator import SimActuator
from fourbar_ros.rules.command_fate import Fate, Readiness
from fourbar_ros.rules.diagnostics import Level
from fourbar_ros.rules.halt import HALTED_LINE
from fourbar_ros.rules.outgoing import actuation_contract
from fourbar_ros.rules.serve import ActuationCounters, Drive, Outgoing, serve_command

pytestmark = pytest.mark.ros

CFG = default_config()
LIMITS = JointLimits.from_config(CFG)
JOINT = CFG.driven_joint
#: At rest: measured within this of a position (rad) and this slow (rad/s); the simulated drive lands on a reference
#: at rest (its last braking step) and is then still (no noise by default).
SETTLED = 1e-9
#: The controller's reference holds the limits to rounding: the closed-form extremes of its quintics.
ROUNDING = 1e-9
_ns = itertools.count()


def q_of(theta: float) -> float:
    return float(driven_angles(CFG, np.array([theta]))[0])


class Rig:
    """fourbar_node in ``mode`` and the simulated actuator in a namespace of their own, with the halt's clients."""

    def __init__(self, ros: RosSession, mode: str) -> None:
        self.ros, self.mode = ros, mode
        self.ns = f'/halt_{mode}_{next(_ns)}'
        self.sim = SimActuator(context=ros.context, namespace=self.ns)
        self.node = FourBarNode(context=ros.context, namespace=self.ns,
                                parameter_overrides=[Parameter('mode', value=mode)],
                                cli_args=['--ros-args', '-r', f'{MEASURED_JOINT_STATES.name}:='
                                                              f'{BROADCASTER_JOINT_STATES.name}'])
        self.taken_over: list[Any] = []  # the simulated controller's reference of every trajectory it took over
        self.lines: list[tuple[str, str]] = []  # (level, line) of every warning and error the node logged
        log = self.node.problems._log

        def logged(level: str, line: str) -> object:
            self.lines.append((level, line))
            return log(level, line)
        self.node.problems._log = logged
        self.sim.follower.on_takeover = self.taken_over.append
        ros.add_node(self.sim)
        ros.add_node(self.node)
        self.measured: Collector[JointState] = ros.collect(JointState, f'{self.ns}/{BROADCASTER_JOINT_STATES.name}')
        self.trajectories: Collector[JointTrajectory] = ros.collect(
            JointTrajectory, f'{self.ns}/{CFG.trajectory_controller}/joint_trajectory', 10)
        self.setpoints: Collector[Float64MultiArray] = ros.collect(
            Float64MultiArray, f'{self.ns}/{CFG.forward_controller}/commands', 10)
        self.cmd = ros.publisher(Float64, f'{self.ns}/antenna_angle_cmd', 10)
        self.antenna = ros.publisher(JointTrajectory, f'{self.ns}/antenna_trajectory', 10)
        self.button = ros.publisher(Bool, f'{self.ns}/{NODE_NAME}/halt', 10)
        node_name = f'{self.ns}/{NODE_NAME}'
        self.halt_client = ros.node.create_client(Trigger, f'{node_name}/halt')
        self.resume_client = ros.node.create_client(Trigger, f'{node_name}/resume')
        for pub in (self.cmd, self.antenna, self.button):
            ros.wait_subscribers(pub)
        out = self.actuation._trajectory_pub if mode == 'trajectory' else self.actuation._setpoint_pub
        ros.wait_subscribers(out, 2)  # the sim and the test
        for client in (self.halt_client, self.resume_client):
            assert client.wait_for_service(timeout_sec=10.0), f'no service {client.srv_name}'
        wait_for(lambda: self.actuation.measured is not None, what='the measured driven joint at the node')

    @property
    def actuation(self) -> Any:
        return self.node.actuation

    def now_ns(self) -> int:
        ns: int = self.node.get_clock().now().nanoseconds
        return ns

    def sent(self) -> int:
        """What the node sent so far: trajectories, or setpoints in forward mode."""
        c = self.actuation.counters
        return c.trajectories_sent if self.mode == 'trajectory' else c.setpoints_published

    def call(self, client: Any) -> Any:
        """Call a Trigger service; its response."""
        future = client.call_async(Trigger.Request())
        wait_for(future.done, what=f'the answer of {client.srv_name}')
        return future.result()

    def command(self, theta: float) -> None:
        """Publish a command and wait until the node gave it a fate."""
        before = sum(self.actuation.fates.counts.values())
        self.cmd.publish(Float64(data=theta))
        self.ros.wait_for(lambda: sum(self.actuation.fates.counts.values()) > before, what='the command taken')

    def at_rest(self, position: float, start: int = 0) -> JointState:
        """The first measurement from ``start`` on at rest at ``position`` (rad), once the node has one too."""
        def still(q: float, v: float) -> bool:
            return abs(q - position) <= SETTLED and abs(v) <= SETTLED

        try:
            m = self.measured.wait_match(lambda m: still(m.position[0], m.velocity[0]), start=start)
            self.ros.wait_for(lambda: (s := self.actuation.measured) is not None and still(s.position, s.velocity),
                              what=f'the node\'s measured driven joint at rest at {position!r} rad')
        except AssertionError as exc:
            raise AssertionError(f'{exc}\n{self.sides()}') from None
        return m

    def moving_fast(self) -> None:
        """Wait until the drive is measured near the plan's top speed (the motion's cruise)."""
        fast = 0.9 * PLAN_SHRINK * LIMITS.at_rocker(1)
        self.measured.wait_match(lambda m: abs(m.velocity[0]) >= fast, start=len(self.measured))

    def status(self) -> tuple[Level, str, dict[str, str]]:
        with self.ros.paused():
            s = self.node.diagnostic_status()
        return Level(s.level[0]), s.message, {kv.key: kv.value for kv in s.values}

    def sides(self) -> str:
        follower = self.sim.follower
        return (f'node: {self.actuation.counters.as_dict()}, {self.actuation.halt}, fate '
                f'{self.actuation.fates.current}; sim: drive at {self.sim.drive.position!r} rad, '
                f'{follower.counters.as_dict()}, holding: {follower.holding_reason}, {self.sim.counters}')

    def close(self) -> None:
        for c in (self.measured, self.trajectories, self.setpoints):
            self.ros.uncollect(c)
        self.ros.destroy(self.cmd, self.antenna, self.button, self.halt_client, self.resume_client)
        self.ros.remove_node(self.node)
        self.ros.remove_node(self.sim)


@pytest.fixture(scope='module')
def traj(ros: RosSession) -> Iterator[Rig]:
    rig = Rig(ros, 'trajectory')
    yield rig
    rig.close()


@pytest.fixture
def fwd(ros: RosSession) -> Iterator[Rig]:
    rig = Rig(ros, 'forward')
    yield rig
    rig.close()


def planned_end(motion: Any, t0_ns: int) -> float:
    """When (s after ``t0_ns``, node clock) ``motion`` (the brake, from its origin) plans the drive at rest."""
    return float((motion.start_ns - t0_ns) * 1e-9 + motion.duration)


def ratio(ref: Any) -> float:
    """The largest of a controller reference's motor speed, acceleration and jerk over the limits (its lead-in
    included)."""
    return max(LIMITS.ratio * v / LIMITS.motor(order) for order, v in ref.extremes().items())


def stream_over_limits(times_ns: Any, q: Any) -> list[str]:
    """What of a setpoint stream (node-clock ns, rad) is over the limits, by its divided differences: k! f[t_i ..
    t_i+k] is the k-th derivative of the motion sampled somewhere between its samples, so samples of a motion within
    the limits pass, up to the positions' rounding (half an ulp each moves an order-k difference by at most 2^k ulp
    / h^k)."""
    t, diff, factorial, over = times_ns * 1e-9, q, 1.0, []
    ulp = float(np.spacing(np.max(np.abs(q))))
    h = float(np.min(np.diff(t)))
    for order in (1, 2, 3):
        diff = np.diff(diff) / (t[order:] - t[:-order])
        factorial *= order
        worst = float(np.max(np.abs(factorial * diff)))
        bound = LIMITS.at_rocker(order) + 2.0 ** order * ulp / h ** order
        if worst > bound:
            over.append(f'order {order}: {worst!r} over {bound!r}')
    return over


def halted_checks(rig: Rig, theta: float) -> None:
    """While halted: a second halt answers success and says so, a command and an antenna trajectory are dropped
    with nothing sent, the status is WARN naming the halt, a controller deactivated and activated moves nothing."""
    act = rig.actuation
    again = rig.call(rig.halt_client)
    assert again.success and again.message.startswith('already halted (by the ~/halt service, '), again.message
    sent, dropped = rig.sent(), act.fates.counts[Fate.DROPPED]
    rig.command(theta)
    assert act.fates.counts[Fate.DROPPED] == dropped + 1, act.fates.counts
    line = f'command theta = {theta!r} rad dropped: {HALTED_LINE} (halted by the ~/halt service)'
    assert ('warn', line) in rig.lines, rig.lines
    received = act.counters.trajectories_received
    rig.antenna.publish(JointTrajectory(joint_names=[ANTENNA_JOINT], points=[JointTrajectoryPoint(
        positions=[0.0], time_from_start=Duration(sec=1))]))
    rig.ros.wait_for(lambda: act.counters.trajectories_received == received + 1, what='the antenna trajectory taken')
    assert ('warn', f'antenna trajectory dropped: {HALTED_LINE} (halted by the ~/halt service)') in rig.lines
    level, message, values = rig.status()
    assert level is Level.WARN and message.startswith('halted by the ~/halt service, ') and message.endswith(
        'call ~/resume'), message
    assert values['halted'].startswith('yes: by the ~/halt service, ') and values['halts'] == '1', values
    assert values['halts_repeated'] == '1' and values['halt_dropped'] == '2', values
    # the command in force stays the one the halt ended (a dropped new one never becomes current)
    assert values['command_fate'] == 'interrupted' and values['command_fate_reason'] == 'halted by the ~/halt ' \
        'service', values
    # The controller deactivated and activated again (as switch_controllers does): the sim holds the drive, the
    # node hears it through the controller manager's activity where controller_manager_msgs is installed, else is
    # told here as its watch would tell it; once it has measured the drive again, it has sent nothing.
    for active in (False, True):
        assert rig.sim.set_parameters([Parameter('controller_active', value=active)])[0].successful
        want = Readiness.ACTIVE if active else Readiness.INACTIVE
        if act.watch.readiness is Readiness.NOT_FOLLOWED:
            with rig.ros.paused():
                act._on_readiness(want)
        else:
            rig.ros.wait_for(lambda w=want: act.fates.readiness is w, what=f'the node to see {want.value}')
    rig.ros.wait_for(lambda: act.fates.measured, what='the drive measured again after the activation')
    rig.measured.wait_count(len(rig.measured) + 3)
    with rig.ros.paused():
        assert rig.sent() == sent, f'sent while halted: {rig.sides()}'


def resume_then_move(rig: Rig, theta: float) -> None:
    """Resume moves nothing; the next command moves the drive to its target."""
    act = rig.actuation
    sent = rig.sent()
    answer = rig.call(rig.resume_client)
    assert answer.success and answer.message.startswith('resumed (halted by the ~/halt service'), answer.message
    rig.measured.wait_count(len(rig.measured) + 3)
    with rig.ros.paused():
        assert rig.sent() == sent, f'sent on resume: {rig.sides()}'
    _, _, values = rig.status()
    assert values['halted'] == 'no' and values['halt_resumes'] == '1', values
    assert not rig.call(rig.resume_client).success  # not halted: nothing to resume
    mark = len(rig.measured)
    rig.command(theta)
    assert act.fates.current is not None and act.fates.current.fate is Fate.SENT, act.fates.current
    rig.at_rest(q_of(theta), mark)


def test_a_halt_during_a_motion_brakes_the_drive_to_rest_within_the_limits_short_of_the_target(traj: Rig) -> None:
    rig, act = traj, traj.actuation
    q_start, q_target = act.measured.position, q_of(CFG.theta_max)
    direction = np.sign(q_target - q_start)
    first = len(rig.trajectories)
    rig.command(CFG.theta_max)  # a motion of seconds
    rig.trajectories.wait_count(first + 1)
    rig.moving_fast()
    taken = len(rig.taken_over)
    t0 = rig.now_ns()
    answer = rig.call(rig.halt_client)
    assert answer.success and answer.message.startswith('halted: braking to rest at '), answer.message
    cmd = act.fates.current
    assert cmd is not None and cmd.fate is Fate.INTERRUPTED and cmd.reason == 'halted by the ~/halt service', cmd
    brake = rig.trajectories.wait_count(first + 2)[-1]
    q_rest = brake.points[-1].positions[0]
    assert abs(brake.points[-1].velocities[0]) <= 1.2e-7, brake.points[-1]  # at rest, to the planner's rounding
    # short of the target, on the way to it (no turn back): beyond where the drive was measured at the call
    assert direction * (q_target - q_rest) > 0.0, (q_rest, q_target)
    mark = len(rig.measured)
    rest = rig.at_rest(q_rest, mark)
    wait_for(lambda: len(rig.taken_over) > taken, what='the brake taken over')
    worst = [ratio(ref) for ref in rig.taken_over[taken - 1:]]  # the command's motion and the brake, whole
    assert max(worst) <= 1.0 + ROUNDING, (worst, rig.sides())
    moving = [m for m in rig.measured.messages[:mark] if to_ns(m.header.stamp) <= t0]
    assert direction * (q_rest - moving[-1].position[0]) > 0.0, (q_rest, moving[-1])
    print(f'\ntrajectory mode: halted at {moving[-1].velocity[0]:.4g} rad/s; the drive at rest at {q_rest:.6f} rad '
          f'{(to_ns(rest.header.stamp) - t0) * 1e-9:.3f} s after the halt call (the brake departs at the takeover, '
          f'up to 0.25 s after the call; planned at rest {planned_end(act.motion, t0):.3f} s after it); '
          f'{q_target - q_rest:+.4f} rad short of the target; the references\' worst limit ratio {max(worst):.9f}')
    halted_checks(rig, CFG.theta_max)
    resume_then_move(rig, 0.0)


def test_a_halt_at_rest_sends_nothing_and_the_topic_halts_on_true_only(traj: Rig) -> None:
    rig, act = traj, traj.actuation
    if act.halt.why:  # left halted by a failed test before
        rig.call(rig.resume_client)
    mark = len(rig.measured)
    rig.command(0.02)
    rig.at_rest(q_of(0.02), mark)
    halts, repeated, resumes, sent = act.halt.halts, act.halt.repeated, act.halt.resumes, rig.sent()
    rig.button.publish(Bool(data=True))
    rig.ros.wait_for(lambda: act.halt.halts == halts + 1, what='the halt from the topic')
    assert act.halt.why == 'by the ~/halt topic', act.halt
    rig.button.publish(Bool(data=False))  # does nothing ...
    rig.button.publish(Bool(data=True))  # ... as this one, taken after it, shows: still halted
    rig.ros.wait_for(lambda: act.halt.repeated == repeated + 1, what='the second true taken')
    assert act.halt.why == 'by the ~/halt topic' and act.halt.resumes == resumes, act.halt
    with rig.ros.paused():
        assert rig.sent() == sent, rig.sides()
    answer = rig.call(rig.resume_client)
    assert answer.success, answer.message
    answer = rig.call(rig.halt_client)
    assert answer.success and answer.message == 'halted: at rest, nothing sent', answer.message
    rig.measured.wait_count(len(rig.measured) + 3)
    with rig.ros.paused():
        assert rig.sent() == sent, rig.sides()
    assert rig.call(rig.resume_client).success


#: replan_tolerance (rad) for the off-motion halt, and the measurement jump (rad) behind the sim's latest: with the
#: drive's own lag behind its reference (>= 0) the node's measured state is off the motion by more than the tolerance.
#: The jump is small so that the controller's lead-in, which starts from the drive's true state and so bridges it, is
#: a motion within the limits too: a cubic bridging 2e-5 rad in d s peaks at 6 * 2e-5 / d^2 rad/s^2 and
#: 12 * 2e-5 / d^3 rad/s^3, within 0.2 and 2.0 for a takeover up to 0.2 s after the call (d >= 0.05 s).
OFF_TOLERANCE, JUMP = 1e-5, 2e-5


def test_a_halt_with_the_drive_measured_moving_off_the_motion_brakes_from_the_measured_state(traj: Rig) -> None:
    """The node's measured state jumps off its motion while the drive cruises (a faulty count, beside the sim's own
    measurements), and the halt comes before the sim's next: the brake is planned from the measured state (no start
    on the motion can be vouched for), sent, taken over, and the drive comes to rest within the limits, short of
    the target. The jump and the halt are handed to the node's own callbacks back to back with the executor paused,
    so that the sim's next measurement cannot come between them."""
    rig, act = traj, traj.actuation
    if act.halt.why:  # left halted by a failed test before
        rig.call(rig.resume_client)
    tolerance = rig.node.get_parameter('replan_tolerance').value
    assert rig.node.set_parameters([Parameter('replan_tolerance', value=OFF_TOLERANCE)])[0].successful
    try:
        q_start = act.measured.position
        lower, upper = q_of(CFG.theta_min), q_of(CFG.theta_max)
        target = CFG.theta_max if q_start - lower < upper - q_start else CFG.theta_min
        q_target = q_of(target)
        direction = float(np.sign(q_target - q_start))
        first, taken = len(rig.trajectories), len(rig.taken_over)
        rig.command(target)
        rig.trajectories.wait_count(first + 1)
        cruise = PLAN_SHRINK * LIMITS.at_rocker(1)

        def cruising(m: JointState) -> bool:
            """Measured half a second (ten lag time constants) into the plan's cruise: the drive's lag settled."""
            motion = act.motion
            t = to_ns(m.header.stamp)
            return motion is not None and all(
                abs(s.acceleration) <= 1e-9 and abs(abs(s.velocity) - cruise) <= 1e-9 * cruise
                for s in (motion.state_at(t - 500_000_000), motion.state_at(t)))
        rig.measured.wait_match(cruising, start=len(rig.measured))
        from_measured, brakes = act.counters.brakes_from_measured, act.counters.brakes_planned
        with rig.ros.paused():
            m, m_ns = act.measured, act.measured_ns
            jumped = JointState(name=[JOINT], position=[m.position - direction * JUMP], velocity=[m.velocity],
                                effort=[0.0])
            jumped.header.stamp = Time(sec=m_ns // 10**9, nanosec=m_ns % 10**9)
            act._on_measured(jumped)
            on = act.motion.state_at(act.measured_ns)
            off = act.measured.position - on.position
            t0 = rig.now_ns()
            answer = act._on_halt_call(Trigger.Request(), Trigger.Response())
        assert abs(off) > OFF_TOLERANCE, (off, m, on)
        assert answer.success and answer.message.startswith('halted: braking to rest at ') and \
            'from the measured state' in answer.message, (answer.message, rig.sides())
        assert (act.counters.brakes_planned, act.counters.brakes_from_measured) == (brakes + 1, from_measured + 1)
        brake = rig.trajectories.wait_count(first + 2)[-1]
        q_rest = brake.points[-1].positions[0]
        q_from = m.position - direction * JUMP
        assert direction * (q_rest - q_from) > 0.0 and direction * (q_target - q_rest) > 0.0, (q_from, q_rest,
                                                                                               q_target)
        rest = rig.at_rest(q_rest, len(rig.measured))
        wait_for(lambda: len(rig.taken_over) > taken + 1, what='the brake taken over')
        worst = ratio(rig.taken_over[-1])  # the brake as the controller runs it, its lead-in from the drive included
        assert worst <= 1.0 + ROUNDING, (worst, rig.taken_over[-1], rig.sides())
        print(f'\noff the motion by {off:+.3g} rad at {m.velocity:.4g} rad/s: the drive at rest at {q_rest:.6f} rad '
              f'{(to_ns(rest.header.stamp) - t0) * 1e-9:.3f} s after the halt (planned at rest '
              f'{planned_end(act.motion, t0):.3f} s after it); {q_target - q_rest:+.4f} rad short of the target; '
              f'the brake\'s worst limit ratio {worst:.6f}')
    finally:
        rig.node.set_parameters([Parameter('replan_tolerance', value=tolerance)])
        if act.halt.why:
            rig.call(rig.resume_client)


def test_a_halt_with_the_drive_moved_by_another_sender_brakes_it_from_the_measured_state(traj: Rig) -> None:
    """The node's own motion has ended; another sender's trajectory moves the drive (published to the controller
    as the node would): the halt brakes the drive from its measured state, and it comes to rest within the limits
    (the controller's reference of the brake, lead-in from the drive included), short of the other motion's end."""
    rig, act = traj, traj.actuation
    if act.halt.why:  # left halted by a failed test before
        rig.call(rig.resume_client)
    other = rig.ros.publisher(JointTrajectory, f'{rig.ns}/{CFG.trajectory_controller}/joint_trajectory', 10)
    try:
        rig.ros.wait_subscribers(other, 2)  # the sim and the test's collector
        with rig.ros.paused():
            m = act.measured
            now = rig.now_ns()
        assert abs(m.velocity) <= SETTLED and (act.motion is None or act.motion.done(now)), (m, rig.sides())
        lower, upper = q_of(CFG.theta_min), q_of(CFG.theta_max)
        target = CFG.theta_max if m.position - lower < upper - m.position else CFG.theta_min
        direction = float(np.sign(q_of(target) - m.position))
        out = serve_command(CFG, actuation_contract(CFG, 'trajectory'), Drive(None, JointMotionState(m.position), now),
                            target, now, ActuationCounters())
        assert isinstance(out, Outgoing), out
        sent, taken, brakes = rig.sent(), len(rig.taken_over), act.counters.brakes_from_measured
        collected = len(rig.trajectories)
        other.publish(joint_trajectory(MESSAGE_CLASSES, JOINT, out.points, out.stamp_ns))
        rig.trajectories.wait_count(collected + 1)
        cruise = PLAN_SHRINK * LIMITS.at_rocker(1)

        def cruising(msg: JointState) -> bool:
            """Half a second (ten lag time constants) into the other motion's cruise."""
            t = to_ns(msg.header.stamp)
            return all(abs(s.acceleration) <= 1e-9 and abs(abs(s.velocity) - cruise) <= 1e-9 * cruise
                       for s in (out.motion.state_at(t - 500_000_000), out.motion.state_at(t)))
        moving = rig.measured.wait_match(cruising, start=len(rig.measured))
        first = len(rig.trajectories)
        t0 = rig.now_ns()
        answer = rig.call(rig.halt_client)
        assert answer.success and answer.message.startswith('halted: braking to rest at ') and \
            'from the measured state' in answer.message, (answer.message, rig.sides())
        assert act.counters.brakes_from_measured == brakes + 1 and rig.sent() == sent + 1, rig.sides()
        brake = rig.trajectories.wait_count(first + 1)[-1]
        q_rest = brake.points[-1].positions[0]
        assert direction * (q_rest - moving.position[0]) > 0.0 and direction * (q_of(target) - q_rest) > 0.0, (
            moving.position[0], q_rest, q_of(target))
        rest = rig.at_rest(q_rest, len(rig.measured))
        wait_for(lambda: len(rig.taken_over) > taken + 1, what='the brake taken over')
        worst = ratio(rig.taken_over[-1])
        assert worst <= 1.0 + ROUNDING, (worst, rig.taken_over[-1], rig.sides())
        print(f'\nanother sender\'s motion at {moving.velocity[0]:.4g} rad/s: the drive at rest at {q_rest:.6f} rad '
              f'{(to_ns(rest.header.stamp) - t0) * 1e-9:.3f} s after the halt call; the brake\'s worst limit ratio '
              f'{worst:.6f}')
    finally:
        rig.ros.destroy(other)
        if act.halt.why:
            rig.call(rig.resume_client)


def test_in_forward_mode_a_halt_brakes_the_stream_on_its_grid_within_the_limits(fwd: Rig) -> None:
    rig, act = fwd, fwd.actuation
    q_start, q_target = act.measured.position, q_of(CFG.theta_max)
    direction = np.sign(q_target - q_start)
    rig.command(CFG.theta_max)
    rig.moving_fast()
    t0 = rig.now_ns()
    answer = rig.call(rig.halt_client)
    assert answer.success and answer.message.startswith('halted: braking to rest at '), answer.message
    cmd = act.fates.current
    assert cmd is not None and cmd.fate is Fate.INTERRUPTED, cmd
    rig.ros.wait_for(lambda: act._setpoints is None, what='the brake streamed to its end')
    with rig.ros.paused():
        recorded = list(act.recent_setpoints)
    q_rest = recorded[-1][1]
    assert direction * (q_target - q_rest) > 0.0, (q_rest, q_target)
    rest = rig.at_rest(q_rest)
    # The whole stream, the command's and the brake's (one grid: the brake starts at the running stream's next
    # setpoint), within the limits; what went out is what was recorded.
    assert [m.data[0] for m in rig.setpoints.messages][-len(recorded):] == [p for _, p in recorded]
    # A tick before the next setpoint is due publishes the latest one again: the same sample, counted once here.
    samples = dict(recorded)
    assert len(samples) == len(set(recorded)), 'two positions for one time'
    t_ns = np.array(sorted(samples), dtype=np.int64)
    q = np.array([samples[t] for t in t_ns.tolist()])
    assert (np.diff(t_ns) > 0).all() and [t for t, _ in recorded] == sorted(t for t, _ in recorded)
    over = stream_over_limits(t_ns - t_ns[0], q)
    assert not over, (over, rig.sides())
    brake_from = int(np.searchsorted(t_ns, t0))
    print(f'\nforward mode: the drive at rest at {q_rest:.6f} rad {(to_ns(rest.header.stamp) - t0) * 1e-9:.3f} s after '
          f'the halt call (the brake from the stream\'s next setpoint planned at rest '
          f'{planned_end(act.motion, t0):.3f} s after it); '
          f'{q_target - q_rest:+.4f} rad short of the target; {len(t_ns) - brake_from} setpoints after the call')
    with rig.ros.paused():  # the forward controller holds the brake's last setpoint
        assert rig.sim.follower.trajectory is None and rig.sim.follower._hold.position == q_rest
    halted_checks(rig, CFG.theta_max)
    resume_then_move(rig, 0.0)
