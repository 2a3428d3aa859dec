"""The antenna linkage core: known values, loop closure, statics, inverse, bad input. No ROS here."""

from __future__ import annotations

import math

import numpy as np
import pytest
from support.reference_table import FIRST_ORDER_ROWS
from support.ulp_bounds import CHAIN_ULPS, angle_scale, assert_close_ulps, sine_ratio_scale

from fourbar_ros import (
    AntennaLinkage,
    Branch,
    DeadPointError,
    Driven,
    FourBarError,
    InvalidGeometryError,
    LinkageState,
    SingularPositionError,
    UnreachableError,
)
from fourbar_ros.core.numeric import ArrayLike
from fourbar_ros.core.transforms import antenna_joint_positions

TURNANTENNA = AntennaLinkage(frame=0.180, rocker_ab=0.060, coupler=0.102)

# The 60-digit reference table (test/data/turnantenna_reference.csv): theta, gamma, delta in degrees; the two
# rates dimensionless; upper branch.
KNOWN = FIRST_ORDER_ROWS


# Turnantenna's rockers each have a dead point inside the reach (gamma at +19.3 deg, delta at -19.3 deg);
# statics and the inverse (whose assembly changes there) are checked between them.
WORKING = np.radians(np.linspace(-18.0, 18.0, 37))


def sweep(link: AntennaLinkage, fraction: float = 0.99, n: int = 401) -> np.ndarray:
    r = link.reach()
    if r.theta_gap:
        return np.linspace(r.theta_gap + (1 - fraction) * (r.theta_max - r.theta_gap),
                           r.theta_max * fraction, n)
    return np.linspace(-fraction * r.theta_max, fraction * r.theta_max, n)


@pytest.mark.parametrize(('theta', 'gamma', 'delta', 'dg', 'dd'), KNOWN)
def test_known_values_scalar(theta: float, gamma: float, delta: float, dg: float, dd: float) -> None:
    t = math.radians(theta)
    g, d = TURNANTENNA.rocker_angles(t)
    # Accuracy against the 60-digit table (converting its degrees costs < 1e-15 rad): unchanged strictness.
    assert abs(g - math.radians(gamma)) < 1e-12
    assert abs(d - math.radians(delta)) < 1e-12
    rates = TURNANTENNA.rocker_rates(t)
    assert abs(rates.dgamma_dtheta - dg) < 1e-12
    assert abs(rates.ddelta_dtheta - dd) < 1e-12


def pose_scales(link: AntennaLinkage, theta: ArrayLike, g: ArrayLike, d: ArrayLike) -> tuple[ArrayLike, ArrayLike]:
    """Condition-weighted magnitudes (rad) of gamma and delta at theta: see ulp_bounds.angle_scale."""
    r = link.rates_at(theta, g, d)
    return angle_scale(g, theta, r.dgamma_dtheta), angle_scale(d, theta, r.ddelta_dtheta)


def test_known_values_vectorized_match_scalar_within_ulps() -> None:
    thetas = np.radians([row[0] for row in KNOWN])
    g, d = TURNANTENNA.rocker_angles(thetas)
    scalar = [TURNANTENNA.rocker_angles(float(t)) for t in thetas]
    sg, sd = pose_scales(TURNANTENNA, thetas, g, d)
    # numpy's and libm's sin, cos, arctan2 may differ by 1-2 ulp each (about four in the chain): 8 ulps of the
    # condition-weighted magnitude 1 + |q| + |theta dq/dtheta|.
    assert_close_ulps(g, [p.gamma for p in scalar], CHAIN_ULPS, sg, 'gamma array vs scalar')
    assert_close_ulps(d, [p.delta for p in scalar], CHAIN_ULPS, sd, 'delta array vs scalar')
    assert np.allclose(g, np.radians([row[1] for row in KNOWN]), rtol=0, atol=1e-12)


