"""The motion layer: trajectory conversion, the interpolation-error bound, limits (reject/retime), ruckig planning."""

from __future__ import annotations

import importlib.util
import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from support import ulp_jitter

from fourbar_ros.config.antenna_config import AntennaConfig, config_from_values, default_config
from fourbar_ros.core.errors import UnreachableError
from fourbar_ros.motion.errors import LimitError, TrajectoryError
from fourbar_ros.motion.limits import (
    JointLimits,
    enforce_limits,
    point_magnitudes,
    segment_magnitudes,
    worst_violation,
)
from fourbar_ros.motion.planner import (
    END_SPAN,
    PLAN_SHRINK,
    PLAN_SHRINKS,
    JointMotionState,
    driven_angles,
    plan_motion,
    plan_to_angle,
    setpoints,
    trajectory_points,
)
from fourbar_ros.motion.refine import deviation_bounds, refine
from fourbar_ros.motion.splines import evaluate, hermite_coefficients, segment_extremes
from fourbar_ros.motion.trajectory import AntennaTrajectory, DrivenTrajectory, antenna_trajectory, on_wire, to_driven

CFG = default_config()
DELTA_CFG = config_from_values({'driven_rocker': 'delta'})
LIMITS = JointLimits.from_config(CFG)


def sine(cfg: AntennaConfig, n: int, duration: float, kind: int = 5, cycles: float = 1.0) -> AntennaTrajectory:
    """A sine sweep over most of the tilt range: theta, its exact rate and acceleration as the kind asks."""
    t = np.linspace(0.0, duration, n)
    mid, amp = 0.5 * (cfg.theta_min + cfg.theta_max), 0.45 * (cfg.theta_max - cfg.theta_min)
    w = 2.0 * math.pi * cycles / duration
    return antenna_trajectory(cfg, t, mid + amp * np.sin(w * t), amp * w * np.cos(w * t) if kind > 1 else None,
                              -amp * w * w * np.sin(w * t) if kind > 3 else None)


# ----------------------------------------------------------------------------- conversion

@pytest.mark.parametrize('cfg', [CFG, DELTA_CFG], ids=['gamma', 'delta'])
def test_conversion_is_the_chain_rule_through_the_core(cfg: AntennaConfig) -> None:
    a = sine(cfg, 101, 10.0)
    d = to_driven(cfg, a)
    link = cfg.linkage
    gamma_driven = cfg.driven.value == 'gamma'
    q = link.rocker_angles(a.theta, cfg.branch)
    rates = link.rocker_rates(a.theta, cfg.branch)
    second = link.rocker_second_derivatives(a.theta, cfg.branch)
    q1 = rates.dgamma_dtheta if gamma_driven else rates.ddelta_dtheta
    q2 = second.d2gamma_dtheta2 if gamma_driven else second.d2delta_dtheta2
    assert a.theta_dot is not None and a.theta_ddot is not None
    assert d.velocities is not None and d.accelerations is not None
    # The same core operations on the same values: identical floats.
    np.testing.assert_array_equal(d.positions, q.gamma if gamma_driven else q.delta)
    np.testing.assert_array_equal(d.velocities, q1 * a.theta_dot)
    # The second derivative of both rockers (the reference here) and of the driven one only (the conversion) may
    # round differently by a few ulps of each term: within 8 ulps of the terms' magnitudes.
    terms = np.abs(q2 * a.theta_dot ** 2) + np.abs(q1 * a.theta_ddot)
    assert np.all(np.abs(d.accelerations - (q2 * a.theta_dot ** 2 + q1 * a.theta_ddot))
                  <= 8 * np.finfo(float).eps * terms)
    # Effort by power balance (load / q') against the core's torque_at (load AB sin X / (h sin u)): two roundings
    # of three factors each, so within 8 ulps relative.
    core = np.asarray(link.torque_at(a.theta, q.gamma, q.delta, cfg.load_torque, cfg.driven))
    np.testing.assert_allclose(d.efforts, core, rtol=8 * np.finfo(float).eps, atol=0)
    assert np.all(d.efforts * q1 * a.theta_dot == pytest.approx(cfg.load_torque * a.theta_dot, rel=1e-14))


def test_conversion_keeps_the_fields_given() -> None:
    for kind, fields in ((1, (False, False)), (3, (True, False)), (5, (True, True))):
        d = to_driven(CFG, sine(CFG, 11, 1.0, kind))
        assert (d.velocities is not None, d.accelerations is not None) == fields
        assert int(d.kind) == kind


