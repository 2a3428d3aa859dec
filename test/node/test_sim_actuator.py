"""sim_actuator over the real middleware: JointTrajectory and Float64MultiArray in, the measured joint on
joint_state_broadcaster/joint_states out (following within the lag and the limits, effort from the statics, encoder
counts and offset visible), what the controllers refuse refused and counted with the running trajectory going on, a
new trajectory started from the measured state, a hold on a tolerance violation, and the console script stopping
with status 0 on SIGINT and SIGTERM.

Timing is never asserted: each check is a property every message must have (monotonic, within limits, behind
the reference) or a state the drive converges to, waited for with a deadline.
"""

from __future__ import annotations

import itertools
import math
import re
import signal
import sys
from collections.abc import Iterator, Sequence
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest
from builtin_interfaces.msg import Duration, Time
from rclpy.parameter import Parameter
from rclpy.time import Time as RclpyTime
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, Header
from support.paths import REPO
from support.ros_support import Collector, NodeProcess, RosSession, wait_for
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from fourbar_ros.config.antenna_config import default_config
from fourbar_ros.config.robot_model import driven_angle, joint_limits
from fourbar_ros.config.sim_actuator_params import SIM_PARAMETERS_BY_NAME
from fourbar_ros.interface.topics import BROADCASTER_JOINT_STATES
from fourbar_ros.node import sim_actuator
from fourbar_ros.node.sim_actuator import SimActuator
from fourbar_ros.rules.controller_contract import ContractRule
from fourbar_ros.rules.simulated_drive import STEP_S, effort_at

pytestmark = pytest.mark.ros

YAML = REPO / 'config' / 'antenna.yaml'
CFG = default_config()
JOINT = CFG.driven_joint
Q0 = driven_angle(CFG)  # where the drive starts (initial_theta 0)
LIMIT = joint_limits(CFG)[JOINT]
VMAX = float(SIM_PARAMETERS_BY_NAME['max_velocity'].default)
EPS = sys.float_info.epsilon
#: Converged: the lag's remaining error after many time constants (e^-40 of a 0.2 rad step, far below this).
SETTLED = 1e-9
LOG_LINE = re.compile(r'^\[(DEBUG|INFO|WARN|ERROR|FATAL)\] \[\d+\.\d+\] \[')
_ns = itertools.count()


class Rig:
    """An in-process SimActuator in its own namespace, with the client's publishers and a joint_states Collector."""

    def __init__(self, ros: RosSession, **overrides: Any) -> None:
        self.ros = ros
        self.ns = f'/sim_test_{next(_ns)}'
        self.node = SimActuator(context=ros.context, namespace=self.ns,
                                parameter_overrides=[Parameter(k, value=v) for k, v in overrides.items()],
                                cli_args=['--ros-args', '--params-file', str(YAML)])
        ros.add_node(self.node)
        self.states: Collector[JointState] = ros.collect(JointState, f'{self.ns}/{BROADCASTER_JOINT_STATES.name}')
        self.traj_pub = ros.publisher(JointTrajectory, f'{self.ns}/joint_trajectory_controller/joint_trajectory', 10)
        self.fwd_pub = ros.publisher(Float64MultiArray, f'{self.ns}/forward_position_controller/commands', 10)
        ros.wait_publishers(self.states)
        ros.wait_subscribers(self.traj_pub)
        ros.wait_subscribers(self.fwd_pub)
        self.states.wait_count(1)

    def close(self) -> None:
        self.ros.uncollect(self.states)
        self.ros.destroy(self.traj_pub)
        self.ros.destroy(self.fwd_pub)
        self.ros.remove_node(self.node)

    def forward(self, values: Sequence[float]) -> None:
        self.fwd_pub.publish(Float64MultiArray(data=list(values)))

    def settle_at(self, position: float, start: int = 0) -> JointState:
        """The first message at or after index ``start`` whose position is within SETTLED of ``position``."""
        return self.states.wait_match(lambda m: abs(m.position[0] - position) <= SETTLED, start=start)


@pytest.fixture
def rig(ros: RosSession) -> Iterator[Any]:
    made: list[Rig] = []

    def make(**overrides: Any) -> Rig:
        made.append(Rig(ros, **overrides))
        return made[-1]

    yield make
    for r in made:
        r.close()


