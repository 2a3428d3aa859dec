"""Second derivatives d2 gamma/d theta2 and d2 delta/d theta2: the reference table, scalar vs array, the forms that
reuse a solved pose, the reach limit and bad input. No ROS, no mpmath (test_core_precision holds them to the
60-digit reference near and at the limits)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from support.linkages import TURNANTENNA, links
from support.reference_table import FLOAT_ROWS
from support.ulp_bounds import CHAIN_ULPS, angle_scale, assert_close_ulps, second_derivative_scales

from fourbar_ros import AntennaLinkage, Branch, Driven, SingularPositionError, UnreachableError
from fourbar_ros.core.numeric import FloatArray


def scales(link: AntennaLinkage, t: FloatArray, branch: Branch = Branch.UPPER) -> tuple[FloatArray, FloatArray]:
    """ulp_bounds.second_derivative_scales with the angles' condition-weighted magnitudes (angle_scale)."""
    g, d = link.rocker_angles(t, branch)
    r = link.rates_at(t, g, d)
    return second_derivative_scales(link.rocker_ab, float(link.rocker_cd or 0), link.coupler, t, g, d,
                                    angle_scale(g, t, r.dgamma_dtheta), angle_scale(d, t, r.ddelta_dtheta))


def inside(link: AntennaLinkage, n: int = 201, margin: float = 1e-9) -> FloatArray:
    """Angles (rad) across the reach, from relative margin inside either limit."""
    r = link.reach()
    lo = r.theta_gap + margin * (r.theta_max - r.theta_gap)
    mags = np.linspace(lo, r.theta_max * (1 - margin), n)
    return np.concatenate([mags, -mags])


@pytest.mark.parametrize('row', FLOAT_ROWS, ids=lambda r: f'theta={r.theta_deg:g}deg')
def test_reference_table(row: tuple[float, ...]) -> None:
    t = math.radians(row[0])
    want = row[5:7]
    scalar = TURNANTENNA.rocker_second_derivatives(t)
    array = TURNANTENNA.rocker_second_derivatives(np.array([t]))
    for got, w, s in zip(scalar, want, scales(TURNANTENNA, np.array([t])), strict=True):
        # The table's floats are the nearest to 60 digits; CHAIN_ULPS ulps of the condition-weighted scale.
        assert_close_ulps([got], [w], CHAIN_ULPS, s)
    for got, w, s in zip(array, want, scales(TURNANTENNA, np.array([t])), strict=True):
        assert_close_ulps(got, [w], CHAIN_ULPS, s)


@pytest.mark.parametrize('branch', list(Branch))
def test_scalar_and_array_paths_agree_within_the_bound(branch: Branch) -> None:
    for link in links(4, 12):
        t = inside(link)
        array = link.rocker_second_derivatives(t, branch)
        scalar = [link.rocker_second_derivatives(float(ti), branch) for ti in t]
        for i, s in enumerate(scales(link, t, branch)):
            # numpy (SIMD) vs math (libm): CHAIN_ULPS ulps of the scale, which carries the angles' rounding.
            assert_close_ulps(array[i], [v[i] for v in scalar], CHAIN_ULPS, s, f'{link} {branch} field {i}')


def test_finite_differences_of_the_rates() -> None:
    # Independent of the closed form: central differences of the (first-order) rates.
    t = np.radians(np.linspace(-35.0, 35.0, 71))
    step = 1e-6
    plus, minus = TURNANTENNA.rocker_rates(t + step), TURNANTENNA.rocker_rates(t - step)
    second = TURNANTENNA.rocker_second_derivatives(t)
    for i in range(2):
        fd = (plus[i] - minus[i]) / (2 * step)
        assert np.allclose(second[i], fd, rtol=1e-6, atol=1e-6)
    # The tilt range bends both rockers the same way (both second derivatives negative, table and annex alike).
    tilt = TURNANTENNA.rocker_second_derivatives(np.radians(np.linspace(-6.0, 7.0, 27)))
    assert (tilt.d2gamma_dtheta2 < 0).all() and (tilt.d2delta_dtheta2 < 0).all()