def test_gravity_load_effort_matches_the_scalar_load_model() -> None:
    from fourbar_ros.core.loads import solve
    cfg = config_from_values({'antenna_mass': 2.0, 'com_offset_along': 0.01})
    d = to_driven(cfg, sine(cfg, 7, 1.0))
    expected = [float(solve(cfg, float(t)).input_torque) for t in d.antenna.theta]
    np.testing.assert_allclose(d.efforts, expected, rtol=16 * np.finfo(float).eps)


@pytest.mark.parametrize(('args', 'kind', 'match'), [
    (([], []), TrajectoryError, '^empty trajectory'),
    (([0.0, 1.0], [0.0]), TrajectoryError, r'^theta: 1 values for 2 points'),
    (([0.0, 1.0], [0.0, math.nan]), TrajectoryError, r'^theta\[1\] = nan is not finite'),
    (([0.0, 1.0, 1.0], [0.0, 0.0, 0.0]), TrajectoryError, r'^time not increasing at point 2'),
    (([-1.0, 1.0], [0.0, 0.0]), TrajectoryError, 'negative'),
    (([0.0, 1.0], [0.0, 0.5]), UnreachableError, r'^point 1 \(t = 1.0 s\): theta = 0.5 rad'),
    (([0.0, 1.0], [0.0, 0.0], None, [0.0, 0.0]), TrajectoryError, r'^accelerations without velocities'),
])
def test_bad_trajectories_raise_one_line(args: tuple[object, ...], kind: type[Exception], match: str) -> None:
    with pytest.raises(kind, match=match) as info:
        antenna_trajectory(CFG, *args)
    assert '\n' not in str(info.value)


def test_too_many_points_are_refused() -> None:
    cfg = config_from_values({'max_trajectory_points': 10})
    with pytest.raises(TrajectoryError, match=r'^11 points exceed max_trajectory_points = 10'):
        antenna_trajectory(cfg, np.arange(11.0), np.zeros(11))


# ----------------------------------------------------------------------------- interpolation error

def dense_deviation(cfg: AntennaConfig, d: DrivenTrajectory, samples: int = 1024) -> float:
    """Largest |Theta(Q(s)) - T(s)| (rad) on a dense sample of every segment: an independent look at the bound."""
    s = np.linspace(0.0, 1.0, samples + 1)[None, :]
    q = evaluate(hermite_coefficients(d.times, d.positions, d.velocities, d.accelerations), s)
    a = d.antenna
    t = evaluate(hermite_coefficients(a.times, a.theta, a.theta_dot, a.theta_ddot), s)
    theta, _ = cfg.linkage.from_rocker(q, cfg.driven, cfg.measured_branch)
    return float(np.max(np.abs(np.asarray(theta) - t)))


#: The deviation is computed from two rounded angles near 0.1 rad (from_rocker's and the spline's, each a few
#: ulps): 1e-15 rad covers that rounding.
ROUNDING = 1e-15


@settings(max_examples=25, deadline=None, derandomize=True)
@given(kind=st.sampled_from([1, 3, 5]), n=st.integers(2, 8), duration=st.floats(0.5, 30.0),
       cycles=st.floats(0.1, 2.0), tol_exp=st.floats(-7.0, -3.0), delta=st.booleans())
def test_refined_trajectories_stay_within_the_tolerance(kind: int, n: int, duration: float, cycles: float,
                                                         tol_exp: float, delta: bool) -> None:
    # At least 4 points per cycle: sparser, the request's own interpolation overshoots the sine's 5% margin to
    # [theta_min, theta_max], and refine rightly refuses it (tested below).
    assume(n - 1 >= 4 * cycles)
    cfg = config_from_values({'trajectory_tolerance': 10.0 ** tol_exp, 'driven_rocker': 'delta' if delta else
                              'gamma', 'max_trajectory_points': 100000})
    d = to_driven(cfg, sine(cfg, n, duration, kind, cycles))
    r = refine(cfg, d)
    assert r.bound <= cfg.trajectory_tolerance
    assert dense_deviation(cfg, r.trajectory) <= cfg.trajectory_tolerance + ROUNDING
    assert r.inserted == len(r.trajectory) - n
    # The request is unchanged: the original points are still there and the inserted ones lie on its path.
    assert np.isin(d.times, r.trajectory.times).all()