def test_symmetric_pose_closed_form() -> None:
    # At theta = 0 with equal rockers the trapezoid is symmetric: cos(gamma) = (H - h) / (2 l).
    g, d = TURNANTENNA.rocker_angles(0.0)
    assert g == d
    assert abs(g - math.acos(0.078 / 0.120)) < 4e-16


def test_annex_branch_sum_in_zero_pi_and_lower_branch_mirrors() -> None:
    t = sweep(TURNANTENNA)
    g, d = TURNANTENNA.rocker_angles(t)
    assert np.all((g + d >= 0) & (g + d <= math.pi))
    gl, dl = TURNANTENNA.rocker_angles(t, Branch.LOWER)
    assert np.all(g + d + (gl + dl) < 1e-12)  # the lower branch has gamma + delta = -(upper's)
    # The annex's closed form for equal rockers on its own branch: gamma - delta = 2 atan(P).
    p = 0.102 * np.sin(t) / (0.180 - 0.102 * np.cos(t))
    assert np.allclose(g - d, 2 * np.arctan(p), rtol=0, atol=1e-14)


def test_reach_in_closed_form() -> None:
    r = TURNANTENNA.reach()
    # |AD'| = AB + CD at the limit: H^2 + h^2 - 2 H h cos(theta) = (2 l)^2.
    expected = math.acos((0.180**2 + 0.102**2 - 0.120**2) / (2 * 0.180 * 0.102))
    assert abs(r.theta_max - expected) < 1e-14
    assert r.theta_gap == 0.0
    assert abs(math.degrees(r.theta_max) - 39.33) < 0.01
    assert r.contains(r.theta_max) and r.contains(-r.theta_max)
    assert not r.contains(math.nextafter(r.theta_max, 4.0) + 1e-12)
    assert not r.contains(math.nan) and not r.contains(math.inf)


def test_exact_reach_limit_is_solved_without_nan() -> None:
    r = TURNANTENNA.reach()
    for t in (r.theta_max, -r.theta_max):
        g, d = TURNANTENNA.rocker_angles(t)
        assert math.isfinite(g) and math.isfinite(d)
        assert abs(g + d) < 1e-7  # the rockers are in line (gamma + delta = 0) at the limit
        pos = antenna_joint_positions(0.180, 0.060, 0.102, 0.060, t, g, d)
        assert pos.residual < 1e-15
    arr = TURNANTENNA.rocker_angles(np.array([r.theta_max, -r.theta_max]))
    assert np.all(np.isfinite(arr.gamma))


def test_reach_limit_float_neighbourhood_never_nan_and_reach_agrees() -> None:
    # Every float in a window around the limit: either solved (finite) or rejected, never NaN,
    # and the verdict agrees with reachable() up to rounding of the limit itself.
    rng = np.random.default_rng(7)
    for _ in range(200):
        frame, ab, coupler, cd = rng.uniform(0.05, 2.0, 4)
        try:
            link = AntennaLinkage(frame, ab, coupler, cd)
        except InvalidGeometryError:
            continue
        t = link.reach().theta_max
        for k in range(-3, 4):
            x = t
            for _ in range(abs(k)):
                x = math.nextafter(x, math.inf if k > 0 else -math.inf)
            try:
                g, d = link.rocker_angles(x)
            except UnreachableError:
                assert k > 0
                continue
            assert math.isfinite(g) and math.isfinite(d)


def test_loop_closure_random_geometries_both_branches() -> None:
    rng = np.random.default_rng(2018)
    checked = 0
    for _ in range(300):
        frame, ab, coupler, cd = rng.uniform(0.01, 3.0, 4)
        try:
            link = AntennaLinkage(frame, ab, coupler, cd)
        except InvalidGeometryError:
            continue
        t = sweep(link, 0.999, 101)
        for branch in Branch:
            g, d = link.rocker_angles(t, branch)
            pos = antenna_joint_positions(frame, ab, coupler, cd, t, g, d)
            scale = max(frame, ab, coupler, cd)
            assert np.max(pos.residual) < 1e-14 * scale * 8
            # The link lengths themselves are respected by the chain (B on AB's circle, C on CD's).
            assert np.allclose(np.hypot(*pos.b.T), ab, rtol=1e-14, atol=0)
        checked += 1
    assert checked > 100


