"""fourbar_node's actuator modes over the real middleware, driving the simulated actuator: plain commands become
motion the sim follows to the command's driven angle (trajectory and forward modes), antenna trajectories are
converted and followed, replanning mid-motion continues the running motion without a jump (with measurements that
reach the node late too), every bad antenna trajectory is counted with nothing sent, and every point and setpoint
sent is within the limits.

One trajectory-mode node and one forward-mode node, each with its own sim actuator in its own namespace, for the
whole module; a held drive and late measurements each get a pair of their own. No timing is asserted: each check
waits for a state with a deadline, or holds for every message.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from builtin_interfaces.msg import Duration, Time
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64, Float64MultiArray
from support.ros_support import Collector, RosSession, wait_for
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from fourbar_ros.config.antenna_config import default_config
from fourbar_ros.interface.stamps import to_ns
from fourbar_ros.interface.topics import ANTENNA_JOINT, BROADCASTER_JOINT_STATES, JOINT_STATES, MEASURED_JOINT_STATES
from fourbar_ros.motion.limits import JointLimits, worst_violation
from fourbar_ros.motion.planner import PLAN_SHRINK, JointMotionState, driven_angles
from fourbar_ros.motion.trajectory import AntennaTrajectory, DrivenTrajectory
from fourbar_ros.node.fourbar_node import FourBarNode
from fourbar_ros.node.sim_actuator import SimActuator
from fourbar_ros.rules.antenna_trajectory import TrajectoryProblem
from fourbar_ros.rules.diagnostics import Level
from fourbar_ros.rules.takeover import ARRIVAL_MARGIN_S, Start, motion_start

pytestmark = pytest.mark.ros

CFG = default_config()
LIMITS = JointLimits.from_config(CFG)
JOINT = CFG.driven_joint
#: Settled: measured within this of the target (rad) and at rest (rad/s). The sim's drive lands on a reference at
#: rest (its last braking step) or converges to it exponentially, and is then still (no noise, no quantization by
#: default); the measurement taken as it lands is on the target but still shows that last step's mean speed (up to
#: 2e-4 rad/s), which the node carries on to where a new motion starts.
SETTLED = 1e-9


def q_of(theta: float) -> float:
    return float(driven_angles(CFG, np.array([theta]))[0])


def duration(t: float) -> Duration:
    ns = round(t * 1e9)
    return Duration(sec=ns // 10**9, nanosec=ns % 10**9)


def as_driven(msg: JointTrajectory) -> DrivenTrajectory:
    """A received JointTrajectory as arrays (the antenna path is not in the message: zeros stand in)."""
    pts = msg.points
    t = np.array([p.time_from_start.sec + 1e-9 * p.time_from_start.nanosec for p in pts])

    def col(name: str) -> Any:
        rows = [getattr(p, name) for p in pts]
        return np.array([r[0] for r in rows]) if all(len(r) == 1 for r in rows) else None

    effort = col('effort')
    return DrivenTrajectory(t, col('positions'), col('velocities'), col('accelerations'),
                            np.zeros_like(t) if effort is None else effort, AntennaTrajectory(t, np.zeros_like(t)))


class Pair:
    """A FourBarNode in ``mode`` and a SimActuator in one namespace, with the client's endpoints."""

    def __init__(self, ros: RosSession, mode: str, suffix: str = '', sim: tuple[Parameter, ...] = (),
                 overrides: tuple[Parameter, ...] = (), delay_s: float = 0.0) -> None:
        """``delay_s`` > 0: the node gets the drive's measurements that much after the broadcaster sent them
        (``DelayRelay``)."""
        self.ros, self.ns = ros, f'/actuation_{mode}{suffix}'
        self.mark = 0
        self.sim = SimActuator(context=ros.context, namespace=self.ns, parameter_overrides=list(sim))
        self.relay = DelayRelay(ros, self.ns, delay_s) if delay_s > 0.0 else None
        measured_from = DelayRelay.OUT if self.relay is not None else BROADCASTER_JOINT_STATES.name
        self.node = FourBarNode(context=ros.context, namespace=self.ns,
                                parameter_overrides=[Parameter('mode', value=mode), *overrides],
                                cli_args=['--ros-args', '-r', f'{MEASURED_JOINT_STATES.name}:={measured_from}'])
        ros.add_node(self.sim)
        if self.relay is not None:
            ros.add_node(self.relay)
        ros.add_node(self.node)
        self.measured: Collector[JointState] = ros.collect(JointState, f'{self.ns}/{BROADCASTER_JOINT_STATES.name}')
        self.complete: Collector[JointState] = ros.collect(JointState, f'{self.ns}/{JOINT_STATES.name}')
        self.trajectories: Collector[JointTrajectory] = ros.collect(
            JointTrajectory, f'{self.ns}/joint_trajectory_controller/joint_trajectory', 10)
        self.setpoints: Collector[Float64MultiArray] = ros.collect(
            Float64MultiArray, f'{self.ns}/forward_position_controller/commands', 10)
        #: the simulated controller's reference of every trajectory it took over
        self.taken_over: list[Any] = []
        self.sim.follower.on_takeover = self.taken_over.append
        self.cmd = ros.publisher(Float64, f'{self.ns}/antenna_angle_cmd', 10)
        self.antenna = ros.publisher(JointTrajectory, f'{self.ns}/antenna_trajectory', 10)
        ros.wait_subscribers(self.cmd)
        ros.wait_subscribers(self.antenna)  # both modes serve antenna trajectories
        out = self.actuation._trajectory_pub if mode == 'trajectory' else self.actuation._setpoint_pub
        ros.wait_subscribers(out, 2)  # the sim and the client
        wait_for(lambda: self.actuation.measured is not None, what='the measured driven joint at the node')

    @property
    def actuation(self) -> Any:
        return self.node.actuation

    def command(self, theta: float) -> None:
        self.mark = len(self.measured)
        self.cmd.publish(Float64(data=theta))

    def settle_at(self, theta: float) -> JointState:
        """The first measured message since the last command or trajectory (``mark``) at rest at theta's driven
        angle, once the node has taken in such a measurement too (both sides: under load the node's measurements can
        lag the test's, and a plan from the drive's measured state would start where the drive was, moving on at
        its measured speed)."""
        q = q_of(theta)

        def still(position: float, velocity: float) -> bool:
            return abs(position - q) <= SETTLED and abs(velocity) <= SETTLED

        def still_in(m: JointState) -> bool:
            i = list(m.name).index(JOINT) if JOINT in m.name else -1
            return i >= 0 and still(m.position[i], m.velocity[i])

        try:
            settled = self.measured.wait_match(still_in, start=self.mark)
            self.ros.wait_for(lambda: (m := self.actuation.measured) is not None and still(m.position, m.velocity),
                              what=f'the node\'s measured driven joint within {SETTLED} rad of {q!r} rad, at rest')
        except AssertionError as exc:
            raise AssertionError(f'{exc}\n{self.sides()}') from None
        return settled

    def sides(self) -> str:
        """What the node and the simulated drive each say they did (for a failure message)."""
        follower = self.sim.follower
        return (f'node: {self.actuation.counters.as_dict()}, diagnostics {self.actuation.diagnostics()}; '
                f'sim: drive at {self.sim.drive.position!r} rad, {follower.counters.as_dict()}, '
                f'{follower.waiting} waiting, holding: {follower.holding_reason}, {self.sim.counters}')

    def close(self) -> None:
        for c in (self.measured, self.complete, self.trajectories, self.setpoints):
            self.ros.uncollect(c)
        self.ros.destroy(self.cmd)
        self.ros.destroy(self.antenna)
        self.ros.remove_node(self.node)
        if self.relay is not None:
            self.ros.remove_node(self.relay)
        self.ros.remove_node(self.sim)