def test_a_request_whose_own_path_leaves_the_range_is_refused() -> None:
    # Two points at mid-range, two cycles of the sine apart, with the sine's velocities: the request's cubic
    # between them swings beyond the tilt range although both points lie within it.
    a = sine(CFG, 2, 1.0, kind=3, cycles=2.0)
    with pytest.raises(UnreachableError, match=r'^the requested path leaves \[theta_min, theta_max\] = .* between '
                       r'points 0 and 1 \(t = 0.0 .. 1.0 s\)$'):
        refine(CFG, to_driven(CFG, a))


def test_unrefined_trajectories_do_exceed_the_tolerance() -> None:
    """The property above is not vacuous: the controller's interpolation of the raw conversion leaves the path."""
    cfg = config_from_values({'trajectory_tolerance': 1e-6})
    for kind in (1, 3, 5):
        d = to_driven(cfg, sine(cfg, 5, 10.0, kind))
        assert dense_deviation(cfg, d) > cfg.trajectory_tolerance
        assert np.max(deviation_bounds(cfg, d)) >= dense_deviation(cfg, d)


def test_refinement_is_bounded_by_max_points() -> None:
    cfg = config_from_values({'trajectory_tolerance': 1e-9, 'max_trajectory_points': 20})
    with pytest.raises(TrajectoryError, match='refining needs more than max_trajectory_points = 20'):
        refine(cfg, to_driven(cfg, sine(cfg, 4, 10.0, 1)))


# ----------------------------------------------------------------------------- limits

def fast(kind: int = 5) -> DrivenTrajectory:
    """A sweep of the tilt range in 0.5 s: far over the motor's speed, acceleration and jerk."""
    return to_driven(CFG, sine(CFG, 41, 0.5, kind))


def test_reject_names_the_worst_point() -> None:
    with pytest.raises(LimitError, match=r'^segment from point \d+ \(t = [0-9.e-]+ s\): motor \w+ [0-9.e+]+ '
                                         r'rad/s\S* exceeds its limit [0-9.e+]+ rad/s\S* by [0-9.e+]+ rad/s\S* '
                                         r'\([0-9.e+]+%\)$'):
        enforce_limits(fast(), LIMITS, CFG, 'reject')


@pytest.mark.parametrize('kind', [1, 3, 5])
def test_retime_brings_every_point_within_the_limits(kind: int) -> None:
    d = fast(kind)
    assert worst_violation(d, LIMITS, CFG) is not None
    out = enforce_limits(d, LIMITS, CFG, 'retime')
    assert worst_violation(out, LIMITS, CFG) is None
    # Checked directly too: every point's own velocity and acceleration, and the controller's one-sided values.
    n = LIMITS.ratio
    if out.velocities is not None:
        assert np.all(n * np.abs(out.velocities) <= LIMITS.motor_speed)
    if out.accelerations is not None:
        assert np.all(n * np.abs(out.accelerations) <= LIMITS.motor_acceleration)
    for order, values in point_magnitudes(out).items():
        assert np.all(n * values <= LIMITS.motor(order))
    # The smallest factor: some limit is reached to within the retiming's rounding and that of the times to whole
    # nanoseconds (on_wire: 0.5 ns on a segment h moves an order-k derivative by up to k * 0.5 ns / h, k <= 3).
    ratios = [float(np.max(n * v)) / LIMITS.motor(o) for o, v in segment_magnitudes(out).items()]
    assert max(ratios) <= 1.0  # over each whole segment, not only at the points
    assert max(ratios) > 1.0 - 1e-9 - 3 * 0.5e-9 / float(np.min(np.diff(out.times)))
    np.testing.assert_array_equal(out.positions, d.positions)
    np.testing.assert_array_equal(out.efforts, d.efforts)


def test_torque_over_its_limit_is_rejected_under_both_policies() -> None:
    cfg = config_from_values({'motor_torque_limit': 0.001})
    d = to_driven(cfg, sine(cfg, 11, 100.0))
    for policy in ('reject', 'retime'):
        with pytest.raises(LimitError, match=r'motor torque .* a static torque does not depend on timing$'):
            enforce_limits(d, JointLimits.from_config(cfg), cfg, policy)  # type: ignore[arg-type]


def test_a_slow_trajectory_passes_unchanged() -> None:
    d = to_driven(CFG, sine(CFG, 41, 200.0))
    assert enforce_limits(d, LIMITS, CFG, 'reject') is d


