"""fourbar_node in trajectory mode and the simulated actuator over the real middleware, driven through random
sequences (hypothesis): commands in and out of range, antenna trajectories of 1 to 5 points with random times and
stamps (zero, past, future) ending at rest or not, measurements with NaN and jumps injected beside the drive's own,
and parameter changes. After every step, both sides having handled it:

- the node is up: no exception reached its callback boundary (``callback_errors`` 0);
- every trajectory it sent passed the controller's contract (the node's own check and the strict simulated
  controller refused none);
- the whole motion the controller makes of each (``rules.controller_motion``, from the state measured at its
  takeover, lead-in included) is within the motor's speed, acceleration and jerk limits;
- at every takeover the node promises continuity for, the reference's acceleration steps by at most
  ``TAKEOVER_STEP`` of the limit (``continuity``); not promised where the trajectory is taken over after its
  departure from the motion it continues (delivered later than the node's ``ARRIVAL_MARGIN_S``: counted, printed).

``make test`` runs a few short sequences (seconds); ``make test-stress`` many longer ones (minutes).
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Iterator
from dataclasses import replace
from typing import Any

import numpy as np
import pytest
from builtin_interfaces.msg import Duration, Time
from hypothesis import HealthCheck, Phase, settings
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, invariant, rule, run_state_machine_as_test
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64
from std_srvs.srv import Trigger
from support.ros_support import TIMEOUT, RosSession, wait_for
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from fourbar_ros.config.antenna_config import default_config
from fourbar_ros.interface.stamps import to_ns
from fourbar_ros.interface.topics import ANTENNA_JOINT, BROADCASTER_JOINT_STATES, MEASURED_JOINT_STATES, NODE_NAME
from fourbar_ros.motion.limits import JointLimits
from fourbar_ros.node.fourbar_node import FourBarNode
from fourbar_ros.node.sim_actuator import SimActuator
from fourbar_ros.rules.command_fate import Readiness
from fourbar_ros.rules.controller_motion import Reference
from fourbar_ros.rules.simulated_drive import Trajectory

pytestmark = pytest.mark.ros

CFG = default_config()
LIMITS = JointLimits.from_config(CFG)
JOINT = CFG.driven_joint
NS = '/stateful'
#: The motion's limits hold to rounding: the closed-form extremes of the quintics through the planned points.
ROUNDING = 1e-9
#: The most the reference's acceleration may step at a takeover, as a fraction of the limit: the node's plans are
#: jerk-limited, and a step is an unbounded jerk.
TAKEOVER_STEP = 0.05
#: A lead-in spanning at most this (rad) between states at rest is the controller holding the drive until the first
#: point (a start from rest stamped ahead), not a motion of its own.
HELD = 1e-9


def _smooth_at(ref: Reference, t: float) -> bool:
    """Whether the reference at ``t`` s from its origin is the node's jerk-limited motion: a quintic segment of its
    points (or the hold after them: acceleration 0), or a lead-in holding the drive at rest until the first point.
    Not: a cubic or linear segment, or a lead-in that moves the drive (the controller's own, from a measured state
    off the motion)."""
    knots = ref.knots
    if knots.size < 2 or t >= knots[-1]:
        return True
    i = max(int(np.searchsorted(knots, t, side='right')) - 1, 0)
    if ref.degrees[i] < 5:
        return False
    if i == 0 and ref.lead_in:
        (p0, v0, _), (p1, v1, _) = ref.sample(float(knots[0])), ref.sample(float(knots[1]))
        return v0 == 0.0 and v1 == 0.0 and abs(p1 - p0) <= HELD
    return True


def continuity(before: Trajectory | None, after: Trajectory) -> float | None:
    """The step of the reference's acceleration (a fraction of the limit) where the controller took ``after`` over
    from ``before`` (None: a hold at rest), or None where the node promises no continuity: either side not smooth
    there (``_smooth_at``: a cubic's acceleration is free at its points, a linear one steps; a lead-in that moves
    the drive follows a start from a measured state off the running motion, after a faulty measurement or with
    ``replan_tolerance`` 0)."""
    if not _smooth_at(after.reference, 0.0):
        return None
    a0 = 0.0
    if before is not None:
        t = after.start - before.start
        if not _smooth_at(before.reference, t):
            return None
        a0 = before.reference.sample(t)[2]
    return abs(after.reference.sample(0.0)[2] - a0) / LIMITS.at_rocker(2)


def worst_ratio(ref: Reference) -> float:
    """The largest of the reference's motor speed, acceleration and jerk over the limits, the controller's lead-in
    left out: a plan starts from the measured state ARRIVAL_MARGIN_S ahead, and after a faulty measurement (the
    'jump' rule) that state is not where the drive is; the lead-in bridges the gap (and the drive's tolerance check
    holds it). The node's own motion is what is held to the limits."""
    if ref.lead_in and ref.knots.size > 2:
        ref = replace(ref, takeover=float(ref.knots[1]), knots=ref.knots[1:], coefficients=ref.coefficients[1:],
                      degrees=ref.degrees[1:], lead_in=False)
    return max(LIMITS.ratio * v / LIMITS.motor(order) for order, v in ref.extremes().items())