class DelayRelay(Node):
    """Passes the broadcaster's measurements on to ``OUT``, unchanged (stamps included), each when a later one
    arrives at least ``delay_s`` after it: a drive whose measurements reach the node late, as on a loaded machine.
    Driven by the measurements alone (no timer of its own to load the test's executor)."""

    OUT = 'late_joint_states'

    def __init__(self, ros: RosSession, namespace: str, delay_s: float) -> None:
        super().__init__('delay_relay', context=ros.context, namespace=namespace)
        self._delay_ns = round(delay_s * 1e9)
        self._held: deque[tuple[int, JointState]] = deque()
        self._out = self.create_publisher(JointState, self.OUT, 100)
        self.create_subscription(JointState, BROADCASTER_JOINT_STATES.name, self._on_measured, 100)

    def _on_measured(self, msg: JointState) -> None:
        now = self.get_clock().now().nanoseconds
        self._held.append((now, msg))
        while self._held[0][0] <= now - self._delay_ns:
            self._out.publish(self._held.popleft()[1])


@pytest.fixture(scope='module')
def traj(ros: RosSession) -> Iterator[Pair]:
    """The default replan_tolerance (0.01 rad) is far above the simulated drive's lag (its speed times its 0.05 s
    time constant, 3e-3 rad), and the node compares a measurement with the motion at the measurement's stamp, so a
    command mid-motion plans on from the motion however late the measurement arrives."""
    pair = Pair(ros, 'trajectory')
    yield pair
    # Every trajectory the node sent in this module, whatever the test: what the controller accepts (checked by
    # the contract, and by the strict simulated actuator, which refused none), no effort field, the interpolated
    # motion within every limit (segment extremes, not only the points), and so is the controller's whole reference,
    # the lead-in it makes to a plan stamped ahead of its arrival included (a hold where the drive is).
    for msg in pair.trajectories.messages:
        assert msg.joint_names == [JOINT] and all(len(p.effort) == 0 for p in msg.points)
        assert worst_violation(as_driven(msg), LIMITS, CFG) is None
    assert sum(pair.sim.follower.counters.refused.values()) == 0
    over = [(ref, ratio) for ref in pair.taken_over
            if (ratio := max(LIMITS.ratio * v / LIMITS.motor(order) for order, v in ref.extremes().items())) > 1 + 1e-9]
    assert not over, f'the controller\'s reference over a limit (the largest over it, its ratio): {over[:3]}'
    assert sum(pair.actuation.counters.refused.values()) == 0
    pair.close()