def test_branch_continuity_along_sweep() -> None:
    for link in (TURNANTENNA, AntennaLinkage(0.100, 0.040, 0.120), AntennaLinkage(0.3, 0.2, 0.1, 0.25)):
        t = sweep(link, 0.99, 4001)
        g, d = link.rocker_angles(t)
        rates = link.rocker_rates(t)
        step = t[1] - t[0]
        # No jump: each increment is bounded by the largest rate over the step (plus slack for curvature).
        bound = 1.5 * step * np.maximum(np.abs(rates.dgamma_dtheta[1:]), np.abs(rates.dgamma_dtheta[:-1])) + 1e-12
        assert np.all(np.abs(np.diff(g)) <= bound)
        bound_d = 1.5 * step * np.maximum(np.abs(rates.ddelta_dtheta[1:]), np.abs(rates.ddelta_dtheta[:-1])) + 1e-12
        assert np.all(np.abs(np.diff(d)) <= bound_d)


def test_coupler_longer_than_frame_is_continuous_through_zero() -> None:
    # The annex's atan(P) returns the wrong branch by pi here; atan2 with the cut moved away does not.
    link = AntennaLinkage(frame=0.100, rocker_ab=0.040, coupler=0.120)
    t = np.array([-1e-9, 0.0, 1e-9])
    g, d = link.rocker_angles(t)
    assert np.ptp(g) < 1e-7 and np.ptp(d) < 1e-7
    pos = antenna_joint_positions(0.100, 0.040, 0.120, 0.040, t, g, d)
    assert np.max(pos.residual) < 1e-16


def test_rates_match_finite_differences_and_sign() -> None:
    t = sweep(TURNANTENNA, 0.9, 50)
    rates = TURNANTENNA.rocker_rates(t)
    h = 1e-6
    gp, dp = TURNANTENNA.rocker_angles(t + h)
    gm, dm = TURNANTENNA.rocker_angles(t - h)
    assert np.allclose(rates.dgamma_dtheta, (gp - gm) / (2 * h), rtol=1e-8)
    assert np.allclose(rates.ddelta_dtheta, (dp - dm) / (2 * h), rtol=1e-8)
    # Over the tilt range the rockers turn in opposite senses; beyond it a dead point of each rocker lies
    # inside the reach (the rate changes sign), which test_dead_point_* covers.
    tilt = TURNANTENNA.rocker_rates(np.radians(np.linspace(-6, 7, 27)))
    assert np.all(tilt.dgamma_dtheta > 0) and np.all(tilt.ddelta_dtheta < 0)
    assert np.any(rates.dgamma_dtheta < 0) and np.any(rates.ddelta_dtheta > 0)
    v = TURNANTENNA.rocker_velocities(0.05, 0.2)
    r = TURNANTENNA.rocker_rates(0.05)
    assert v.dgamma_dtheta == r.dgamma_dtheta * 0.2


@pytest.mark.parametrize('driven', list(Driven))
def test_power_balance_of_input_torque(driven: Driven) -> None:
    # tau_in * dq = tau_load * dtheta, with dq measured by finite differences of the position solve,
    # independently of the closed-form rates the torque uses.
    load = 3.5
    for t in WORKING:
        tau_in = TURNANTENNA.input_torque(float(t), load, driven)
        h = 1e-6
        q = {Driven.GAMMA: 0, Driven.DELTA: 1}[driven]
        dq = TURNANTENNA.rocker_angles(float(t) + h)[q] - TURNANTENNA.rocker_angles(float(t) - h)[q]
        assert abs(tau_in * dq - load * 2 * h) < 1e-8 * load * 2 * h
        assert math.copysign(1.0, tau_in) == (1.0 if driven is Driven.GAMMA else -1.0)
        ma = TURNANTENNA.mechanical_advantage(float(t), driven)
        assert abs(tau_in * ma - load) < 1e-13 * load


