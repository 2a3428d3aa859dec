"""Every target at or next to an end of the tilt range is served, in every mode, and nothing sent passes the range.

Through the node's own pure entries (``serve_command``, ``serve_antenna_trajectory``: what fourbar_ros.node.actuation
calls per message): commands to theta_min and theta_max exactly and one ulp inside, from rest positions across the
range, exactly at each end and up to measured_range_tolerance outside it, in forward mode (setpoints) and trajectory
mode; antenna trajectories of each spline kind ending exactly at each end; plans from a start at the speed limit.
Sent positions lie within ``range_slack`` of the range; setpoints within the range itself.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from support.trajectory_points import Duration, Point

from fourbar_ros.config.antenna_config import default_config
from fourbar_ros.core.errors import UnreachableError
from fourbar_ros.interface.stamps import from_ns, seconds_to_ns, to_ns
from fourbar_ros.interface.topics import ANTENNA_JOINT
from fourbar_ros.motion.limits import JointLimits, range_slack, worst_violation
from fourbar_ros.motion.planner import JointMotionState, driven_angles, plan_motion
from fourbar_ros.motion.refine import SAMPLES, deviation_bounds
from fourbar_ros.motion.splines import evaluate, hermite_coefficients
from fourbar_ros.motion.trajectory import AntennaTrajectory, DrivenTrajectory, antenna_trajectory, to_driven
from fourbar_ros.rules.antenna_trajectory import TrajectoryProblem, convert, problem_of
from fourbar_ros.rules.motion_plan import driven_range, plan_command, planned_points, planned_setpoints
from fourbar_ros.rules.outgoing import actuation_contract
from fourbar_ros.rules.policy import Outcome, Policy, decide
from fourbar_ros.rules.serve import ActuationCounters, Drive, Outgoing, Refused, serve_antenna_trajectory, serve_command

CFG = default_config()
LIMITS = JointLimits.from_config(CFG)
LOWER, UPPER = driven_range(CFG)
SLACK = range_slack(LOWER, UPPER)
TOL = CFG.measured_range_tolerance
NOW = 10**12
MODES = {'forward': actuation_contract(CFG, 'forward'), 'trajectory': actuation_contract(CFG, 'trajectory')}
THETA_MIN, THETA_MAX = CFG.theta_min, CFG.theta_max


def inward(x: float, toward: float) -> float:
    """The double next to x towards ``toward``."""
    return float(np.nextafter(x, toward))


#: The targets at the ends: each end exactly and one ulp inside.
END_TARGETS = (THETA_MIN, inward(THETA_MIN, 0.0), THETA_MAX, inward(THETA_MAX, 0.0))
#: Rest positions (rad) at the edges: each end, an ulp either side, measured_range_tolerance either side.
EDGE_RESTS = tuple(x for end in (LOWER, UPPER) for x in (
    end, inward(end, -math.inf), inward(end, math.inf), end - TOL, end + TOL, inward(end - TOL, end),
    inward(end + TOL, end)))
#: Rest positions across the range: the edges and five inside.
SPREAD_RESTS = (*EDGE_RESTS, *(float(q) for q in np.linspace(LOWER, UPPER, 7)[1:-1]))
RESTS = st.one_of(st.sampled_from(EDGE_RESTS), st.floats(LOWER - TOL, UPPER + TOL))
KINDS = {'linear': 1, 'cubic': 3, 'quintic': 5}


def sent_positions(out: Outgoing) -> np.ndarray:
    """The positions (rad) that leave for the controller: the setpoints, or the trajectory's points."""
    if out.setpoints is not None:
        return np.asarray(out.setpoints.positions)
    return np.array([p.positions[0] for p in out.points])