@pytest.fixture(scope='module')
def fwd(ros: RosSession) -> Iterator[Pair]:
    pair = Pair(ros, 'forward')
    yield pair
    pair.close()


def test_a_command_in_trajectory_mode_moves_the_actuator_to_its_driven_angle(traj: Pair) -> None:
    before = len(traj.trajectories)
    traj.command(0.03)
    msg = traj.trajectories.wait_count(before + 1)[-1]
    out = as_driven(msg)
    assert out.velocities is not None and out.accelerations is not None  # quintic segments for the controller
    assert out.positions[-1] == pytest.approx(q_of(0.03), abs=1e-12)  # ruckig's target, to its rounding
    traj.settle_at(0.03)
    assert traj.actuation.counters.commands_planned >= 1


def test_a_replan_tolerance_not_below_the_path_tolerance_is_refused_at_run_time(traj: Pair) -> None:
    """The check the node makes at startup holds for a change at run time: refused in one line, counted, nothing
    changed; a value below the controller's path tolerance (1 deg) applies."""
    node = traj.node
    rejected = node.counters.parameter_changes_rejected
    result = node.set_parameters([Parameter('replan_tolerance', value=0.05)])[0]
    assert not result.successful and result.reason.startswith('replan_tolerance: 0.05 rad must be below the path '
                                                              'tolerance') and '\n' not in result.reason, result
    assert node.config.replan_tolerance == CFG.replan_tolerance
    assert node.counters.parameter_changes_rejected == rejected + 1
    try:
        assert node.set_parameters([Parameter('replan_tolerance', value=0.015)])[0].successful
        assert node.config.replan_tolerance == 0.015
    finally:
        assert node.set_parameters([Parameter('replan_tolerance', value=CFG.replan_tolerance)])[0].successful


@pytest.mark.parametrize('name, value', [('motor_speed_limit', 2.0 * CFG.motor_speed_limit),
                                         ('theta_max', CFG.theta_max - 0.01),
                                         ('reducer_ratio', 2.0 * CFG.reducer_ratio)])