class Rig:
    """The node (trajectory mode, the drive's joint states as its measurement) and the simulated actuator."""

    def __init__(self, ros: RosSession) -> None:
        self.ros = ros
        self.sim = SimActuator(context=ros.context, namespace=NS)
        self.node = FourBarNode(context=ros.context, namespace=NS,
                                parameter_overrides=[Parameter('mode', value='trajectory')],
                                cli_args=['--ros-args', '-r', f'{MEASURED_JOINT_STATES.name}:='
                                                              f'{BROADCASTER_JOINT_STATES.name}'])
        self.references: list[Reference] = []
        self.worst = 0.0
        self.worst_reference: Reference | None = None
        #: the takeovers continuity was checked at, the largest acceleration step (fraction of the limit) and both
        #: sides there; the next takeover after a faulty measurement is left out (it may start from that fault)
        self.continuous_checked = 0
        self.worst_step = 0.0
        self.worst_step_sides: tuple[Trajectory | None, Trajectory] | None = None
        self.after_fault = False
        self.holds = 0
        #: the latest steps taken (rule and arguments), to say what led to the worst step
        self.recent: deque[str] = deque(maxlen=12)
        self.worst_step_after: list[str] = []
        self.sim.follower.on_takeover = self._taken_over
        #: (arrival ns, departure ns or None) of each trajectory the sim accepted and has not taken over yet, and
        #: the (stamp ns, points) of the latest accepted: the departure is where the node's new plan leaves the
        #: motion it continues (``_departure_ns``)
        self.departures: deque[tuple[int, int | None]] = deque()
        self.last_accepted: tuple[int, Any] | None = None
        #: takeovers after their trajectory's departure (delivered later than the node's arrival margin), and the
        #: latest by how much (s)
        self.late = 0
        self.latest = 0.0
        #: every measured driven position the node's completion passed on to the actuation
        self.seen: set[float] = set()
        completion = self.node.completion
        assert completion is not None and completion._on_measured is not None
        passed_on = completion._on_measured

        def note(position: float, velocity: float | None, stamp_ns: int) -> None:
            self.seen.add(position)
            passed_on(position, velocity, stamp_ns)
        completion._on_measured = note
        #: (rule, reason) of every trajectory the simulated controller refused
        self.refusals: list[tuple[str, ...]] = []
        receive = self.sim.follower.receive

        def received(*args: Any) -> Any:
            refusal = receive(*args)
            _names, points, stamp, now = args
            if refusal is None:
                self.departures.append((now, _departure_ns(stamp, points, self.last_accepted)))
                self.last_accepted = (stamp, points)
            self.recent.append(f'the sim received {len(points)} points, stamp {stamp}, at {now}, first at '
                               f'{points[0].time_from_start if points else None}')
            if refusal is not None:
                _names, points, stamp, now = args
                last = points[-1].time_from_start if points else None
                self.refusals.append((refusal.rule.value, refusal.reason, f'{len(points)} points, stamp {stamp}, '
                                      f'last at {last}, arrived {now}'))
            return refusal
        self.sim.follower.receive = received  # type: ignore[method-assign]
        ros.add_node(self.sim)
        ros.add_node(self.node)
        self.cmd = ros.publisher(Float64, f'{NS}/antenna_angle_cmd', 10)
        self.antenna = ros.publisher(JointTrajectory, f'{NS}/antenna_trajectory', 10)
        self.fake = ros.publisher(JointState, f'{NS}/{BROADCASTER_JOINT_STATES.name}', 10)
        ros.wait_subscribers(self.cmd)
        ros.wait_subscribers(self.antenna)
        ros.wait_subscribers(self.fake)  # the node's measured-joint subscription
        ros.wait_subscribers(self.node.actuation._trajectory_pub)
        self.halt_client = ros.node.create_client(Trigger, f'{NS}/{NODE_NAME}/halt')
        self.resume_client = ros.node.create_client(Trigger, f'{NS}/{NODE_NAME}/resume')
        for client in (self.halt_client, self.resume_client):
            assert client.wait_for_service(timeout_sec=TIMEOUT), f'no service {client.srv_name} in {TIMEOUT} s'
        #: the node's trajectories sent once halted (its brake included); None while not halted
        self.sent_at_halt: int | None = None
        wait_for(lambda: self.node.actuation.measured is not None, what='the measured driven joint at the node')

    def _taken_over(self, ref: Reference) -> None:
        self.references.append(ref)
        follower = self.sim.follower
        assert follower.trajectory is not None
        holds = follower.counters.tolerance_holds + follower.counters.goal_time_holds
        taken_ns = round(follower.trajectory.start * 1e9)
        departure = None
        while self.departures and self.departures[0][0] <= taken_ns + 1000:  # the sim's clock in float s: +-1 us
            departure = self.departures.popleft()[1]
        # Taken over after its departure, the trajectory reached the controller later than the node's arrival margin
        # (a loaded machine): the reference is then part-way into the new plan, off the running one, and the node
        # promises no continuity there.
        late = departure is not None and taken_ns > departure
        if late:
            assert departure is not None
            self.late += 1
            self.latest = max(self.latest, (taken_ns - departure) * 1e-9)
        # A controller that held on a tolerance since the last takeover dropped the motion the node may go on
        # from: the node notices only once the drive is replan_tolerance off it.
        step = (None if self.after_fault or holds > self.holds or late
                else continuity(follower.previous, follower.trajectory))
        self.after_fault, self.holds = False, holds
        if step is not None:
            self.continuous_checked += 1
            if step > self.worst_step:
                self.worst_step, self.worst_step_sides = step, (follower.previous, follower.trajectory)
                self.worst_step_after = list(self.recent)
        ratio = worst_ratio(ref)
        if ratio > self.worst:
            self.worst, self.worst_reference = ratio, ref

    def call(self, client: Any) -> Any:
        """Call a Trigger service; its answer."""
        future = client.call_async(Trigger.Request())
        self.ros.wait_for(future.done, what=f'the answer of {client.srv_name}')
        return future.result()

    def settled(self) -> None:
        """Wait until the simulated controller has received every trajectory the node sent and taken over the
        last one it accepted."""
        node, follower = self.node.actuation.counters, self.sim.follower
        self.ros.wait_for(lambda: follower.counters.accepted + sum(follower.counters.refused.values())
                          + follower.counters.refused_not_finite + self.sim.counters.dropped_inactive
                          >= node.trajectories_sent
                          and follower.waiting == 0,
                          what=f'the sim to take over the node\'s {node.trajectories_sent} trajectories '
                               f'(accepted {follower.counters.accepted}, refused {follower.counters.refused})')

    def close(self) -> None:
        self.sim.set_parameters([Parameter('controller_active', value=True)])
        self.ros.destroy(self.cmd, self.antenna, self.fake, self.halt_client, self.resume_client)
        self.ros.remove_node(self.node)
        self.ros.remove_node(self.sim)


