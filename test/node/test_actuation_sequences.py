"""The trajectory mode's actuation in-process, on a clock of the test's own, through random sequences drawn over the
edges ordinary use meets: the range's exact ends and one ulp inside, measurements late by up to
``measurement_timeout`` (stamped, zero-stamped, stamped ahead), the controller switched off and on between any two
callbacks, a setpoint republished at 1 to 50 Hz, commands just after a motion's end.

The drive is the model of joint_trajectory_controller on mock hardware (``rules.controller_motion``, held to the
real controller by the real-stack tests): it takes each trajectory over ``delay`` s after it went out, its lead-in
from its own state there, and on deactivation holds where it is. Invariants: the whole reference of every
trajectory taken over, lead-in included, within the speed, acceleration and jerk limits; every reachable command
goes out or waits (none refused); each served command one final fate (the latest: held or sent), or joined to the
one in force; a command whose drive rests on its target is reached.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator
from typing import Any, ClassVar

import numpy as np
import pytest
from hypothesis import HealthCheck, Phase, settings
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, initialize, invariant, rule, run_state_machine_as_test
from rclpy.node import Node
from support.ros_support import RosSession

from fourbar_ros.config.antenna_config import config_from_values
from fourbar_ros.interface.stamps import ns_to_seconds, seconds_to_ns, to_ns
from fourbar_ros.motion.limits import JointLimits
from fourbar_ros.motion.planner import driven_angles
from fourbar_ros.node.actuation import Actuation
from fourbar_ros.rules.command_fate import Fate, Readiness
from fourbar_ros.rules.controller_motion import ControllerPoint, Reference, controller_reference
from fourbar_ros.rules.outgoing import actuation_contract
from fourbar_ros.rules.takeover import ARRIVAL_MARGIN_S
from fourbar_ros.runtime.problem_log import ProblemLog

pytestmark = pytest.mark.ros

CFG = config_from_values({'mode': 'trajectory'})
LIMITS = JointLimits.from_config(CFG)
PERIOD = 0.01  # s: the controller manager's update period at 100 Hz
#: The reference's extremes are the closed-form maxima of the controller's polynomials, evaluated in float64: a
#: plan at PLAN_SHRINK of a limit leaves it far below 1 + 1e-9; a stale speed planned into the lead-in is 1.7x to
#: 100x over (the failures this test was written against).
ROUNDING = 1e-9
LO, HI = CFG.theta_min, CFG.theta_max
EDGES = (LO, math.nextafter(LO, math.inf), HI, math.nextafter(HI, -math.inf))
THETAS = st.one_of(st.sampled_from(EDGES), st.floats(LO, HI))
START_NS = 1_700_000_000 * 10**9
#: When the controller takes over a trajectory sent from a callback other than a command's (s after it).
RESUMED_DELAY_S = 0.005


class Recorder:
    """Stands for the trajectory publisher: keeps what goes out."""

    def __init__(self) -> None:
        self.sent: list[Any] = []

    def publish(self, msg: Any) -> None:
        self.sent.append(msg)


def _points(msg: Any) -> list[ControllerPoint]:
    def one(x: Any) -> float | None:
        return float(x[0]) if len(x) else None

    return [ControllerPoint(ns_to_seconds(to_ns(p.time_from_start)), float(p.positions[0]), one(p.velocities),
                            one(p.accelerations)) for p in msg.points]


class Sequences(RuleBasedStateMachine):
    node: Node
    #: the worst of each order over every sequence run (order: ratio to its limit), and the fates of every command
    seen: ClassVar[dict[int, float]] = {}
    fates: ClassVar[dict[str, int]] = {}

    @initialize(theta=THETAS)
    def start(self, theta: float) -> None:
        self.now_ns = START_NS
        self.said: list[str] = []  # the node's warnings, every one (period 0)
        problems = ProblemLog(lambda level, line: self.said.append(f'{level}: {line}'), period=0.0)
        self.act = Actuation(self.node, lambda: CFG, problems, actuation_contract(CFG, 'trajectory'))
        self.act._now_ns = lambda: self.now_ns  # type: ignore[method-assign]  # the test's clock
        self.out = Recorder()
        self.act._trajectory_pub = self.out  # type: ignore[assignment]
        self.act._on_readiness(Readiness.ACTIVE)
        self.q = float(driven_angles(CFG, np.array([theta]))[0])  # where the drive rests until a takeover
        self.ref: Reference | None = None  # the controller's reference, times from ref_origin_ns
        self.ref_origin_ns = 0
        self.active = True
        self.taken = 0  # trajectories taken over
        self.served = 0
        self.worst = (0.0, '')
        self.measure(0.0, 'stamped')

    # ------------------------------------------------------------------ the drive

    def drive_at(self, t_ns: int) -> tuple[float, float]:
        """The drive's position rad and velocity rad/s at ``t_ns``: the reference of the trajectory it follows."""
        if self.ref is None:
            return self.q, 0.0
        p, v, _ = self.ref.sample(ns_to_seconds(t_ns - self.ref_origin_ns))
        return p, v

    def take_over(self, delay: float) -> None:
        """The controller takes the latest trajectory sent over ``delay`` s after now, from its own state there."""
        if len(self.out.sent) <= self.taken or not self.active:
            return
        msg = self.out.sent[-1]
        self.taken = len(self.out.sent)
        at_ns = self.now_ns + seconds_to_ns(delay)
        p, v = self.drive_at(at_ns)
        stamp_ns = to_ns(msg.header.stamp)
        origin = stamp_ns or at_ns
        ref = controller_reference(True, _points(msg), 0.0 if stamp_ns else None, ns_to_seconds(at_ns - origin),
                                   p, v, PERIOD)
        for order, value in ref.extremes().items():
            ratio = LIMITS.ratio * value / LIMITS.motor(order)
            self.seen[order] = max(self.seen.get(order, 0.0), ratio)
            if ratio > self.worst[0]:
                self.worst = (ratio, f'order {order} at {ratio:.6g} x its limit; taken over from {p!r} rad, '
                                     f'{v!r} rad/s; measured {self.act.measured} at {self.act.measured_ns}')
        self.q, _ = self.drive_at(at_ns)  # (the state held if it is deactivated before moving on)
        self.ref, self.ref_origin_ns = ref, origin
        self.now_ns = max(self.now_ns, at_ns)

    # ------------------------------------------------------------------ what the node meets

    @rule(theta=THETAS, delay=st.floats(1e-4, ARRIVAL_MARGIN_S * 0.99))
    def command(self, theta: float, delay: float) -> None:
        self.served += 1
        self.act.command(theta)
        self.take_over(delay)

    @rule(theta=THETAS, hz=st.one_of(st.sampled_from((1.0, 4.0, 10.0, 50.0)), st.floats(1.0, 50.0)),
          n=st.integers(2, 30), delay=st.floats(1e-4, 0.02))
    def republish(self, theta: float, hz: float, n: int, delay: float) -> None:
        """``ros2 topic pub -r HZ``: the same angle again and again, a measurement between each two."""
        for _ in range(n):
            self.served += 1
            self.act.command(theta)
            self.take_over(delay)
            self.advance(1.0 / hz)
            self.measure(0.0, 'stamped')

    @rule(dt=st.one_of(st.sampled_from((0.01, 0.05, 0.3)), st.floats(0.0, 3.0)))
    def advance(self, dt: float) -> None:
        self.now_ns += seconds_to_ns(dt)

    @rule()
    def to_the_end(self) -> None:
        """Time to just after the motion's planned end (a command then is the ordinary case of a late one)."""
        motion = self.act.motion
        if motion is not None:
            self.now_ns = max(self.now_ns, motion.start_ns + seconds_to_ns(motion.duration) + seconds_to_ns(0.01))

    @rule(lag=st.one_of(st.sampled_from((0.0, 0.1, 0.3, CFG.measurement_timeout)),
                        st.floats(0.0, CFG.measurement_timeout)),
          stamp=st.sampled_from(('stamped', 'zero', 'ahead')))
    def measure(self, lag: float, stamp: str) -> None:
        """A measurement of the drive taken ``lag`` s ago, arriving now; or taken now, stamped zero (on arrival) or
        10 ms ahead (a drive's clock ahead of the node's)."""
        at_ns = max(self.now_ns - seconds_to_ns(lag), START_NS) if stamp == 'stamped' else self.now_ns
        p, v = self.drive_at(at_ns)
        stamp_ns = {'stamped': at_ns, 'zero': 0, 'ahead': at_ns + seconds_to_ns(0.01)}[stamp]
        self.act.note_measured(p, v, stamp_ns)
        self.act.note_theta(self.theta_of(p))
        self.take_over(RESUMED_DELAY_S)  # a held command it resumed

    @rule(lag=st.floats(0.0, 0.1))
    def switch_off_and_on(self, lag: float) -> None:
        """The controller deactivated and activated between two callbacks; then a measurement from before it."""
        self.q, _ = self.drive_at(self.now_ns)
        self.ref = None  # the controller holds the drive where it is
        self.act._on_readiness(Readiness.INACTIVE)
        self.act._on_readiness(Readiness.ACTIVE)
        self.measure(lag + 0.03, 'stamped')

    @rule()
    def fate_timer(self) -> None:
        self.act._on_fate_timer()
        self.take_over(RESUMED_DELAY_S)

    @staticmethod
    def theta_of(q: float) -> float:
        """The antenna angle (rad) at driven angle q (rad): what the node completes from a measurement."""
        return float(CFG.linkage.from_rocker(q, CFG.driven, CFG.branch).theta)

    # ------------------------------------------------------------------ invariants

    def teardown(self) -> None:
        for fate, n in self.act.fates.counts.items():
            self.fates[fate.value] = self.fates.get(fate.value, 0) + n
        self.fates['repeated'] = self.fates.get('repeated', 0) + self.act.fates.repeats

    @invariant()
    def within_the_limits(self) -> None:
        assert self.worst[0] <= 1.0 + ROUNDING, self.worst[1]

    @invariant()
    def nothing_refused(self) -> None:
        # every reachable target goes out or waits: nothing dropped as refused, nothing planned past the range
        dropped = self.act.fates.counts[Fate.DROPPED]
        assert dropped == 0, self.said[-3:]

    @invariant()
    def one_fate_each(self) -> None:
        fates = self.act.fates
        finals = sum(n for f, n in fates.counts.items() if f.final)
        live = fates.current is not None and not fates.current.fate.final
        assert fates.pending is None
        assert finals + live + fates.repeats == self.served, (self.served, fates.counts, fates.repeats,
                                                              fates.current)

    @invariant()
    def reached_where_it_rests(self) -> None:
        cmd = self.act.fates.current
        motion = self.act.motion
        if cmd is None or cmd.fate is not Fate.SENT or motion is None or self.ref is None:
            return
        if not motion.done(self.now_ns) or not self.act.measured_ns >= motion.start_ns + seconds_to_ns(
                motion.duration):
            return
        p, v = self.drive_at(self.now_ns)
        if v == 0.0 and abs(self.theta_of(p) - cmd.theta) <= 0.5 * CFG.reached_tolerance:
            self.act.note_theta(self.theta_of(p))
            assert cmd.fate is Fate.REACHED, (cmd, p)