def test_a_change_that_alters_the_robot_model_is_refused_at_run_time(traj: Pair, name: str, value: float) -> None:
    """The controller manager enforces the robot model's limits as loaded at launch: a change that would make the
    node plan with others is refused in one line naming it, counted, nothing changed; a change the model does not
    hold (load_torque) applies."""
    node = traj.node
    rejected = node.counters.parameter_changes_rejected
    result = node.set_parameters([Parameter(name, value=value)])[0]
    assert not result.successful and result.reason.startswith(f'{name}: feeds the robot model'), result
    assert '\n' not in result.reason, result
    assert getattr(node.config, name) == getattr(CFG, name)
    assert node.counters.parameter_changes_rejected == rejected + 1
    try:
        assert node.set_parameters([Parameter('load_torque', value=2.0)])[0].successful
        assert node.config.load_torque == 2.0
    finally:
        assert node.set_parameters([Parameter('load_torque', value=CFG.load_torque)])[0].successful


def test_replanning_mid_motion_continues_the_running_motion(traj: Pair) -> None:
    before = len(traj.trajectories)
    traj.command(CFG.theta_max)  # a motion of seconds ...
    first = traj.trajectories.wait_count(before + 1)[-1]
    start = as_driven(first).positions[0]  # (it begins ARRIVAL_MARGIN_S after the command: wait until it runs)
    wait_for(lambda: traj.actuation.measured.position > start + 1e-3, what='the drive moving')
    traj.command(CFG.theta_min)  # ... interrupted by a command the other way
    second = traj.trajectories.wait_count(before + 2)[-1]
    a, b = as_driven(first), as_driven(second)
    assert traj.actuation.counters.commands_replanned_from_measured == 0
    # The second carries the first's stamp and repeats its points, bit for bit, from the one the node's now fell in
    # up to the first at least ARRIVAL_MARGIN_S ahead, where the new motion starts: wherever the controller takes it
    # over, it is on the segments it was following.
    assert to_ns(second.header.stamp) == to_ns(first.header.stamp) > 0
    k0 = int(np.flatnonzero(a.times == b.times[0])[0])
    n = min(len(b), len(a) - k0)
    assert b.velocities is not None and b.accelerations is not None
    assert a.velocities is not None and a.accelerations is not None
    differs = ((b.positions[:n] != a.positions[k0:k0 + n]) | (b.velocities[:n] != a.velocities[k0:k0 + n])
               | (b.accelerations[:n] != a.accelerations[k0:k0 + n]))
    k1 = int(np.flatnonzero(differs)[0])  # where they part: the new plan's second point
    assert k1 >= 2 and b.times[k1 - 1] - b.times[0] >= ARRIVAL_MARGIN_S
    for field in ('times', 'positions', 'velocities', 'accelerations'):
        assert np.array_equal(getattr(b, field)[:k1], getattr(a, field)[k0:k0 + k1]), field
    assert b.velocities[k1 - 1] > 0.0  # it was moving when replanned
    traj.settle_at(CFG.theta_min)


#: How late the ``late`` fixture's node gets each measurement, at least (s): long enough that at the plan's top speed
#: the drive moves on by more than the default replan_tolerance meanwhile.
LATE_S = 0.4


@pytest.fixture
def late(ros: RosSession) -> Iterator[Pair]:
    pair = Pair(ros, 'trajectory', '_late', delay_s=LATE_S)
    yield pair
    pair.close()


def test_measurements_arriving_late_leave_the_motion_followed(late: Pair) -> None:
    late.command(CFG.theta_min)
    late.settle_at(CFG.theta_min)
    before = len(late.trajectories)
    late.command(CFG.theta_max)  # a motion of seconds ...
    late.trajectories.wait_count(before + 1)
    # ... at a speed where the drive moves on by more than the replan tolerance while a measurement is on its way
    fast = PLAN_SHRINK * LIMITS.at_rocker(1) * 0.9
    assert fast * LATE_S > CFG.replan_tolerance
    try:
        late.measured.wait_match(lambda m: abs(m.velocity[0]) >= fast, start=late.mark)
    except AssertionError as exc:
        raise AssertionError(f'{exc}\n{late.sides()}; takeovers {len(late.taken_over)}') from None
    late.command(CFG.theta_min)  # ... interrupted: the node's latest measurement is LATE_S old
    late.trajectories.wait_count(before + 2)
    actuation = late.actuation
    counters = actuation.counters
    age = (late.node.get_clock().now().nanoseconds - actuation.measured_ns) * 1e-9
    assert counters.commands_replanned_from_measured == 0, (
        f'the node took a late measurement for a drive off its motion: its latest {actuation.measured}, {age:.3f} s '
        f'old now; {late.sides()}')
    late.settle_at(CFG.theta_min)
    assert late.sim.follower.counters.tolerance_holds == 0, late.sides()