def test_forms_that_reuse_a_solved_pose_are_the_same_operations() -> None:
    t = inside(TURNANTENNA, 51)
    g, d = TURNANTENNA.rocker_angles(t)
    rates = TURNANTENNA.rates_at(t, g, d)
    full = TURNANTENNA.rocker_second_derivatives(t)
    for given in (None, rates):
        at = TURNANTENNA.second_derivatives_at(t, g, d, given)
        # Same arrays, same operations in the same order: bit for bit.
        assert np.array_equal(at.d2gamma_dtheta2, full.d2gamma_dtheta2)
        assert np.array_equal(at.d2delta_dtheta2, full.d2delta_dtheta2)
        assert np.array_equal(TURNANTENNA.second_derivative_at(t, g, d, given, Driven.GAMMA), full.d2gamma_dtheta2)
        assert np.array_equal(TURNANTENNA.second_derivative_at(t, g, d, given, Driven.DELTA), full.d2delta_dtheta2)
    ts = float(t[7])
    gs, ds = TURNANTENNA.rocker_angles(ts)
    one = TURNANTENNA.second_derivatives_at(ts, gs, ds, TURNANTENNA.rates_at(ts, gs, ds))
    assert one == TURNANTENNA.rocker_second_derivatives(ts)
    assert TURNANTENNA.second_derivative_at(ts, gs, ds, None, Driven.DELTA) == one.d2delta_dtheta2
    assert isinstance(one.d2gamma_dtheta2, float)


def test_symmetric_pose_and_mirror() -> None:
    # Equal rockers: the mirror image across the frame's bisector maps theta to -theta and gamma to delta, so
    # d2 gamma/d theta2 (theta) = d2 delta/d theta2 (-theta) (a mirror is exact in floats: same operations).
    t = inside(TURNANTENNA, 41)[:41]
    plus, minus = TURNANTENNA.rocker_second_derivatives(t), TURNANTENNA.rocker_second_derivatives(-t)
    s = scales(TURNANTENNA, t)
    assert_close_ulps(plus.d2gamma_dtheta2, minus.d2delta_dtheta2, CHAIN_ULPS, s[0])
    zero = TURNANTENNA.rocker_second_derivatives(0.0)
    assert zero.d2gamma_dtheta2 == zero.d2delta_dtheta2  # gamma == delta there, and the mirrored operations


def test_reach_limit_is_reported_scalar_and_nan_in_arrays() -> None:
    top = TURNANTENNA.reach().theta_max
    g, d = TURNANTENNA.rocker_angles(top)
    assert math.sin(g + d) == 0.0  # the limit's own pose: the rockers in line
    with pytest.raises(SingularPositionError, match='reach limit'):
        TURNANTENNA.rocker_second_derivatives(top)
    with pytest.raises(SingularPositionError, match='reach limit'):  # also with the (unbounded) rates supplied
        TURNANTENNA.second_derivatives_at(top, g, d, TURNANTENNA.rates_at(np.array([0.1]), np.array([g]),
                                                                          np.array([d])))
    t = np.array([-top, 0.1, top])
    ga, da = TURNANTENNA.rocker_angles(t)
    at_limit = np.sin(ga + da) == 0.0  # the array path's own angles (its arctan2 may round differently)
    for v in TURNANTENNA.rocker_second_derivatives(t):
        assert np.array_equal(np.isnan(v), at_limit) and np.isfinite(v[~at_limit]).all()
    # Just inside they are finite and large, growing as 1/sin^3(gamma + delta).
    near = TURNANTENNA.rocker_second_derivatives(top * (1 - 1e-12))
    assert all(math.isfinite(v) and abs(v) > 1e15 for v in near)


def test_bad_input() -> None:
    for bad in (math.nan, math.inf, 0.7):
        with pytest.raises(UnreachableError):
            TURNANTENNA.rocker_second_derivatives(bad)
    with pytest.raises(UnreachableError):
        TURNANTENNA.rocker_second_derivatives(np.array([0.1, math.nan]))
    arr = TURNANTENNA.rocker_second_derivatives(np.array([0.1, math.nan, math.inf, 0.7]), on_invalid='nan')
    for v in arr:
        assert np.isfinite(v[0]) and np.isnan(v[1:]).all()