def stamp_s(msg: JointState) -> float:
    return msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec


def point(position: float, t: float, velocity: float | None = None, acceleration: float | None = None,
          width: int = 1, index: int = 0) -> JointTrajectoryPoint:
    def row(value: float | None) -> list[float]:
        return [] if value is None else [value if i == index else 0.0 for i in range(width)]

    sec = math.floor(t)
    return JointTrajectoryPoint(positions=row(position), velocities=row(velocity), accelerations=row(acceleration),
                                time_from_start=Duration(sec=sec, nanosec=round((t - sec) * 1e9)))


def test_a_trajectory_is_followed_behind_the_reference_and_effort_is_the_statics(rig: Any) -> None:
    r = rig()
    # Stamped 1 s ahead: the controller still takes it over at its first update after arrival, and its lead-in
    # from the measured state reaches the first point at stamp + 0.4 s. That lead-in is quintic (the point has
    # accelerations): from rest over T it moves forward only while v T / d < 2.5, for the first point's velocity v
    # and distance d; at v = 0.03 rad/s, d = 0.02 rad, T up to 1.4 s gives 2.1.
    start = r.node.get_clock().now().nanoseconds + 1_000_000_000
    target = Q0 + 0.05
    msg = JointTrajectory(joint_names=[JOINT])
    msg.header.stamp = Time(sec=start // 10**9, nanosec=start % 10**9)
    msg.points = [point(Q0 + 0.02, 0.4, 0.03, 0.0), point(target, 1.0, 0.0, 0.0)]
    first = len(r.states)
    r.traj_pub.publish(msg)
    r.ros.wait_for(lambda: r.node.follower._trajectory is not None, what='the trajectory taken over')
    taken_at = r.node.follower._trajectory.start
    end = r.settle_at(target, first)
    msgs = r.states.messages[first:r.states.messages.index(end) + 1]
    assert stamp_s(msgs[-1]) > start * 1e-9 + 1.0  # converged only after the trajectory's end (it lags)
    before_stamp = [m.position[0] for m in msgs if stamp_s(m) <= start * 1e-9]
    assert any(q > Q0 for q in before_stamp), (taken_at, start * 1e-9, before_stamp)  # moving before the stamp
    prev = msgs[0]
    for m in msgs:
        assert list(m.name) == [JOINT]
        x, v, e = m.position[0], m.velocity[0], m.effort[0]
        # The reference rises monotonically to the target: the lagged drive never passes it nor turns back, up to
        # the rounding of the last steps' additions (an ulp or two of the angle).
        ulps = 2 * EPS * target
        assert prev.position[0] - ulps <= x <= target + ulps and -ulps / STEP_S <= v <= VMAX
        # No noise, counts or offset here: the measured position is the true one, and the effort the very same
        # statics call on it.
        assert e == effort_at(CFG, x)
        prev = m
    assert sum(r.node.follower.counters.refused.values()) == 0 and r.node.follower.counters.tolerance_holds == 0


def test_a_forward_command_is_followed_at_the_speed_limit(rig: Any) -> None:
    r = rig()
    target = min(Q0 + 0.2, LIMIT.upper)
    first = len(r.states)
    r.forward([target])
    end = r.settle_at(target, first)
    msgs = r.states.messages[first:r.states.messages.index(end) + 1]
    speeds = [m.velocity[0] for m in msgs]
    assert all(0.0 <= v <= VMAX for v in speeds)
    assert max(speeds) == VMAX  # a 0.2 rad step saturates the drive's speed
    assert all(a.position[0] <= b.position[0] for a, b in itertools.pairwise(msgs))
    assert r.node.counters.commands_accepted == 1
    # A new trajectory starts from where the forward command left the drive: no jump. Its time lets the drive follow
    # within its speed limit (its linear path at about half of it), inside the controller's path tolerance.
    back = JointTrajectory(joint_names=[JOINT], points=[point(Q0, 2.0 * (target - Q0) / VMAX)])
    first = len(r.states)
    r.traj_pub.publish(back)
    end = r.settle_at(Q0, first)
    assert all(abs(m.velocity[0]) <= VMAX for m in r.states.messages[first:])


def test_encoder_counts_and_offset_show_in_the_measurement(rig: Any) -> None:
    counts, offset = 4096, 0.01
    r = rig(encoder_counts_per_rev=counts, position_offset=offset)
    resolution = 2.0 * math.pi / (counts * CFG.reducer_ratio)
    target = Q0 + 0.013
    first = len(r.states)
    r.forward([target])
    want = round(target / resolution) * resolution + offset
    r.settle_at(want, first)
    for m in r.states.messages[first:]:
        n = (m.position[0] - offset) / resolution
        # A whole number of counts, up to the rounding of n * resolution + offset (a few ulps of ~1 rad, i.e.
        # ~1e-12 counts at 3e-6 rad per count).
        assert abs(n - round(n)) <= 1e-9, m.position[0]


def stamped(msg: JointTrajectory, stamp_ns: int) -> JointTrajectory:
    msg.header.stamp = Time(sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9)
    return msg


#: What joint_trajectory_controller refuses (each as the contract's rule), and a NaN the sim refuses too. With the
#: shipped controllers YAML (allow_partial_joints_goal false) empty joint names break the joint count first, so the
#: NO_JOINT_NAMES rule is reached only with partial goals allowed (test_controller_contract).
BAD = {
    ContractRule.FOREIGN_JOINT: JointTrajectory(joint_names=['not_ours'], points=[point(0.9, 1.0)]),
    ContractRule.TIME_NOT_INCREASING: JointTrajectory(joint_names=[JOINT], points=[point(0.9, 1.0), point(0.95, 0.5)]),
    ContractRule.PARTIAL_JOINTS: JointTrajectory(joint_names=[JOINT, 'b'], points=[point(0.9, 1.0)]),
    ContractRule.NO_POINTS: JointTrajectory(joint_names=[JOINT], points=[]),
    ContractRule.FIELD_SIZE: JointTrajectory(joint_names=[JOINT], points=[JointTrajectoryPoint(
        positions=[Q0 + 0.01, 0.0], time_from_start=Duration(sec=1))]),
    ContractRule.EFFORT_FIELD: JointTrajectory(joint_names=[JOINT], points=[JointTrajectoryPoint(
        positions=[Q0 + 0.01], effort=[0.5], time_from_start=Duration(sec=1))]),
    ContractRule.END_MOVING: JointTrajectory(joint_names=[JOINT], points=[point(Q0 + 0.01, 1.0, 0.004)]),
    ContractRule.ENDS_IN_PAST: stamped(JointTrajectory(joint_names=[JOINT], points=[point(Q0 + 0.01, 1.0)]), 10**9),
    None: JointTrajectory(joint_names=[JOINT], points=[point(math.nan, 1.0)]),
}


@pytest.mark.parametrize('rule', list(BAD), ids=lambda r: 'not_finite' if r is None else r.value)
def test_what_the_controller_refuses_is_counted_and_the_running_trajectory_goes_on(rig: Any,
                                                                                   rule: ContractRule | None) -> None:
    r = rig()
    # A slow trajectory running, then the refused message: the drive still reaches the running one's end.
    target = Q0 + 0.02
    r.traj_pub.publish(JointTrajectory(joint_names=[JOINT], points=[point(target, 1.0)]))
    wait_for(lambda: r.node.follower.counters.accepted == 1, what='the trajectory accepted')
    first = len(r.states)
    r.traj_pub.publish(BAD[rule])
    counters = r.node.follower.counters
    wait_for(lambda: (counters.refused_not_finite if rule is None else counters.refused[rule]) == 1,
             what='the trajectory refused')
    r.settle_at(target, first)
    assert counters.accepted == 1 and all(math.isfinite(m.position[0]) for m in r.states.messages)


@pytest.mark.parametrize('data, deactivates', [([], True), ([0.9, 0.9], True), ([math.inf], False)],
                         ids=['empty', 'two', 'inf'])
def test_bad_forward_commands_are_counted_and_change_nothing(rig: Any, data: list[float], deactivates: bool) -> None:
    # forward_command_controller fails its update on a command of the wrong size, and the controller manager then
    # deactivates it: a good command after it is not written either. An infinity it would write: refused here.
    r = rig()
    first = len(r.states)
    r.forward(data)
    wait_for(lambda: r.node.counters.commands_rejected == 1, what='the command rejected')
    assert r.node.counters.commands_accepted == 0
    assert r.node.counters.forward_deactivations == int(deactivates)
    r.forward([Q0 + 0.01])
    if deactivates:
        wait_for(lambda: r.node.counters.commands_rejected == 2, what='the next command rejected')
    else:
        wait_for(lambda: r.node.counters.commands_accepted == 1, what='the next command accepted')
        return
    seen = len(r.states)
    r.states.wait_count(seen + 2)
    assert all(m.position[0] == Q0 for m in r.states.messages[first:])  # it did not move


def test_a_forward_command_of_nan_only_is_no_command(rig: Any) -> None:
    r = rig()
    r.forward([Q0 + 0.01])
    wait_for(lambda: r.node.counters.commands_accepted == 1, what='the command accepted')
    r.forward([math.nan])  # the controller keeps writing its last command
    wait_for(lambda: r.node.counters.commands_ignored_nan == 1, what='the NaN command ignored')
    end = r.settle_at(Q0 + 0.01, len(r.states))
    assert r.node.counters.commands_rejected == 0 and math.isfinite(end.position[0])


def test_bad_parameter_is_one_line_and_status_2(ros: RosSession) -> None:
    proc = NodeProcess(['--ros-args', '--params-file', str(YAML), '-p', 'time_constant:=-1.0'], ros.env(),
                       command=[*_command()])
    with proc:
        assert proc.wait_exit() == 2
    assert proc.stderr.strip().count('\n') == 0 and 'time_constant' in proc.stderr, proc.stderr


def _command() -> list[str]:
    script = Path(sys.executable).parent / 'fourbar_sim_actuator'
    start = 'import sys; from fourbar_ros.node import sim_actuator_main; sys.exit(sim_actuator_main())'
    return [str(script)] if script.exists() else [sys.executable, '-c', start]


@pytest.mark.parametrize('sig', [signal.SIGINT, signal.SIGTERM], ids=['SIGINT', 'SIGTERM'])
def test_console_script_serves_and_stops_with_status_0(ros: RosSession, sig: int) -> None:
    ns = f'/sim_proc_{next(_ns)}'
    states: Collector[JointState] = ros.collect(JointState, f'{ns}/{BROADCASTER_JOINT_STATES.name}')
    try:
        with NodeProcess(['--ros-args', '--params-file', str(YAML), '-r', f'__ns:={ns}'], ros.env(),
                         command=_command()) as proc:
            ros.wait_publishers(states)
            states.wait_count(3)
            assert proc.stop(sig) == 0, proc.stderr
        assert all(LOG_LINE.match(line) for line in proc.stderr.splitlines() if line.strip()), proc.stderr
        assert list(states.messages[0].name) == [JOINT]
    finally:
        ros.uncollect(states)


class ManualClock:
    """What SimActuator reads its clocks through (``now().nanoseconds``, ``now().to_msg()``), set by the test."""

    def __init__(self, ns: int) -> None:
        self.ns = ns

    def now(self) -> RclpyTime:
        return RclpyTime(nanoseconds=self.ns)


def follow_with_ticks(ros: RosSession, ticks: Sequence[int]) -> SimActuator:
    """An in-process SimActuator that is not spun: it takes a linear trajectory of 0.12 rad in 2 s (0.06 rad/s,
    within its speed limit) 5 ms after its first tick, and ticks at ``ticks`` (ms) on a clock of the test's."""
    node = SimActuator(context=ros.context, namespace=f'/sim_test_{next(_ns)}',
                       cli_args=['--ros-args', '--params-file', str(YAML)])
    clock = ManualClock(10**12)
    node._clock = node._tick_clock = clock
    start = clock.ns
    for k, t in enumerate(ticks):
        clock.ns = start + t * 1_000_000
        node._on_tick()
        if k == 0:
            clock.ns += 5_000_000
            node._on_trajectory(JointTrajectory(joint_names=[JOINT], points=[point(Q0 + 0.12, 2.0)]), {})
    return node


def test_a_late_tick_makes_the_controller_updates_it_missed(ros: RosSession,
                                                            monkeypatch: pytest.MonkeyPatch) -> None:
    """A tick 1 s late (a busy machine) in the middle of the motion: the drive moves as with ticks on time, and no
    tolerance hold. Without the missed updates, the drive would wait at the last command for the whole second,
    1 s x 0.06 rad/s behind the reference, beyond the trajectory tolerance of 0.05 rad: held."""
    on_time = list(range(0, 3010, 10))
    late = [t for t in on_time if not 500 < t < 1500]
    nodes = [follow_with_ticks(ros, on_time), follow_with_ticks(ros, late)]
    try:
        (a, b) = (n.drive for n in nodes)
        assert [n.follower.counters.tolerance_holds for n in nodes] == [0, 0], [n.follower.holding_reason
                                                                                 for n in nodes]
        assert abs(a.position - (Q0 + 0.12)) <= SETTLED
        # The same updates at the same times (their times computed back from the late tick: a few ulps of the
        # clock's 1e3 s apart), on a drive that integrates in fixed 1 ms steps: far below one encoder count.
        assert abs(a.position - b.position) <= 1e-9 and abs(a.velocity - b.velocity) <= 1e-9
        monkeypatch.setattr(sim_actuator, 'MAX_CATCH_UP', 1)  # one update per tick, however late
        nodes.append(follow_with_ticks(ros, late))
        assert nodes[-1].follower.counters.tolerance_holds == 1, nodes[-1].drive.position
    finally:
        for node in nodes:
            node.destroy_node()


def test_a_pause_between_the_two_clock_reads_takes_no_trajectory_over_before_it_arrived(ros: RosSession) -> None:
    """The tick reads the node clock, then the timer's clock; paused 50 ms between the two, its interval is 50 ms
    longer on one than on the other, and the tick makes 5 updates it missed. A trajectory stamped at its arrival,
    starting at the measured state (as the node sends them), is taken over at the first of them after it, not
    before: no lead-in for the controller; the tick publishes once."""
    node = SimActuator(context=ros.context, namespace=f'/sim_test_{next(_ns)}',
                       cli_args=['--ros-args', '--params-file', str(YAML)])
    taken: list[Any] = []
    node.follower.on_takeover = taken.append
    stamps: list[int] = []
    node._pub = SimpleNamespace(publish=lambda m: stamps.append(m.header.stamp.sec * 10**9 + m.header.stamp.nanosec))
    clock, tick_clock = ManualClock(10**12), ManualClock(10**12)
    node._clock, node._tick_clock = clock, tick_clock
    try:
        node._on_tick()
        clock.ns += 5_000_000  # the trajectory arrives 5 ms later, stamped then
        arrival = clock.ns
        stamp = Time(sec=clock.ns // 10**9, nanosec=clock.ns % 10**9)
        node._on_trajectory(JointTrajectory(header=Header(stamp=stamp), joint_names=[JOINT],
                                            points=[point(Q0, 0.0), point(Q0 + 0.05, 2.0)]), {})
        clock.ns += 5_000_000
        tick_clock.ns += 60_000_000  # the next tick, read 50 ms late on the timer's clock
        node._on_tick()
        assert len(taken) == 1 and not taken[0].lead_in, [(r.takeover, r.lead_in) for r in taken]
        trajectory = node.follower._trajectory
        assert trajectory is not None and arrival * 1e-9 <= trajectory.start <= clock.ns * 1e-9, trajectory.start
        assert stamps == [10**12, clock.ns], stamps  # one measured state a tick, stamped at the tick
    finally:
        node.destroy_node()


def test_a_trajectory_received_during_a_late_tick_is_taken_over_at_the_update_after_its_reception(
        ros: RosSession) -> None:
    """The executor stalls 300 ms: the middleware received a trajectory 5 ms after the last tick, but its callback
    runs only just before the late tick. The controller manager's loop would have taken it over at its next update,
    10 ms after the last: so does the tick's first missed update, not the tick itself (which would start it 300 ms
    into its plan)."""
    node = SimActuator(context=ros.context, namespace=f'/sim_test_{next(_ns)}',
                       cli_args=['--ros-args', '--params-file', str(YAML)])
    clock, tick_clock = ManualClock(10**12), ManualClock(10**12)
    node._clock, node._tick_clock = clock, tick_clock
    try:
        node._on_tick()
        received = clock.ns + 5_000_000
        stamp = Time(sec=received // 10**9, nanosec=received % 10**9)
        clock.ns += 300_000_000
        node._on_trajectory(JointTrajectory(header=Header(stamp=stamp), joint_names=[JOINT],
                                            points=[point(Q0, 0.0), point(Q0 + 0.05, 2.0)]),
                            {'received_timestamp': received})
        clock.ns += 10_000_000
        tick_clock.ns += 310_000_000
        node._on_tick()
        trajectory = node.follower._trajectory
        assert trajectory is not None and trajectory.start == pytest.approx((10**12 + 10_000_000) * 1e-9, abs=1e-6)
        # the drive is on the plan 300 ms in (the lag behind a reference moving at 0.025 rad/s), not at rest
        assert node.drive.position > Q0 + 0.005 and node.follower.counters.tolerance_holds == 0
    finally:
        node.destroy_node()


def test_a_new_trajectory_starts_from_the_measured_state_not_the_last_reference(rig: Any) -> None:
    r = rig()
    far = min(Q0 + 0.2, LIMIT.upper)
    r.forward([far])  # the reference jumps to far; the drive follows at its speed limit
    r.states.wait_match(lambda m: m.position[0] > Q0 + 0.02)
    measured: list[float] = []  # the drive's position at the takeover (no encoder noise or rounding)
    r.node.follower.on_takeover = lambda _ref: measured.append(r.node.drive.position)
    r.traj_pub.publish(JointTrajectory(joint_names=[JOINT], points=[point(Q0 + 0.05, 3.0)]))
    wait_for(lambda: r.node.follower._trajectory is not None, what='the trajectory started')
    taken = r.node.follower._trajectory
    initial = taken.sample(taken.start)
    # It starts where the drive was measured at its first update after arrival, moving; not at the forward
    # command's reference.
    assert measured and initial.position == measured[0], (initial, measured)
    assert abs(far - initial.position) > 0.05 and initial.velocity > 0.0


def test_a_drive_that_cannot_follow_is_held_where_it_is(rig: Any) -> None:
    # A drive 100 times slower than the trajectory: it falls behind by more than the trajectory tolerance, and
    # the controller holds the measured position (the drive stops there).
    r = rig(max_velocity=VMAX / 100.0)
    r.traj_pub.publish(JointTrajectory(joint_names=[JOINT], points=[point(Q0 + 0.1, 1.5)]))
    wait_for(lambda: r.node.follower.counters.tolerance_holds == 1, what='the hold')
    held = r.node.follower.reference(0.0, 0.0, 0.0).position  # a hold ignores time and the measured state
    first = len(r.states)
    r.settle_at(held, first)
    assert held < Q0 + 0.02 and r.node.follower.holding_reason is not None


def test_an_inactive_controller_drops_what_it_is_sent_and_holds_the_drive(rig: Any) -> None:
    # As a deactivated joint_trajectory_controller or forward_command_controller: what arrives is dropped (never
    # taken over later), the drive holds where it is; once active again a trajectory is followed.
    r = rig()
    result = r.node.set_parameters([Parameter('controller_active', value=False)])[0]
    assert result.successful, result.reason
    msg = JointTrajectory(joint_names=[JOINT], points=[point(Q0 + 0.03, 1.0)])  # within the drive's speed
    r.traj_pub.publish(msg)
    r.forward([Q0 + 0.03])
    r.ros.wait_for(lambda: r.node.counters.dropped_inactive == 2, what='both dropped')
    start = len(r.states)
    r.states.wait_count(start + 120)  # 1.2 s at 100 Hz, past the trajectory's end
    assert all(abs(m.position[0] - Q0) <= SETTLED for m in r.states.messages[start:]), 'the drive moved'
    assert r.node.set_parameters([Parameter('controller_active', value=True)])[0].successful
    r.traj_pub.publish(msg)
    r.settle_at(Q0 + 0.03, len(r.states))
    assert r.node.counters.dropped_inactive == 2


def test_only_controller_active_is_settable_at_run_time(rig: Any) -> None:
    r = rig()
    assert not r.node.set_parameters([Parameter('publish_rate', value=50.0)])[0].successful
    assert not r.node.set_parameters([Parameter('controller_active', value=3.0)])[0].successful
    assert r.node.controller_active