def antenna_msg(times: list[float], theta: list[float], theta_dot: list[float] | None = None,
                joint: str = ANTENNA_JOINT, stamp_ns: int = 0) -> JointTrajectory:
    pts = [JointTrajectoryPoint(positions=[th], velocities=[] if theta_dot is None else [theta_dot[i]],
                                time_from_start=duration(t))
           for i, (t, th) in enumerate(zip(times, theta, strict=True))]
    msg = JointTrajectory(joint_names=[joint], points=pts)
    msg.header.stamp = Time(sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9)
    return msg


def test_an_antenna_trajectory_is_converted_and_followed(traj: Pair) -> None:
    traj.command(0.0)
    traj.settle_at(0.0)
    before = len(traj.trajectories)
    t = [0.0, 1.0, 2.0, 3.0]
    theta = [0.0, 0.01, 0.02, 0.025]
    theta_dot = [0.0, 0.01, 0.008, 0.0]
    traj.mark = len(traj.measured)
    traj.antenna.publish(antenna_msg(t, theta, theta_dot))
    msg = traj.trajectories.wait_count(before + 1)[-1]
    out = as_driven(msg)
    sent = [float(x) for x in out.times]
    assert set(t) <= set(sent)  # the requested points are kept (refinement may insert more)
    idx = [sent.index(x) for x in t]
    # Positions are the core's driven angles, bit for bit (the same vectorized solve).
    assert out.positions[idx].tolist() == driven_angles(CFG, np.array(theta)).tolist()
    assert out.velocities is not None and len(out.efforts) == len(out)
    traj.settle_at(0.025)


BAD = {
    TrajectoryProblem.EMPTY: antenna_msg([], []),
    TrajectoryProblem.TIME_NOT_INCREASING: antenna_msg([0.0, 1.0, 1.0], [0.0, 0.01, 0.02]),
    TrajectoryProblem.NOT_FINITE: antenna_msg([0.0, 1.0], [0.0, math.nan]),
    TrajectoryProblem.WRONG_JOINT: antenna_msg([0.0, 1.0], [0.0, 0.01], joint='tilt'),
    TrajectoryProblem.OUT_OF_REACH: antenna_msg([0.0, 1.0], [0.0, CFG.theta_max + 0.01]),
    TrajectoryProblem.TOO_MANY_POINTS: antenna_msg([0.01 * i for i in range(CFG.max_trajectory_points + 1)],
                                                   [0.0] * (CFG.max_trajectory_points + 1)),
    # limit_policy reject (the default): the whole range in 10 ms is far over the motor's speed
    TrajectoryProblem.OVER_LIMITS: antenna_msg([0.0, 0.01], [CFG.theta_min, CFG.theta_max]),
}


@pytest.mark.parametrize('problem', list(BAD), ids=lambda p: p.value)
def test_a_bad_antenna_trajectory_is_counted_and_nothing_is_sent(traj: Pair, problem: TrajectoryProblem) -> None:
    counters = traj.actuation.counters
    was, sent = counters.rejected[problem], counters.trajectories_sent
    before = len(traj.trajectories)
    traj.antenna.publish(BAD[problem])
    wait_for(lambda: counters.rejected[problem] == was + 1, what=f'{problem.value} counted')
    assert counters.trajectories_sent == sent
    # The next good one is the only message that goes out.
    # The last measurement (joint_states also carries the node's completed passive joints).
    now = next(m for m in reversed(traj.measured.messages) if JOINT in m.name)
    q = now.position[list(now.name).index(JOINT)]
    theta = float(CFG.linkage.from_rocker(np.array([q]), CFG.driven, CFG.measured_branch)[0][0])
    # At an end of the range the completed angle may lie an ulp outside it: the good trajectory stays inside.
    theta = min(max(theta, CFG.theta_min), CFG.theta_max)
    traj.antenna.publish(antenna_msg([0.5], [theta]))
    assert len(traj.trajectories.wait_count(before + 1)) == before + 1
    values = {kv.key: kv.value for kv in traj.node.diagnostic_status().values}
    assert values[f'trajectories_rejected_{problem.value}'] == str(was + 1)