def check_sent(out: Outgoing | Refused, end_q: float | None = None) -> None:
    """Served, nothing sent past the range by more than the slack (setpoints: not at all), ending at ``end_q``
    (rad, to the slack) when given."""
    assert isinstance(out, Outgoing), out
    q = sent_positions(out)
    assert q.size
    over = 0.0 if out.setpoints is not None else SLACK
    assert LOWER - over <= q.min() and q.max() <= UPPER + over, (q.min() - LOWER, q.max() - UPPER)
    if end_q is not None:
        assert abs(float(q[-1]) - end_q) <= SLACK


def q_of(theta: float) -> float:
    return float(driven_angles(CFG, np.array([theta]))[0])


def check_command(mode: str, rest: float, theta: float) -> None:
    drive = Drive(measured=JointMotionState(rest), measured_ns=NOW)
    check_sent(serve_command(CFG, MODES[mode], drive, theta, NOW, ActuationCounters()), q_of(theta))


@pytest.mark.parametrize('theta', END_TARGETS)
@pytest.mark.parametrize('rest', SPREAD_RESTS)
@pytest.mark.parametrize('mode', MODES)
def test_a_command_to_an_end_from_an_edge_or_across_is_served(mode: str, rest: float, theta: float) -> None:
    check_command(mode, rest, theta)


@settings(max_examples=150, deadline=None)
@given(mode=st.sampled_from(list(MODES)), rest=RESTS, theta=st.sampled_from(END_TARGETS))
def test_a_command_to_an_end_from_anywhere_is_served(mode: str, rest: float, theta: float) -> None:
    check_command(mode, rest, theta)


@settings(max_examples=60, deadline=None)
@given(mode=st.sampled_from(list(MODES)), rest=RESTS,
       command=st.one_of(st.floats(THETA_MIN - 0.2, inward(THETA_MIN, -math.inf)),
                         st.floats(inward(THETA_MAX, math.inf), THETA_MAX + 0.2)))
def test_a_command_clamped_onto_an_end_is_served(mode: str, rest: float, command: float) -> None:
    # out_of_limits: clamp: a command past an end is served as that end, and then goes out like any other.
    decision = decide(command, THETA_MIN, THETA_MAX, Policy.CLAMP, CFG.linkage.reach())
    assert decision.outcome is Outcome.CLAMPED and decision.theta in (THETA_MIN, THETA_MAX)
    check_command(mode, rest, decision.theta)


def antenna_message(kind: int, start: float, end: float, duration: float = 12.0) -> SimpleNamespace:
    """A two-point antenna trajectory from ``start`` to ``end`` (rad), at rest at both (kind 1: positions only)."""
    rates = [0.0] if kind >= 3 else []
    points = [Point([theta], rates, [0.0] if kind == 5 else [],
                    time_from_start=Duration(*from_ns(seconds_to_ns(t))))
              for t, theta in ((0.0, start), (duration, end))]
    return SimpleNamespace(header=SimpleNamespace(stamp=Duration()), joint_names=[ANTENNA_JOINT], points=points)


def check_antenna(mode: str, kind: str, start: float, end: float) -> None:
    out = serve_antenna_trajectory(CFG, MODES[mode], Drive(), antenna_message(KINDS[kind], start, end), NOW,
                                   ActuationCounters())
    check_sent(out, q_of(end))


EDGE_STARTS = (THETA_MIN, inward(THETA_MIN, 0.0), 0.0, inward(THETA_MAX, 0.0), THETA_MAX)


@pytest.mark.parametrize('end', END_TARGETS)
@pytest.mark.parametrize('start', EDGE_STARTS)
@pytest.mark.parametrize('kind', KINDS)
@pytest.mark.parametrize('mode', MODES)
def test_an_antenna_trajectory_from_an_edge_to_an_end_is_served(mode: str, kind: str, start: float,
                                                                 end: float) -> None:
    check_antenna(mode, kind, start, end)