def state_scales(link: AntennaLinkage, st: LinkageState, load: float, driven: Driven) -> dict[str, ArrayLike]:
    """Condition-weighted magnitude of each LinkageState field, for comparing two paths by CHAIN_ULPS ulps.

    gamma, delta: 1 + |q| + |theta dq/dtheta| (ulp_bounds.angle_scale). The rates, the mechanical advantage and
    the input torque are c sin(u)/sin(v) with angle arguments accurate to those scales: sine_ratio_scale, whose
    |cot| factor is the amplification near a dead point (sin(v) -> 0, up to ~10x over WORKING). The transmission
    angle is atan2(|sin x|, -cos x), of condition 1 in x: the scale of x plus its own magnitude.
    """
    t, g, d = (np.asarray(v, dtype=np.float64) for v in (st.theta, st.gamma, st.delta))
    sg, sd = pose_scales(link, t, g, d)
    h, ab, cd = link.coupler, link.rocker_ab, float(link.rocker_cd or 0.0)
    rate_g = sine_ratio_scale(h / ab, d - t, sd, g + d, sg + sd)
    rate_d = sine_ratio_scale(h / cd, g + t, sg, g + d, sg + sd)
    if driven is Driven.GAMMA:  # tau = load AB sin(gamma + delta) / (h sin(delta - theta))
        torque = sine_ratio_scale(abs(load * ab / h), g + d, sg + sd, d - t, sd)
        mu_scale, ma = sd, rate_g
    else:  # tau = -load CD sin(gamma + delta) / (h sin(gamma + theta))
        torque = sine_ratio_scale(abs(load * cd / h), g + d, sg + sd, g + t, sg)
        mu_scale, ma = sg, rate_d
    return {'theta': np.zeros_like(t), 'gamma': sg, 'delta': sd, 'dgamma_dtheta': rate_g, 'ddelta_dtheta': rate_d,
            'mechanical_advantage': ma, 'input_torque': torque,
            'transmission_angle': mu_scale + np.abs(np.asarray(st.transmission_angle))}


def test_state_agrees_with_separate_calls_and_arrays() -> None:
    t = WORKING
    for driven in Driven:
        st = TURNANTENNA.state(t, 3.5, driven)
        scalar = [TURNANTENNA.state(float(ti), 3.5, driven) for ti in t]
        scales = state_scales(TURNANTENNA, st, 3.5, driven)
        for i, name in enumerate(st._fields):
            # Array (numpy) vs scalar (math) path: CHAIN_ULPS ulps of each field's condition-weighted magnitude.
            assert_close_ulps(st[i], [s[i] for s in scalar], CHAIN_ULPS, scales[name], f'{driven} {name}')
        # Same array, same operations in the same order: these are bit for bit.
        assert np.array_equal(st.input_torque, TURNANTENNA.input_torque(t, 3.5, driven))
        assert np.array_equal(st.transmission_angle, TURNANTENNA.transmission_angle(t, driven))


def test_transmission_angle_definition() -> None:
    t = 0.05
    g, d = TURNANTENNA.rocker_angles(t)
    pos = antenna_joint_positions(0.180, 0.060, 0.102, 0.060, t, g, d)
    cb, cd = pos.b - pos.c, pos.d - pos.c
    mu_c = math.acos(float(cb @ cd) / (np.linalg.norm(cb) * np.linalg.norm(cd)))
    assert abs(TURNANTENNA.transmission_angle(t, Driven.GAMMA) - mu_c) < 1e-12
    ba, bc = pos.a - pos.b, pos.c - pos.b
    mu_b = math.acos(float(ba @ bc) / (np.linalg.norm(ba) * np.linalg.norm(bc)))
    assert abs(TURNANTENNA.transmission_angle(t, Driven.DELTA) - mu_b) < 1e-12