def test_a_command_in_forward_mode_streams_setpoints_within_limits_without_jumps(fwd: Pair) -> None:
    fwd.command(0.04)
    wait_for(lambda: fwd.actuation.counters.setpoints_published > 3, what='setpoints')
    fwd.command(-0.04)  # mid-motion: the stream continues from where the first plan is
    fwd.settle_at(-0.04)
    recorded = list(fwd.actuation.recent_setpoints)
    assert len(recorded) >= 10
    received = [m.data[0] for m in fwd.setpoints.messages]
    assert [q for _, q in recorded] == received[-len(recorded):]  # what is on the wire is what was recorded
    t_ns, q = np.array([t for t, _ in recorded]), np.array([q for _, q in recorded])
    dt, dq = 1e-9 * np.diff(t_ns), np.abs(np.diff(q))
    assert (dt >= 0.0).all()
    # Samples of one continuous reference whose speed is below the limit (PLAN_SHRINK of it), across the replan too:
    # each step is at most the speed times the time between the samples (ns, exact), up to the rounding of the
    # sample times to ns (1e-7 of a 10 ms step) and ruckig's (~1e-13 relative): 1e-6 of headroom covers both.
    vmax = LIMITS.at_rocker(1)
    bad = np.flatnonzero(dq > PLAN_SHRINK * vmax * dt + 1e-12)
    assert bad.size == 0, [(int(t_ns[i]), int(t_ns[i + 1]), q[i], q[i + 1]) for i in bad]
    lo, hi = sorted(driven_angles(CFG, np.array([CFG.theta_min, CFG.theta_max])))
    assert ((lo <= q) & (q <= hi)).all()
    assert q[-1] == pytest.approx(q_of(-0.04), abs=1e-12)


def test_the_node_publishes_one_complete_joint_state_per_measurement(traj: Pair) -> None:
    # Every joint at the measurement's stamp: the driven one as measured, the others completed; efforts [measured,
    # 0, 0]. One complete message per measurement (matched by stamp), none without a measurement.
    start = len(traj.complete)
    traj.complete.wait_count(start + 5)
    measured = {to_ns(m.header.stamp): m for m in traj.measured.messages}
    names = [JOINT, CFG.delta_joint, CFG.coupler_joint]
    seen = set()
    for m in traj.complete.messages[start:]:
        assert list(m.name) == names
        k = to_ns(m.header.stamp)
        src = measured.get(k) or traj.measured.wait_match(lambda x, k=k: to_ns(x.header.stamp) == k)
        assert m.position[0] == src.position[0] and m.velocity[0] == src.velocity[0]
        assert list(m.effort) == [src.effort[0], 0.0, 0.0]
        assert k not in seen
        seen.add(k)


def test_antenna_trajectories_ending_moving_or_in_the_past_are_refused_and_counted(traj: Pair) -> None:
    counters = traj.actuation.counters
    sent = counters.trajectories_sent
    moving = antenna_msg([0.0, 1.0, 2.0], [0.0, 0.01, 0.02], [0.0, 0.01, 0.004])
    past = antenna_msg([0.0, 1.0], [0.0, 0.01], stamp_ns=traj.node.get_clock().now().nanoseconds - 5 * 10**9)
    for msg, problem in ((moving, TrajectoryProblem.END_MOVING), (past, TrajectoryProblem.ENDS_IN_PAST)):
        was = counters.rejected[problem]
        traj.antenna.publish(msg)
        wait_for(lambda p=problem, w=was: counters.rejected[p] == w + 1, what=f'{problem.value} counted')
    assert counters.trajectories_sent == sent


@pytest.fixture(scope='module')
def held(ros: RosSession) -> Iterator[Pair]:
    """A trajectory-mode node whose simulated drive is 50 times too slow: the controller holds it on its path
    tolerance (1 deg, above the default replan_tolerance)."""
    pair = Pair(ros, 'trajectory', '_held', sim=(Parameter('max_velocity', value=LIMITS.at_rocker(1) / 50.0),))
    yield pair
    pair.close()