@settings(max_examples=150, deadline=None)
@given(mode=st.sampled_from(list(MODES)), kind=st.sampled_from(list(KINDS)),
       start=st.one_of(st.sampled_from(EDGE_STARTS), st.floats(THETA_MIN, THETA_MAX)),
       end=st.sampled_from(END_TARGETS))
def test_an_antenna_trajectory_to_an_end_is_served(mode: str, kind: str, start: float, end: float) -> None:
    check_antenna(mode, kind, start, end)


@settings(max_examples=150, deadline=None)
@given(mode=st.sampled_from(list(MODES)), kind=st.sampled_from(list(KINDS)), rest=RESTS,
       end=st.sampled_from(END_TARGETS))
def test_an_antenna_trajectory_held_at_an_end_is_joined_to_the_measured_drive(mode: str, kind: str, rest: float,
                                                                             end: float) -> None:
    """Its first point 10 s ahead (time enough from anywhere in the range): the connecting segment from the drive
    at rest to a point at an end is served, and passes the range by no more than the slack."""
    msg = antenna_message(KINDS[kind], end, end, 4.0)
    for point in msg.points:
        point.time_from_start = Duration(*from_ns(to_ns(point.time_from_start) + seconds_to_ns(10.0)))
    drive = Drive(measured=JointMotionState(rest), measured_ns=NOW)
    counters = ActuationCounters()
    check_sent(serve_antenna_trajectory(CFG, MODES[mode], drive, msg, NOW, counters), q_of(end))
    assert counters.trajectories_connected == 1


def test_the_request_evaluated_at_its_end_passes_the_range() -> None:
    # The case behind the refusals: the request's own polynomial at s = 1 does not give its end point back (a
    # quintic from 0 to theta_max over 12 s comes out ulps over theta_max); the points count as given.
    start = next(float(x) for x in np.linspace(THETA_MIN, THETA_MAX, 301)
                 if float(_quintic_end(float(x), THETA_MAX)) > THETA_MAX)
    a = antenna_trajectory(CFG, [0.0, 12.0], [start, THETA_MAX], [0.0, 0.0], [0.0, 0.0])
    assert deviation_bounds(CFG, to_driven(CFG, a)).shape == (1,)  # a bound, not UnreachableError


def _quintic_end(start: float, end: float) -> float:
    c = hermite_coefficients(np.array([0.0, 12.0]), np.array([start, end]), np.zeros(2), np.zeros(2))
    return float(evaluate(c, np.array([[1.0]]))[0, 0])


@pytest.mark.parametrize(('end', 'sign'), [(THETA_MAX, 1.0), (THETA_MIN, -1.0)])
def test_a_cubic_past_an_end_inside_its_segment_is_refused(end: float, sign: float) -> None:
    # Both points within the range, the last exactly at an end, reached coming back from beyond it: the request's
    # cubic passes the end between its points (by far more than the slack at its samples) and is refused.
    start, h = end - sign * 1e-4, 1.0
    theta_dot = [0.0, -sign * 2e-3]
    c = hermite_coefficients(np.array([0.0, h]), np.array([start, end]), np.array(theta_dot))
    past = sign * (evaluate(c, np.linspace(0.0, 1.0, SAMPLES + 1)[None, :])[0] - end)
    assert past.max() > 1e3 * range_slack(THETA_MIN, THETA_MAX)
    with pytest.raises(UnreachableError, match=r'^the requested path leaves \[theta_min, theta_max\]') as err:
        convert(CFG, [ANTENNA_JOINT], [Point([start], [theta_dot[0]]),
                                       Point([end], [theta_dot[1]], time_from_start=Duration(1))])
    assert problem_of(err.value) is TrajectoryProblem.OUT_OF_REACH


def one_point(velocity: float) -> DrivenTrajectory:
    q = np.array([0.5 * (LOWER + UPPER)])
    t = np.zeros(1)
    return DrivenTrajectory(t, q, np.array([velocity]), np.zeros(1), np.zeros(1), AntennaTrajectory(t, np.zeros(1)))


