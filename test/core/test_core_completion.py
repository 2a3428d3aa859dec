"""Completing the linkage from a measured driven rocker: round trips against the forward solve within the ulp
bound (also at the driven rocker's reach limit), rates against differences of the inverse, power balance, the
rocker's range, what is computed, and bad input. No ROS."""

from __future__ import annotations

import math

import numpy as np
import pytest
from support.linkages import TURNANTENNA, links
from support.ulp_bounds import CHAIN_ULPS, EPS, assert_close_ulps

from fourbar_ros import AntennaLinkage, Branch, DeadPointError, Driven, UnreachableError
from fourbar_ros.core.completion import complete
from fourbar_ros.core.numeric import FloatArray


def rocker_angles(link: AntennaLinkage, driven: Driven) -> FloatArray:
    """Angles (rad) across the rocker's range, down to 1e-15 of it from either end, both signs."""
    r = link.rocker_reach(driven)
    fractions = np.concatenate([np.linspace(0.0, 1.0, 41), 1 - 10.0 ** -np.arange(1, 16), 10.0 ** -np.arange(1, 16)])
    mags = np.clip(r.theta_gap + fractions * (r.theta_max - r.theta_gap), r.theta_gap, r.theta_max)
    return np.concatenate([mags, -mags])


@pytest.mark.parametrize('driven', list(Driven))
@pytest.mark.parametrize('branch', list(Branch))
def test_round_trip_through_the_forward_solve(driven: Driven, branch: Branch) -> None:
    for link in links(1, 10):
        q = rocker_angles(link, driven)
        c = complete(link, q, driven, branch, on_invalid='nan')
        ok = np.isfinite(c.theta)  # change points (a rocker as long as the frame, q = 0) are undetermined
        q, theta, other = q[ok], c.theta[ok], c.other[ok]
        g, d = (q, other) if driven is Driven.GAMMA else (other, q)
        forward_branch = np.where(np.sin(g + d) >= 0.0, 1.0, -1.0)
        back = np.empty((2, q.size))
        for b in Branch:
            sel = forward_branch == b.value
            back[0, sel], back[1, sel] = link.rocker_angles(theta[sel], b)
        q_back, other_back = (back[0], back[1]) if driven is Driven.GAMMA else (back[1], back[0])
        rates = link.rates_at(theta, back[0], back[1])  # back holds (gamma, delta)
        dq, dother = (rates[0], rates[1]) if driven is Driven.GAMMA else (rates[1], rates[0])
        # theta solved from q is accurate to n ulps of pi + |theta| + |q dtheta/dq| (pi: from_rocker wraps to
        # [-pi, pi], an addition of pi); the forward solve carries that by dq/dtheta and adds its own n ulps of
        # 1 + |q| + |theta dq/dtheta| (ulp_bounds.angle_scale).
        with np.errstate(divide='ignore', invalid='ignore'):  # inf where dq/dtheta = 0 (a dead point), masked
            theta_scale = math.pi + np.abs(theta) + np.abs(q / dq)
            q_scale = np.abs(dq) * theta_scale + 1 + np.abs(q) + np.abs(theta * dq)
            other_scale = (np.abs(dother) * theta_scale + math.pi + 1 + 2 * np.abs(other) + np.abs(theta * dother)
                           + np.abs(q * np.divide(dother, dq)))
        q_scale[~np.isfinite(q_scale)] = 1 / math.sqrt(EPS)  # the antenna's own reach limit (see test_core_precision)
        assert_close_ulps(np.remainder(q_back - q + math.pi, 2 * math.pi) - math.pi, np.zeros_like(q), CHAIN_ULPS,
                          q_scale, f'{link} {driven} {branch} q')
        other_scale[~np.isfinite(other_scale)] = 1 / math.sqrt(EPS)
        assert_close_ulps(np.remainder(other_back - other + math.pi, 2 * math.pi) - math.pi, np.zeros_like(q),
                          CHAIN_ULPS, other_scale, f'{link} {driven} {branch} other')
        assert np.array_equal(c.coupler_joint[ok], (q if driven is Driven.GAMMA else other) + theta)


@pytest.mark.parametrize('driven', list(Driven))
def test_rates_are_the_chain_rule_and_match_differences_of_the_inverse(driven: Driven) -> None:
    r = TURNANTENNA.rocker_reach(driven)
    q = np.linspace(-0.95, 0.95, 39) * r.theta_max
    q_dot = 0.37  # rad/s
    c = complete(TURNANTENNA, q, driven, Branch.UPPER, q_rate=q_dot)
    step = 1e-6
    plus = TURNANTENNA.from_rocker(q + step, driven)
    minus = TURNANTENNA.from_rocker(q - step, driven)
    assert np.allclose(c.theta_rate, q_dot * (plus.theta - minus.theta) / (2 * step), rtol=1e-7, atol=1e-9)
    assert np.allclose(c.other_rate, q_dot * (plus.other - minus.other) / (2 * step), rtol=1e-7, atol=1e-9)
    g_rate = q_dot if driven is Driven.GAMMA else c.other_rate
    assert np.array_equal(c.coupler_joint_rate, g_rate + c.theta_rate)
    assert c.load_torque is None  # no effort: no statics