def test_a_command_after_the_drive_was_held_plans_from_the_measured_state(held: Pair) -> None:
    before = len(held.trajectories)
    held.command(CFG.theta_max)
    held.trajectories.wait_count(before + 1)
    wait_for(lambda: held.sim.follower.counters.tolerance_holds >= 1, what='the controller holding the drive')
    held.measured.wait_count(len(held.measured) + 2)  # a measurement of the held drive
    held.command(CFG.theta_min)
    second = as_driven(held.trajectories.wait_count(before + 2)[-1])
    assert held.actuation.counters.commands_replanned_from_measured == 1
    # The plan starts where the drive was measured at rest (a measurement the node received; the held drive still
    # creeps a little, so not necessarily the latest now), not where its model of the first motion is (seconds into
    # it, far along): the controller gets no step.
    planned_ns = to_ns(held.trajectories.messages[before + 1].header.stamp)

    def planned_from(m: JointState) -> bool:
        measured = JointMotionState(m.position[0], m.velocity[0])
        start = motion_start(CFG, None, measured, planned_ns, 0.0, to_ns(m.header.stamp))
        return isinstance(start, Start) and start.state.position == second.positions[0]
    held.measured.wait_match(planned_from)
    model = held.actuation.motion  # the second motion now; the first one's model is far from the drive
    assert model is not None and abs(second.positions[0] - q_of(CFG.theta_max)) > 0.01


def test_forward_mode_streams_an_antenna_trajectory(fwd: Pair) -> None:
    fwd.command(0.0)
    fwd.settle_at(0.0)
    published = fwd.actuation.counters.setpoints_published
    first = len(fwd.setpoints)
    fwd.mark = len(fwd.measured)
    fwd.antenna.publish(antenna_msg([0.0, 1.0, 2.0], [0.0, 0.01, 0.015], [0.0, 0.01, 0.0]))
    fwd.settle_at(0.015)
    # Streamed over its 2 s (as many setpoints as control ticks ran; a loaded machine skips some), not sent as one
    # step: setpoints strictly inside each of its two segments.
    assert fwd.actuation.counters.setpoints_published > published + 2
    streamed = [m.data[0] for m in fwd.setpoints.messages[first:]]
    for lo, hi in ((q_of(0.0), q_of(0.01)), (q_of(0.01), q_of(0.015))):
        assert any(min(lo, hi) < q < max(lo, hi) for q in streamed), (lo, hi, streamed)
    assert fwd.actuation.counters.trajectories_received >= 1


@pytest.mark.parametrize(('mode', 'msg_type', 'topic'), [
    ('trajectory', JointTrajectory, 'joint_trajectory_controller/joint_trajectory'),
    ('forward', Float64MultiArray, 'forward_position_controller/commands')])
def test_another_sender_to_the_controller_is_a_warning_until_it_goes(request: pytest.FixtureRequest, ros: RosSession,
                                                                      mode: str, msg_type: Any, topic: str) -> None:
    # A bag of a full recording played back publishes the node's own output: nothing sent here, the publisher's
    # presence is what the node reports (its graph, both sides of discovery waited for).
    pair: Pair = request.getfixturevalue('traj' if mode == 'trajectory' else 'fwd')

    def status() -> tuple[Level, str, dict[str, str]]:  # called with the executor paused (ros.wait_for, paused)
        level, message, values = pair.actuation.diagnostics()
        return level, message, dict(values)

    with ros.paused():
        first = status()
    assert first[2]['other_senders'] == 'none', first
    publisher = ros.publisher(msg_type, f'{pair.ns}/{topic}', 10)
    try:
        ros.wait_for(lambda: status()[2]['other_senders'] != 'none', what=f'the node seeing a second sender on {topic}')
        with ros.paused():
            level, message, values = status()
        assert level is Level.WARN and values['other_senders'] == ros.node.get_fully_qualified_name(), (level, values)
        assert message.endswith(f'also send to the controller on {pair.ns}/{topic}'), message
    finally:
        ros.destroy(publisher)
    ros.wait_for(lambda: status()[2]['other_senders'] == 'none', what='the node seeing the second sender gone')