# ----------------------------------------------------------------------------- planning

#: ruckig has no rosdep key (pip only, docs/how-to/ros2-control.md): the planning tests skip where it is missing.
needs_ruckig = pytest.mark.skipif(importlib.util.find_spec('ruckig') is None, reason='ruckig not installed (pip only)')
Q_MIN, Q_MAX = (float(v) for v in driven_angles(CFG, np.array([CFG.theta_min, CFG.theta_max])))


@needs_ruckig
def test_plan_reaches_the_target_within_the_limits() -> None:
    plan = plan_to_angle(CFG, LIMITS, JointMotionState(Q_MIN), CFG.theta_max)
    end = plan.state_at(plan.duration)
    assert end.position == pytest.approx(Q_MAX, abs=1e-12) and end.velocity == pytest.approx(0.0, abs=1e-12)
    points = trajectory_points(CFG, LIMITS, plan, 0.05)
    assert worst_violation(points, LIMITS, CFG) is None
    assert points.times[0] == 0.0 and points.times[-1] == on_wire(np.array([plan.duration]))[0]  # whole ns
    assert np.all(np.diff(points.times) >= 0.025)
    theta = np.asarray(points.antenna.theta)
    assert theta[0] == pytest.approx(CFG.theta_min, abs=1e-12) and theta[-1] == pytest.approx(CFG.theta_max, abs=1e-12)
    stream = setpoints(CFG, plan)
    assert np.allclose(np.diff(stream.times)[:-1], 1.0 / CFG.control_rate)
    assert stream.positions[-1] == pytest.approx(Q_MAX, abs=1e-12)
    assert np.all(LIMITS.ratio * np.abs(np.diff(stream.positions) / np.diff(stream.times)) <= LIMITS.motor_speed)


@needs_ruckig
@pytest.mark.parametrize('at', [0.3, 1.0, 2.5])
def test_replanning_mid_motion_has_no_jump(at: float) -> None:
    first = plan_to_angle(CFG, LIMITS, JointMotionState(Q_MIN), CFG.theta_max)
    state = first.state_at(at)
    second = plan_to_angle(CFG, LIMITS, state, 0.0)
    start = second.state_at(0.0)
    # ruckig starts from the state it is given: position, velocity and acceleration continue exactly (up to its
    # evaluation at t = 0, a few ulps).
    assert start.position == pytest.approx(state.position, abs=1e-15)
    assert start.velocity == pytest.approx(state.velocity, abs=1e-18)
    assert start.acceleration == pytest.approx(state.acceleration, abs=1e-17)
    # ... and stay continuous just after the switch: bounded by the jerk limit over a short time.
    dt = 1e-4
    after = second.state_at(dt)
    j = LIMITS.at_rocker(3)
    assert abs(after.acceleration - state.acceleration) <= j * dt * (1 + 1e-9)
    assert abs(after.velocity - state.velocity) <= (abs(state.acceleration) + j * dt) * dt * (1 + 1e-9)
    points = trajectory_points(CFG, LIMITS, second, 0.05)
    assert worst_violation(points, LIMITS, CFG) is None


@needs_ruckig
def test_plans_that_cannot_stop_within_the_range_are_refused() -> None:
    fast_start = JointMotionState(Q_MAX - 1e-3, 0.9 * LIMITS.at_rocker(1))
    with pytest.raises(UnreachableError, match='cannot stop in time'):
        plan_to_angle(CFG, LIMITS, fast_start, CFG.theta_max)


@needs_ruckig
def test_planner_bad_input() -> None:
    with pytest.raises(TrajectoryError, match=r'^non-finite motion input'):
        plan_motion(JointMotionState(math.nan), 0.8, LIMITS)
    with pytest.raises(UnreachableError, match='outside'):
        plan_to_angle(CFG, LIMITS, JointMotionState(Q_MIN), 0.5)
    plan = plan_motion(JointMotionState(Q_MIN), Q_MAX, LIMITS)
    with pytest.raises(TrajectoryError, match='max_trajectory_points'):
        trajectory_points(CFG, LIMITS, plan, 1e-5)
    with pytest.raises(TrajectoryError, match='positive'):
        trajectory_points(CFG, LIMITS, plan, 0.0)