def _dead_point(link: AntennaLinkage) -> float:
    """Bisect sin(delta - theta) to the last float: the gamma rocker's dead point."""
    t = sweep(link, 0.999, 2001)
    d = link.rocker_angles(t).delta
    f = np.sin(d - t)
    i = int(np.nonzero(np.sign(f[1:]) != np.sign(f[:-1]))[0][0])
    lo, hi = float(t[i]), float(t[i + 1])

    def fn(x: float) -> float:
        return math.sin(link.rocker_angles(x).delta - x)

    flo = fn(lo)
    while math.nextafter(lo, hi) != hi:
        mid = 0.5 * (lo + hi)
        if mid in (lo, hi):
            break
        if (fn(mid) > 0) == (flo > 0):
            lo = mid
        else:
            hi = mid
    return lo if abs(fn(lo)) < abs(fn(hi)) else hi


def test_dead_point_is_reported_not_inf() -> None:
    link = AntennaLinkage(1.1212789244604622, 1.9108346533866836, 0.45948730289534073, 1.9075690048470388)
    t = _dead_point(link)
    with pytest.raises(DeadPointError, match='dead point for the gamma rocker'):
        link.input_torque(t, 1.0, Driven.GAMMA)
    tau = link.input_torque(np.array([t, 0.0]), 1.0, Driven.GAMMA)
    assert math.isnan(tau[0]) and math.isfinite(tau[1])
    assert abs(link.mechanical_advantage(t, Driven.GAMMA)) < 1e-12  # MA vanishes there
    # Away from it the torque is large but finite and honest.
    assert math.isfinite(link.input_torque(t + 1e-6, 1.0, Driven.GAMMA))


def test_inverse_round_trip_both_rockers() -> None:
    t = WORKING
    g, d = TURNANTENNA.rocker_angles(t)
    th_g, d_back = TURNANTENNA.from_rocker(g, Driven.GAMMA)
    assert np.allclose(th_g, t, rtol=0, atol=1e-13)
    assert np.allclose(d_back, d, rtol=0, atol=1e-13)
    th_d, g_back = TURNANTENNA.from_rocker(d, Driven.DELTA)
    assert np.allclose(th_d, t, rtol=0, atol=1e-13)
    assert np.allclose(g_back, g, rtol=0, atol=1e-13)
    th_s, d_s = TURNANTENNA.from_rocker(float(g[10]))
    assert abs(th_s - t[10]) < 1e-13 and abs(d_s - d[10]) < 1e-13
    # The crossed assembly is another pose with the same gamma; it closes the loop too.
    th_x, d_x = TURNANTENNA.from_rocker(float(g[10]), branch=Branch.LOWER)
    pos = antenna_joint_positions(0.180, 0.060, 0.102, 0.060, th_x, float(g[10]), d_x)
    assert pos.residual < 1e-15 and abs(th_x - t[10]) > 0.1


# ------------------------------------------------------------------------------------------------ bad input

@pytest.mark.parametrize('bad', [math.nan, math.inf, -math.inf, 0.7, -0.7, 10.0])
def test_bad_theta_scalar(bad: float) -> None:
    with pytest.raises(UnreachableError) as exc:
        TURNANTENNA.rocker_angles(bad)
    msg = str(exc.value)
    assert '\n' not in msg and 'reachable: [-0.686404945843 rad' in msg
    assert 'math domain error' not in msg
    for call in (TURNANTENNA.rocker_rates, TURNANTENNA.mechanical_advantage, TURNANTENNA.transmission_angle,
                 TURNANTENNA.state):
        with pytest.raises(UnreachableError):
            call(bad)