def _departure_ns(stamp_ns: int, points: Any, previous: tuple[int, Any] | None) -> int | None:
    """Where a trajectory's own motion starts (ns, node clock): continuing the previous one (the same stamp), at
    the last of the leading points it repeats to the bit (the node's new plan starts at the running trajectory's
    point there); else at its first point. None for a zero stamp (it starts on arrival)."""
    if stamp_ns == 0:
        return None

    def key(p: Any) -> tuple[Any, ...]:
        return (to_ns(p.time_from_start), tuple(p.positions), tuple(p.velocities), tuple(p.accelerations))
    at = to_ns(points[0].time_from_start)
    if previous is not None and previous[0] == stamp_ns:
        old = {key(p) for p in previous[1]}
        for p in points:
            if key(p) not in old:
                break
            at = to_ns(p.time_from_start)
    return stamp_ns + at


@pytest.fixture(scope='module')
def rig(ros: RosSession) -> Iterator[Rig]:
    r = Rig(ros)
    yield r
    r.close()


def _duration(t: float) -> Duration:
    ns = round(t * 1e9)
    return Duration(sec=ns // 10**9, nanosec=ns % 10**9)


angles = st.one_of(st.floats(CFG.theta_min, CFG.theta_max), st.floats(-0.5, 0.5),
                   st.sampled_from([math.nan, math.inf, CFG.theta_min, CFG.theta_max]))


class Sequences(RuleBasedStateMachine):
    """Random steps against the rig of the module (``RIG``)."""

    rig: Rig

    @rule(theta=angles)
    def command(self, theta: float) -> None:
        self.rig.recent.append(f'command {theta!r}')
        counters = self.rig.node.counters
        before = counters.commands_received
        self.rig.cmd.publish(Float64(data=theta))
        self.rig.ros.wait_for(lambda: counters.commands_received > before, what='the command received')

    @rule(n=st.integers(1, 5), data=st.data(), stamp=st.sampled_from(['zero', 'past', 'future']),
          at_rest=st.booleans(), fields=st.sampled_from([0, 1, 2]))
    def antenna_trajectory(self, n: int, data: st.DataObject, stamp: str, at_rest: bool, fields: int) -> None:
        steps = data.draw(st.lists(st.floats(0.001, 1.5), min_size=n, max_size=n))
        times = list(np.cumsum(steps) - (steps[0] if data.draw(st.booleans()) else 0.0))
        theta = data.draw(st.lists(st.floats(CFG.theta_min, CFG.theta_max), min_size=n, max_size=n))
        rates = data.draw(st.lists(st.floats(-0.05, 0.05), min_size=n, max_size=n))
        if at_rest:
            rates[-1] = 0.0
        pts = [JointTrajectoryPoint(positions=[theta[i]], velocities=[rates[i]] if fields else [],
                                    accelerations=[0.0] if fields == 2 else [], time_from_start=_duration(t))
               for i, t in enumerate(times)]
        msg = JointTrajectory(joint_names=[ANTENNA_JOINT], points=pts)
        self.rig.recent.append(f'antenna trajectory stamp {stamp}, times {times}, theta {theta}, rates {rates}, '
                               f'fields {fields}')
        now = self.rig.node.get_clock().now().nanoseconds
        at = {'zero': 0, 'past': now - 500_000_000, 'future': now + 300_000_000}[stamp]
        msg.header.stamp = Time(sec=at // 10**9, nanosec=at % 10**9)
        counters = self.rig.node.actuation.counters
        before = counters.trajectories_received
        self.rig.antenna.publish(msg)
        self.rig.ros.wait_for(lambda: counters.trajectories_received > before, what='the antenna trajectory received')

    @rule(kind=st.sampled_from(['nan', 'jump', 'gap']), jump=st.floats(-0.2, 0.2))
    def measurement(self, kind: str, jump: float) -> None:
        """A bad or jumping measurement beside the drive's own (as a faulty encoder gives); 'gap': none for a
        while (the drive's own go on: the node sees the next)."""
        if kind == 'gap':
            return
        measured = self.rig.node.actuation.measured
        q = math.nan if kind == 'nan' else (measured.position if measured else 0.86) + jump
        self.rig.after_fault |= kind == 'jump'
        self.rig.recent.append(f'measurement {kind} {q!r}')
        completion = self.rig.node.completion
        assert completion is not None
        counters = completion.counters
        refused, out = counters.measurements_refused_not_finite, counters.measurements_out_of_range
        self.rig.fake.publish(JointState(name=[JOINT], position=[q], velocity=[0.0], effort=[0.0]))
        seen = self.rig.seen

        def handled() -> bool:
            if kind == 'nan':
                return counters.measurements_refused_not_finite > refused
            return counters.measurements_out_of_range > out or q in seen
        self.rig.ros.wait_for(handled, what=f'the {kind} measurement {q!r} rad handled')

    @rule(policy=st.sampled_from(['reject', 'retime']), tolerance=st.sampled_from([0.0, 0.002, 0.01, 0.017]))
    def parameters(self, policy: str, tolerance: float) -> None:
        self.rig.recent.append(f'parameters {policy} {tolerance}')
        results = self.rig.node.set_parameters([Parameter('limit_policy', value=policy),
                                                Parameter('replan_tolerance', value=tolerance)])
        assert all(r.successful for r in results), [r.reason for r in results]

    @rule(active=st.booleans())
    def controller(self, active: bool) -> None:
        """The simulated controllers deactivated or activated (as `switch_controllers` does): while inactive what the
        node sends is dropped and the drive holds."""
        self.rig.recent.append(f'controller active {active}')
        results = self.rig.sim.set_parameters([Parameter('controller_active', value=active)])
        assert all(r.successful for r in results), [r.reason for r in results]
        fates = self.rig.node.actuation.fates
        if fates.readiness is Readiness.NOT_FOLLOWED:
            # Without the controller manager's messages the node cannot hear it: the next takeover may continue a
            # motion the controller dropped.
            self.rig.after_fault = True
            return
        want = 'active' if active else 'inactive'
        self.rig.ros.wait_for(lambda: (fates.readiness is Readiness.ACTIVE) == active,
                              what=f'the node to see the controller {want} (it sees {fates.readiness.value})')

    @rule(again=st.booleans())
    def halt(self, again: bool) -> None:
        """The operator's halt (the ~/halt service), once or twice: the running motion brakes to rest and nothing
        is sent until a resume."""
        rig = self.rig
        rig.recent.append(f'halt{" twice" if again else ""}')
        for _ in range(1 + again):
            answer = rig.call(rig.halt_client)
            assert answer.success, answer
        if rig.sent_at_halt is None:
            rig.sent_at_halt = rig.node.actuation.counters.trajectories_sent

    @rule()
    def resume(self) -> None:
        rig = self.rig
        rig.recent.append('resume')
        answer = rig.call(rig.resume_client)
        assert answer.success == (rig.sent_at_halt is not None), answer
        rig.sent_at_halt = None

    @invariant()
    def nothing_broke(self) -> None:
        rig = self.rig
        rig.settled()
        node = rig.node
        assert node.guard.total == 0, node.guard.errors
        assert rig.sim.guard.total == 0, rig.sim.guard.errors  # the rig's checks run in the sim's callbacks
        assert sum(node.actuation.counters.refused.values()) == 0, node.actuation.counters.refused
        follower = rig.sim.follower.counters
        assert sum(follower.refused.values()) + follower.refused_not_finite == 0, rig.refusals
        assert rig.worst <= 1.0 + ROUNDING, (rig.worst, rig.worst_reference)
        assert rig.worst_step <= TAKEOVER_STEP, _step_report(rig)
        # halted: nothing sent after the halt's brake (no command, no antenna trajectory, no controller coming back)
        if rig.sent_at_halt is not None:
            assert node.actuation.halt.why, 'the node is not halted'
            assert node.actuation.counters.trajectories_sent == rig.sent_at_halt, (
                f'sent while halted: {node.actuation.counters.trajectories_sent - rig.sent_at_halt} trajectories '
                f'after the steps {list(rig.recent)}')
        # every served command has one fate: final, but for the latest; or it repeated the one in force and joined it
        fates = node.actuation.fates
        served = node.counters.commands_accepted + node.counters.commands_clamped
        finals = sum(n for f, n in fates.counts.items() if f.final)
        pending = fates.current is not None and not fates.current.fate.final
        assert fates.pending is None, fates.pending
        assert finals + pending + fates.repeats == served, (served, fates.counts, fates.repeats, fates.current)


def _step_report(rig: Rig) -> str:
    """Both sides of the worst acceleration step at a takeover."""
    assert rig.worst_step_sides is not None
    before, after = rig.worst_step_sides
    t = after.start - before.start if before is not None else 0.0
    was = before.reference.sample(t) if before is not None else 'a hold at rest'
    return (f'at a takeover the reference acceleration stepped by {rig.worst_step:.1%} of the limit (at most '
            f'{TAKEOVER_STEP:.0%}): followed until then {was} (rad, rad/s, rad/s^2), taken over '
            f'{after.reference.sample(0.0)}, after the steps {rig.worst_step_after}; the reference followed '
            f'{before.reference if before is not None else None}; the new reference {after.reference}')


def _run(rig: Rig, examples: int, steps: int) -> None:
    Sequences.rig = rig
    # No shrinking: each step waits on the middleware, and shrinking a failing sequence takes many minutes; the
    # failure message names the steps that led to it.
    run_state_machine_as_test(Sequences, settings=settings(
        max_examples=examples, stateful_step_count=steps, deadline=None, derandomize=True,
        phases=[Phase.explicit, Phase.reuse, Phase.generate], suppress_health_check=list(HealthCheck)))
    print(f'stateful: {len(rig.references)} trajectories taken over; the worst whole-motion limit ratio '
          f'{rig.worst:.9f}; continuity checked at {rig.continuous_checked} takeovers, the largest acceleration '
          f'step {rig.worst_step:.2%} of the limit; {rig.late} taken over after their departure (the latest by '
          f'{rig.latest:.3g} s); halts {rig.node.actuation.halt.halts}, commands dropped while halted '
          f'{rig.node.actuation.halt.dropped}; node counters {rig.node.actuation.counters.as_dict()}')


def test_random_sequences_never_stop_the_node_nor_break_the_contract_or_the_limits(rig: Rig) -> None:
    _run(rig, examples=4, steps=12)


@pytest.mark.stress
def test_random_sequences_many_and_long(rig: Rig) -> None:
    _run(rig, examples=200, steps=40)