def _replan_starts(grid: int, randoms: int) -> list[tuple[JointMotionState, float]]:
    """(start state, the running plan's target theta rad) along running plans: ``grid`` evenly spaced, the phase
    boundaries (a few ns either side, and 0.05 to 0.6 ms before: the replan's first phase is then shorter than
    ``min_segment`` or a point spacing), the phase at maximum acceleration and the end at rest; then ``randoms``
    states of seeded random plans between random angles at random times."""
    starts = []
    for q0, target in ((Q_MIN, CFG.theta_max), (Q_MAX, 0.0)):
        plan = plan_to_angle(CFG, LIMITS, JointMotionState(q0), target)
        switches = plan.switch_times()
        before = (switches[:, None] - 1e-3 * np.array([0.05, 0.15, 0.25, 0.35, 0.45, 0.6])[None, :]).ravel()
        times = np.concatenate([np.linspace(0.0, plan.duration, grid), switches, switches - 3e-9, switches + 3e-9,
                                before, np.linspace(switches[0], switches[1], 23), [plan.duration]])
        starts += [(plan.state_at(float(t)), target) for t in times]
    rng = np.random.default_rng(7)
    for theta0, target, share in zip(rng.uniform(CFG.theta_min, CFG.theta_max, randoms),
                                     rng.uniform(CFG.theta_min, CFG.theta_max, randoms), rng.uniform(size=randoms),
                                     strict=True):
        plan = plan_to_angle(CFG, LIMITS, JointMotionState(float(driven_angles(CFG, np.array([theta0]))[0])), target)
        starts.append((plan.state_at(share * plan.duration), float(target)))
    return starts


TARGETS_100HZ = (CFG.theta_min, -0.05, 0.0, 0.03, CFG.theta_max)


@needs_ruckig
@pytest.mark.parametrize(('rate', 'grid', 'randoms', 'targets'), [
    pytest.param(100.0, 101, 30, TARGETS_100HZ, id='100Hz'),
    pytest.param(1000.0, 11, 20, (CFG.theta_min, CFG.theta_max), id='1kHz'),  # 10 times the points per plan
    # The same with a finer grid and more random plans (make test-stress).
    pytest.param(100.0, 301, 100, TARGETS_100HZ, id='100Hz-dense', marks=pytest.mark.stress),
    pytest.param(1000.0, 31, 60, (CFG.theta_min, CFG.theta_max), id='1kHz-dense', marks=pytest.mark.stress),
])
def test_a_replan_from_any_state_of_a_running_plan_is_never_refused_for_its_limits(
        rate: float, grid: int, randoms: int, targets: tuple[float, ...]) -> None:
    # A jerk-limited plan starts at the state it is given and stays within the limits: its points must be too,
    # wherever the replan starts: mid-phase, a few ns or a fraction of a ms before a phase boundary (a first phase
    # shorter than min_segment, whose boundary is not a point), at maximum acceleration, at rest on the target itself,
    # at the default control rate and at 1 kHz (segments of about 1 ms, as short as a left-out phase is long).
    starts = _replan_starts(grid, randoms)
    assert max(abs(s.acceleration) for s, _ in starts) >= PLAN_SHRINKS[1] * LIMITS.at_rocker(2) * (1 - 1e-9)
    refused = []
    for start, running_target in starts:
        for theta in (*targets, running_target):
            try:
                plan = plan_to_angle(CFG, LIMITS, start, theta)
            except UnreachableError:
                continue  # cannot stop within the range: refused before any point, rightly
            try:
                points = trajectory_points(CFG, LIMITS, plan, 1.0 / rate)
            except LimitError as exc:
                refused.append(f'{start} -> {theta!r}: {exc}')
                continue
            assert points.positions[0] == start.position
            # The phase boundaries inside a segment (not a point, 1 ns: the times on the wire) lie all in its first or
            # all in its last END_SPAN, where they cannot move the quintic's jerk at its ends beyond the profile's.
            t, sw = points.times, plan.switch_times()
            i = np.searchsorted(t, sw)
            off = np.minimum(np.abs(t[np.minimum(i, t.size - 1)] - sw), np.abs(t[i - 1] - sw)) > 1e-9
            for k in np.unique(i[off]):
                inside, h = sw[off & (i == k)], t[k] - t[k - 1]
                assert (inside.max() - t[k - 1] <= END_SPAN * h + 1e-9
                        or t[k] - inside.min() <= END_SPAN * h + 1e-9), (start, theta, inside, t[k - 1], t[k])
    assert not refused, f'{len(refused)} refused, e.g. {refused[:3]}'