def test_bad_theta_array_policies() -> None:
    t = np.array([0.0, math.nan, 0.1, math.inf, 0.9, -0.05])
    with pytest.raises(UnreachableError, match='3 of 6 angles cannot be solved, the first theta=nan'):
        TURNANTENNA.rocker_angles(t)
    g, d = TURNANTENNA.rocker_angles(t, on_invalid='nan')
    ok = TURNANTENNA.reachable(t)
    assert list(ok) == [True, False, True, False, False, True]
    assert np.array_equal(np.isfinite(g), ok) and np.array_equal(np.isfinite(d), ok)
    g_ok, d_ok = TURNANTENNA.rocker_angles(t[ok])
    # The same angles at other places of another array (numpy may round them differently there):
    # CHAIN_ULPS ulps of the condition-weighted magnitude.
    sg, sd = pose_scales(TURNANTENNA, t[ok], g_ok, d_ok)
    assert_close_ulps(g[ok], g_ok, CHAIN_ULPS, sg, 'gamma, valid elements vs alone')
    assert_close_ulps(d[ok], d_ok, CHAIN_ULPS, sd, 'delta, valid elements vs alone')
    st = TURNANTENNA.state(t, 3.5, on_invalid='nan')
    assert np.array_equal(np.isfinite(st.input_torque), ok)


def test_wrapped_angles_are_the_same_pose() -> None:
    g, d = TURNANTENNA.rocker_angles(0.1)
    g2, d2 = TURNANTENNA.rocker_angles(0.1 + 4 * math.pi)
    assert abs(g - g2) < 1e-14 and abs(d - d2) < 1e-14
    assert TURNANTENNA.reach().contains(0.1 - 2 * math.pi)


@pytest.mark.parametrize(('kwargs', 'match'), [
    ({'frame': 0.0, 'rocker_ab': 0.06, 'coupler': 0.1}, 'frame=0.0 m must be finite and positive'),
    ({'frame': -1.0, 'rocker_ab': 0.06, 'coupler': 0.1}, 'frame=-1.0 m must be finite and positive'),
    ({'frame': 0.18, 'rocker_ab': math.nan, 'coupler': 0.1}, 'rocker_ab=nan m'),
    ({'frame': 0.18, 'rocker_ab': 0.06, 'coupler': math.inf}, 'coupler=inf m'),
    ({'frame': 0.18, 'rocker_ab': 0.06, 'coupler': 0.1, 'rocker_cd': -0.06}, 'rocker_cd=-0.06 m'),
    ({'frame': 0.18, 'rocker_ab': True, 'coupler': 0.1}, 'rocker_ab=True must be a number'),
    ({'frame': '0.18', 'rocker_ab': 0.06, 'coupler': 0.1}, "frame='0.18' must be a number"),
    ({'frame': 0.5, 'rocker_ab': 0.06, 'coupler': 0.1}, r'rockers AB \+ CD = 0.12 m cannot span'),
    ({'frame': 0.1, 'rocker_ab': 1.0, 'coupler': 0.1, 'rocker_cd': 0.1}, r'shorter than \|AB - CD\|'),
])
def test_invalid_geometry(kwargs: dict[str, float], match: str) -> None:
    with pytest.raises(InvalidGeometryError, match=match) as exc:
        AntennaLinkage(**kwargs)
    assert '\n' not in str(exc.value)


def test_parallelogram_change_point_is_reported() -> None:
    link = AntennaLinkage(frame=0.1, rocker_ab=0.03, coupler=0.1)
    with pytest.raises(SingularPositionError, match='change point'):
        link.rocker_angles(0.0)
    g, _ = link.rocker_angles(np.array([0.0, 0.2]), on_invalid='nan')
    assert math.isnan(g[0]) and math.isfinite(g[1])
    # Off the change point the parallelogram is solved and closes.
    g1, d1 = link.rocker_angles(0.2)
    assert antenna_joint_positions(0.1, 0.03, 0.1, 0.03, 0.2, g1, d1).residual < 1e-16