@pytest.mark.parametrize('driven', list(Driven))
def test_power_balance_and_the_statics_inverted(driven: Driven) -> None:
    r = TURNANTENNA.rocker_reach(driven)
    q = np.linspace(-0.9, 0.9, 37) * r.theta_max
    q_dot, tau_in = -0.21, 0.008  # rad/s, N m at the driven rocker
    c = complete(TURNANTENNA, q, driven, Branch.UPPER, q_rate=q_dot, effort=tau_in)
    assert c.load_torque is not None and c.theta_rate is not None
    # Power in equals power out: tau_in q_dot = tau_load theta_dot (a product of two quotients whose sin X and
    # sin u cancel: a few ulps).
    assert np.allclose(c.load_torque * c.theta_rate, tau_in * q_dot, rtol=16 * EPS, atol=0)
    # ... and with theta_dot measured by differences of the position inverse, independently of the closed forms.
    step = 1e-6
    dtheta = TURNANTENNA.from_rocker(q + step, driven).theta - TURNANTENNA.from_rocker(q - step, driven).theta
    assert np.allclose(c.load_torque * dtheta, tau_in * 2 * step, rtol=1e-7)
    # The forward statics take the load back to the effort (at the completed pose, whichever forward branch).
    g, d = (q, c.other) if driven is Driven.GAMMA else (c.other, q)
    back = TURNANTENNA.torque_at(c.theta, g, d, c.load_torque, driven)
    assert np.allclose(back, tau_in, rtol=64 * EPS)


def test_scalar_and_array_agree_and_only_what_is_asked() -> None:
    q = np.linspace(-0.5, 0.5, 11)
    arr = complete(TURNANTENNA, q, Driven.GAMMA, Branch.UPPER, q_rate=0.1, effort=0.005)
    for i, qi in enumerate(q):
        one = complete(TURNANTENNA, float(qi), Driven.GAMMA, Branch.UPPER, q_rate=0.1, effort=0.005)
        for name, a, s in zip(arr._fields, arr, one, strict=True):
            assert isinstance(s, float), name
            # numpy vs math: a few transcendentals per quantity, all well conditioned at these angles.
            assert abs(float(a[i]) - s) <= CHAIN_ULPS * EPS * 4 * (1 + abs(s)), (name, a[i], s)
    bare = complete(TURNANTENNA, 0.8, Driven.GAMMA, Branch.UPPER)
    assert bare.theta_rate is None and bare.other_rate is None and bare.load_torque is None
    only_load = complete(TURNANTENNA, 0.8, Driven.GAMMA, Branch.UPPER, effort=0.005)
    assert only_load.theta_rate is None and isinstance(only_load.load_torque, float)


@pytest.mark.parametrize('driven', list(Driven))
def test_the_driven_rockers_reach_limit(driven: Driven) -> None:
    r = TURNANTENNA.rocker_reach(driven)
    assert r.name == driven.value and r.theta_gap == 0.0 and 0.0 < r.theta_max < math.pi
    top = r.theta_max  # the last float the rocker takes, scalar or array: the reach decides
    for q in (top, -top):
        c = complete(TURNANTENNA, q, driven, Branch.UPPER)  # the pose exists there ...
        assert math.isfinite(c.theta)
        beyond = math.nextafter(q, math.copysign(4.0, q))
        with pytest.raises(UnreachableError):
            complete(TURNANTENNA, beyond, driven, Branch.UPPER)
        with pytest.raises(UnreachableError):
            complete(TURNANTENNA, np.array([beyond]), driven, Branch.UPPER)
        # ... but it is the dead point to within rounding: the antenna's rate is unbounded there (DeadPointError)
        # or rounding-sized (the true limit lies within an ulp of the float).
        try:
            rate = complete(TURNANTENNA, q, driven, Branch.UPPER, q_rate=0.1).theta_rate
            assert rate is not None and abs(float(rate)) > 1e5
        except DeadPointError as exc:
            assert 'reach limit' in str(exc)
        arr = complete(TURNANTENNA, np.array([q, 0.5 * q]), driven, Branch.UPPER, q_rate=0.1)
        assert arr.theta_rate is not None and np.isfinite(arr.theta_rate[1]) and abs(arr.theta_rate[1]) < 10.0
        assert np.isnan(arr.theta_rate[0]) or abs(arr.theta_rate[0]) > 1e5
    with pytest.raises(UnreachableError) as exc:
        complete(TURNANTENNA, top + 1e-9, driven, Branch.UPPER)
    msg = str(exc.value)
    assert '\n' not in msg and f'the {driven.value} rocker' in msg and f'{r.theta_max:.12g}' in msg


@pytest.mark.parametrize('bad', [math.nan, math.inf, -math.inf, 2.0])
def test_bad_measurements(bad: float) -> None:
    with pytest.raises(UnreachableError, match=f'q={bad!r}'):
        complete(TURNANTENNA, bad, Driven.GAMMA, Branch.UPPER, q_rate=0.1, effort=0.01)
    with pytest.raises(UnreachableError):
        complete(TURNANTENNA, np.array([0.8, bad]), Driven.GAMMA, Branch.UPPER)
    c = complete(TURNANTENNA, np.array([0.8, bad]), Driven.GAMMA, Branch.UPPER, q_rate=np.array([0.1, 0.1]),
                 effort=0.01, on_invalid='nan')
    for name, v in zip(c._fields, c, strict=True):
        assert np.isfinite(v[0]) and np.isnan(v[1]), name