@pytest.mark.parametrize('direction', ulp_jitter.DIRECTIONS)
@pytest.mark.parametrize('seed', [0, 1, 2])
def test_a_motion_to_either_end_of_the_range_is_never_refused_for_rounding(seed: int, direction: str) -> None:
    # As on another CPU (every transcendental result of numpy and math one ulp off, by seed and direction): the
    # range's ends and the target are one evaluation, and ruckig's extrema may pass an end by its own rounding.
    cfg = default_config()
    limits = JointLimits.from_config(cfg)
    with ulp_jitter.jittered(1.0, seed, direction=direction, math_names=tuple(ulp_jitter.MATH_FUNCS)):
        ends = driven_angles(cfg, np.array([cfg.theta_min, cfg.theta_max]))
        for start in np.linspace(float(ends.min()), float(ends.max()), 7):
            for theta in (cfg.theta_min, cfg.theta_max):
                plan = plan_to_angle(cfg, limits, JointMotionState(float(start)), theta)
                assert plan.duration >= 0.0



@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**32 - 1), st.sampled_from([1, 3, 5]))
def test_segment_extremes_are_the_closed_form_maxima(seed: int, degree: int) -> None:
    # Against dense sampling (20001 samples a segment): sampling can only find less, and the closed form finds at
    # most the sampled maximum plus what lies between samples (|next derivative| * (1/20000) / 2 per segment,
    # bounded here by the next order's own extreme).
    rng = np.random.default_rng(seed)
    n = 50
    t = np.cumsum(rng.uniform(0.01, 0.5, n + 1))
    p, v, a = rng.normal(size=(3, n + 1))
    c = hermite_coefficients(t, p, None if degree == 1 else v, a if degree == 5 else None)
    s = np.linspace(0.0, 1.0, 20001)[None, :]
    h = np.diff(t)
    for order in (1, 2, 3):
        got = segment_extremes(t, c, order)
        d = c
        for _ in range(order):
            d = d[:, 1:] * np.arange(1, d.shape[1], dtype=np.float64)
        sampled = (np.abs(evaluate(d, s)).max(axis=1) if d.shape[1] else np.zeros(n)) / h ** order
        slack = 0.5 / 20000 * segment_extremes(t, c, order + 1) * h if order < degree else 0.0 * h
        assert np.all(got >= sampled * (1 - 1e-12)), order
        assert np.all(got <= sampled + slack + 1e-12 * (1 + sampled)), order


def cubic_overshoot(scale: float) -> DrivenTrajectory:
    """14 points over 3.13 s, rest to rest, whose points' velocities are at most 0.999 of the rocker's speed limit
    (times ``scale``) while the cubic segments between them reach more: each inner segment rises at the limit on
    average (dp / h = the limit), which a cubic with end velocities below it can only do by passing it."""
    vmax = LIMITS.at_rocker(1) * scale
    t = np.linspace(0.0, 3.13, 14)
    h = float(t[1] - t[0])
    v = np.full(14, 0.999 * vmax)
    v[0] = v[-1] = 0.0
    steps = np.full(13, vmax * h)
    steps[0] = steps[-1] = 0.5 * 0.999 * vmax * h  # the end segments accelerate from and to rest
    q = 0.75 + np.concatenate([[0.0], np.cumsum(steps)])
    return DrivenTrajectory(t, q, v, None, np.zeros(14), AntennaTrajectory(t, np.zeros(14)))


def test_limits_hold_between_the_points_not_only_at_them() -> None:
    d = cubic_overshoot(1.0)
    n = LIMITS.ratio
    assert float(np.max(n * np.abs(d.velocities))) <= 0.999 * LIMITS.motor_speed * (1 + 1e-12)  # each point
    assert all(float(np.max(n * m)) <= LIMITS.motor(o) for o, m in point_magnitudes(d).items() if o == 1)
    peak = float(np.max(n * segment_magnitudes(d)[1])) / LIMITS.motor_speed
    assert peak > 1.0  # the controller's cubic passes the limit between points (1.0005 here)
    with pytest.raises(LimitError, match=r'^segment from point '):  # the worst: its acceleration, here
        enforce_limits(d, LIMITS, CFG, 'reject')
    out = enforce_limits(d, LIMITS, CFG, 'retime')
    assert float(np.max(n * segment_magnitudes(out)[1])) <= LIMITS.motor_speed
    assert worst_violation(out, LIMITS, CFG) is None