def test_rates_at_reach_limit_are_reported() -> None:
    with pytest.raises(SingularPositionError, match='reach limit'):
        TURNANTENNA.rocker_rates(TURNANTENNA.reach().theta_max)
    assert TURNANTENNA.input_torque(TURNANTENNA.reach().theta_max, 3.5) == pytest.approx(0.0, abs=1e-6)


def test_errors_are_value_errors() -> None:
    assert issubclass(FourBarError, ValueError)
    assert issubclass(DeadPointError, SingularPositionError)


def test_gap_geometry_reach() -> None:
    # Rockers differing by more than |frame - coupler| leave a gap around theta = 0.
    link = AntennaLinkage(frame=1.0, rocker_ab=1.0, coupler=0.9, rocker_cd=0.5)
    r = link.reach()
    assert 0 < r.theta_gap < r.theta_max
    with pytest.raises(UnreachableError, match=r'<= \|theta\| <='):
        link.rocker_angles(0.0)
    t = 0.5 * (r.theta_gap + r.theta_max)
    g, d = link.rocker_angles(t)
    assert antenna_joint_positions(1.0, 1.0, 0.9, 0.5, t, g, d).residual < 1e-15


def test_large_arrays_span_blocks_with_the_same_results_and_policies() -> None:
    # Longer than one block of the vectorized solve, in any shape and memory layout.
    t = np.linspace(-0.6, 0.6, 3 * 8192 + 17)
    g, d = TURNANTENNA.rocker_angles(t)
    sg, sd = pose_scales(TURNANTENNA, t, g, d)
    scalar = [TURNANTENNA.rocker_angles(float(x)) for x in t[::97]]
    # Array (numpy) vs scalar (math) path: CHAIN_ULPS ulps of the condition-weighted magnitude.
    assert_close_ulps(g[::97], [p.gamma for p in scalar], CHAIN_ULPS, sg[::97], 'gamma blocks vs scalar')
    assert_close_ulps(d[::97], [p.delta for p in scalar], CHAIN_ULPS, sd[::97], 'delta blocks vs scalar')
    grid = t[:-17].reshape(3, -1)[:, ::2]  # 2-D and non-contiguous
    gg, dd = TURNANTENNA.rocker_angles(grid)
    assert gg.shape == dd.shape == grid.shape
    # The same angles at other places of other blocks: the same bound.
    pick = (slice(None), slice(None, None, 2))
    assert_close_ulps(gg, g[:-17].reshape(3, -1)[pick], CHAIN_ULPS, sg[:-17].reshape(3, -1)[pick], 'gamma 2-D')
    assert_close_ulps(dd, d[:-17].reshape(3, -1)[pick], CHAIN_ULPS, sd[:-17].reshape(3, -1)[pick], 'delta 2-D')
    bad = t.copy()
    bad[[5, 9000, 20000]] = [np.nan, 2.0, -np.inf]
    with pytest.raises(UnreachableError, match=f'3 of {t.size} angles cannot be solved, the first theta=nan'):
        TURNANTENNA.rocker_angles(bad)
    gn, _ = TURNANTENNA.rocker_angles(bad, on_invalid='nan')
    assert list(np.nonzero(np.isnan(gn))[0]) == [5, 9000, 20000]


def test_reachable_is_the_solvers_own_test_at_the_limit_floats() -> None:
    rng = np.random.default_rng(3)
    for _ in range(100):
        frame, ab, coupler, cd = rng.uniform(0.05, 2.0, 4)
        try:
            link = AntennaLinkage(frame, ab, coupler, cd)
        except InvalidGeometryError:
            continue
        t = np.array([link.reach().theta_max])
        floats = [float(t[0])]
        for _ in range(4):
            floats.append(math.nextafter(floats[-1], math.inf))
        arr = np.array(floats + [-f for f in floats])
        g, _ = link.rocker_angles(arr, on_invalid='nan')
        assert np.array_equal(np.isfinite(g), link.reachable(arr))