@pytest.fixture(scope='module')
def node(ros: RosSession) -> Iterator[Node]:
    n = Node('actuation_sequences', context=ros.context)
    yield n
    n.destroy_node()


def _run(node: Node, examples: int, steps: int) -> None:
    Sequences.node = node
    try:
        # No shrinking: a sequence of a few dozen steps reads as it is, and shrinking one takes minutes.
        run_state_machine_as_test(Sequences, settings=settings(
            max_examples=examples, stateful_step_count=steps, deadline=None, derandomize=True,
            phases=[Phase.explicit, Phase.reuse, Phase.generate], suppress_health_check=list(HealthCheck)))
    finally:
        names = {1: 'speed', 2: 'acceleration', 3: 'jerk'}
        print('worst over every takeover, as a multiple of its limit:',
              ', '.join(f'{names[k]} {v:.4g}' for k, v in sorted(Sequences.seen.items())), '; fates:', Sequences.fates)


def test_random_sequences_keep_every_takeover_within_the_limits_and_every_fate_true(node: Node) -> None:
    _run(node, examples=25, steps=25)


@pytest.mark.stress
def test_random_sequences_many_and_long(node: Node) -> None:
    _run(node, examples=150, steps=40)


@pytest.mark.parametrize('start', [0.0, CFG.theta_min], ids=['resting on the target', 'from theta_min'])
def test_a_setpoint_republished_at_10_hz_goes_out_once_and_is_reached(node: Node, start: float) -> None:
    """``ros2 topic pub -r 10`` of 0 rad for 8 s, a measurement between each two: one trajectory, reached, every
    repeat joined to it, none superseded."""
    Sequences.node = node
    machine = Sequences()
    machine.start(start)
    machine.republish(0.0, 10.0, 80, 0.005)
    fates = machine.act.fates
    seen = {f.value: n for f, n in fates.counts.items() if n} | {'repeated': fates.repeats,
                                                                    'trajectories': len(machine.out.sent)}
    print(f'from {start!r} rad:', seen)
    assert seen == {'sent': 1, 'reached': 1, 'repeated': 79, 'trajectories': 1}, machine.said[-3:]