def test_a_converted_antenna_trajectory_is_held_between_its_points() -> None:
    # The same motion asked as an antenna trajectory with velocities (theta_dot = q_dot / q'): convert refuses it
    # under reject, and under retime sends one whose interpolated speed stays within the limit everywhere.
    d = cubic_overshoot(1.0)
    theta, _ = CFG.linkage.from_rocker(d.positions, CFG.driven, CFG.measured_branch)
    theta = np.asarray(theta)
    g, dl = CFG.linkage.rocker_angles(theta, CFG.branch)
    q1 = np.asarray(CFG.linkage.rates_at(theta, g, dl).dgamma_dtheta)
    request = antenna_trajectory(CFG, d.times, theta, d.velocities / q1)
    driven = to_driven(CFG, request)
    assert float(np.max(LIMITS.ratio * np.abs(driven.velocities))) <= 0.9991 * LIMITS.motor_speed
    with pytest.raises(LimitError, match='segment from point'):
        enforce_limits(refine(CFG, driven).trajectory, LIMITS, CFG, 'reject')
    retimed = enforce_limits(refine(CFG, driven).trajectory, LIMITS, CFG, 'retime')
    for order, m in segment_magnitudes(retimed).items():
        assert float(np.max(LIMITS.ratio * m)) <= LIMITS.motor(order), order


MEASURED_STARTS = (st.floats(0.0, 1.0), st.floats(-1.0, 1.0), st.sampled_from([0.01, 0.001]))


@settings(max_examples=60, deadline=None)
@given(*MEASURED_STARTS)
def test_a_plan_from_a_measured_state_is_never_refused_for_its_interpolation(
        where: float, speed: float, spacing: float) -> None:
    check_a_plan_from_a_measured_state(where, speed, spacing)


@pytest.mark.stress
@settings(max_examples=1000, deadline=None)
@given(*MEASURED_STARTS)
def test_a_plan_from_a_measured_state_is_never_refused_for_its_interpolation_many(
        where: float, speed: float, spacing: float) -> None:
    check_a_plan_from_a_measured_state(where, speed, spacing)


def check_a_plan_from_a_measured_state(where: float, speed: float, spacing: float) -> None:
    # A plan from a moving state (position and velocity up to the planner's speed, acceleration 0): the
    # controller's quintics through the profile must stay within the limits between the points too (a segment over
    # them is split at its phase boundaries).
    cfg = default_config()
    ends = driven_angles(cfg, np.array([cfg.theta_min, cfg.theta_max]))
    lo, hi = float(ends.min()), float(ends.max())
    start = JointMotionState(lo + (hi - lo) * where, speed * PLAN_SHRINK * LIMITS.at_rocker(1))
    for theta in (cfg.theta_min, 0.5 * (cfg.theta_min + cfg.theta_max), cfg.theta_max):
        try:
            plan = plan_to_angle(cfg, LIMITS, start, theta)
        except UnreachableError:
            continue  # it cannot stop within the range from this state: refused before any point is made
        out = trajectory_points(cfg, LIMITS, plan, spacing)
        for order, m in segment_magnitudes(out).items():
            assert float(np.max(LIMITS.ratio * m)) <= LIMITS.motor(order), (order, start, theta)


@pytest.mark.parametrize('seed', [0, 1, 2])
def test_a_chain_of_replans_every_control_period_is_never_refused(seed: int) -> None:
    # As the node replans when commands come faster than motions end (the demo's sweep: every 26.4 ms): each plan
    # from the running one's state at the next command; every one sampled and checked, between its points too.
    cfg = default_config()
    rng = np.random.default_rng(seed)
    ends = driven_angles(cfg, np.array([cfg.theta_min, cfg.theta_max]))
    state = JointMotionState(float(ends.mean()))
    for _ in range(300):
        theta = float(rng.uniform(cfg.theta_min, cfg.theta_max))
        try:
            plan = plan_to_angle(cfg, LIMITS, state, theta)
        except UnreachableError:
            continue
        out = trajectory_points(cfg, LIMITS, plan, 0.01)
        for order, m in segment_magnitudes(out).items():
            assert float(np.max(LIMITS.ratio * m)) <= LIMITS.motor(order), order
        state = plan.state_at(float(rng.uniform(0.005, 0.05)))