def test_a_speed_exactly_at_the_limit_is_within_it_and_the_next_double_is_not() -> None:
    # At the rocker the limit is the double nearest motor / ratio: a value at it passes (at the motor, ratio * it
    # rounds to one ulp over), the next double up does not.
    speed = LIMITS.at_rocker(1)
    for sign in (1.0, -1.0):
        assert worst_violation(one_point(sign * speed), LIMITS, CFG) is None
        over = worst_violation(one_point(sign * inward(speed, math.inf)), LIMITS, CFG)
        assert over is not None and over.quantity == 'motor speed'


@settings(max_examples=80, deadline=None)
@given(rest=st.one_of(st.sampled_from(EDGE_RESTS), st.floats(LOWER, UPPER)), sign=st.sampled_from([1.0, -1.0]),
       theta=st.sampled_from((*END_TARGETS, 0.0)), forward=st.booleans())
def test_a_plan_from_a_start_at_the_speed_limit_is_not_refused_for_it(rest: float, sign: float, theta: float,
                                                                       forward: bool) -> None:
    start = JointMotionState(min(max(rest, LOWER), UPPER), sign * LIMITS.at_rocker(1))
    try:
        plan = plan_command(CFG, start, theta)
    except UnreachableError:
        return  # it cannot stop within the range from there: rightly refused before any point is made
    sampled = planned_setpoints(CFG, plan).positions if forward else planned_points(CFG, plan).positions
    assert sampled.min() >= LOWER - SLACK and sampled.max() <= UPPER + SLACK


def test_a_plan_from_mid_range_at_the_speed_limit_is_served() -> None:
    # Deterministic: from the middle, at the limit towards each end, the drive stops within the range.
    for sign, theta in ((1.0, THETA_MAX), (-1.0, THETA_MIN), (1.0, 0.0), (-1.0, 0.0)):
        plan = plan_command(CFG, JointMotionState(0.5 * (LOWER + UPPER), sign * LIMITS.at_rocker(1)), theta)
        assert planned_points(CFG, plan).velocities is not None
        assert planned_setpoints(CFG, plan).positions.size


@settings(max_examples=100, deadline=None)
@given(where=st.floats(0.0, 1.0), speed=st.floats(-1.0, 1.0), accel=st.floats(-0.9, 0.9),
       target=st.floats(0.0, 1.0))
def test_a_plans_position_range_holds_every_position_it_passes(where: float, speed: float, accel: float,
                                                               target: float) -> None:
    # Against dense sampling (2001 samples): the closed form finds at least as far, and no further than the
    # curvature between samples allows (at an extreme the velocity is 0: a_max dt^2 / 2).
    start = JointMotionState(LOWER + (UPPER - LOWER) * where, speed * LIMITS.at_rocker(1),
                             accel * LIMITS.at_rocker(2))
    plan = plan_motion(start, LOWER + (UPPER - LOWER) * target, LIMITS)
    lo, hi = plan.position_range()
    q = plan.sample(np.linspace(0.0, plan.duration, 2001))[0]
    gap = 0.5 * LIMITS.at_rocker(2) * (plan.duration / 2000) ** 2 + 1e-12
    assert lo <= q.min() <= lo + gap and hi - gap <= q.max() <= hi


def test_a_plan_that_swings_past_the_range_is_refused() -> None:
    # Moving away from the target at the speed limit near the lower end: the drive passes it by 1.1 mrad before it
    # turns (inside a phase of constant acceleration, where ruckig's own extrema say 0.7196 rad).
    start = JointMotionState(0.7265625, -LIMITS.at_rocker(1))
    plan = plan_motion(start, UPPER, LIMITS)
    assert plan.sample(np.linspace(0.0, plan.duration, 2001))[0].min() < LOWER - 1e-3
    with pytest.raises(UnreachableError, match='cannot stop in time'):
        plan_command(CFG, start, THETA_MAX)