class SetpointRecorder:
    """Stands for the setpoint publisher: keeps each setpoint (rad)."""

    def __init__(self) -> None:
        self.sent: list[float] = []

    def publish(self, msg: Any) -> None:
        self.sent.append(float(msg.data[0]))


FORWARD = config_from_values({'mode': 'forward'})


@pytest.mark.parametrize('target', [FORWARD.theta_min, 0.05], ids=['reversing', 'going on'])
def test_a_forward_stream_replanned_mid_motion_keeps_the_samples_within_the_limits(node: Node, target: float) -> None:
    """Forward mode at full speed, a new command between two ticks of the control timer, at 12 phases of the tick
    against the stream's grid and 12 of the command between ticks: the setpoints as the timer publishes them, one
    per tick, have divided differences within the speed, acceleration and jerk limits (relative 1e-6: the
    positions' rounding over T^3). Started from the state at the command's own time, off the stream's grid, the
    samples stepped by up to two periods' motion in one: 2x the speed, 31x the acceleration, 628x the jerk limit."""
    period_ns = seconds_to_ns(1.0 / FORWARD.control_rate)
    worst = dict.fromkeys((1, 2, 3), 0.0)
    for tick_phase, command_phase in itertools.product(np.linspace(0.0, 0.99, 12), repeat=2):
        clock = [START_NS]
        act = Actuation(node, lambda: FORWARD, ProblemLog(lambda _level, _line: None),
                        actuation_contract(FORWARD, 'forward'))
        act._now_ns = lambda c=clock: c[0]  # type: ignore[method-assign]
        out = SetpointRecorder()
        act._setpoint_pub = out  # type: ignore[assignment]
        act._on_readiness(Readiness.ACTIVE)
        act.note_measured(float(driven_angles(FORWARD, np.array([FORWARD.theta_max]))[0]), 0.0, START_NS)
        act.command(0.0)  # from theta_max to 0 (2.5 s)
        ticks = START_NS + round(tick_phase * period_ns) + np.arange(1, 400) * period_ns
        first = len(out.sent)
        for k, tick in enumerate(ticks):
            clock[0] = int(tick)
            act._on_control_timer()
            if k == 100:  # 1 s into the motion: at full speed
                clock[0] = int(tick) + round(command_phase * period_ns) + 1
                act.command(target)
        q = np.array(out.sent[first:])
        for order in (1, 2, 3):
            q = np.diff(q) * FORWARD.control_rate
            worst[order] = max(worst[order], float(np.max(np.abs(q))) / LIMITS.at_rocker(order))
    print(f'forward replan mid-stream (to {target!r} rad), worst over every phase, as a multiple of its limit:',
          {order: round(w, 4) for order, w in worst.items()})
    assert max(worst.values()) <= 1.0 + 1e-6, worst
