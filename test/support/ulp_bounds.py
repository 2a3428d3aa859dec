"""Bounds for comparing two float code paths (scalar vs array, blocks, node vs core, offline vs live).

Two paths agree only to the rounding each one makes, carried through the problem: a few ulps times the quantity's
condition number. numpy's SIMD transcendentals may differ from libm (and from another CPU's numpy) by 1-2 ulp, so
a bit-for-bit comparison holds only when both sides run the very same operations on the same data and layout.

    assert_close_ulps(actual, expected, n_ulps, scale=...)

passes when |actual - expected| <= n_ulps * eps * scale element-wise (eps = 2**-52; eps * |x| >= ulp(x)).
scale defaults to |expected| (a relative bound); pass the condition-weighted magnitude where cancellation or
amplification makes the relative bound wrong. NaN must match NaN and infinities must be equal. The scale helpers
below give the condition-weighted magnitudes of this package's quantities.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import numpy.typing as npt

EPS = math.ulp(1.0)

#: Ulps for one quantity computed by a chain of a few rounded operations: each transcendental may be 2 ulps off
#: (SIMD vs libm) and the pose chain has about four of them (sin, cos and two arctan2), so 8 ulps of the
#: condition-weighted scale.
CHAIN_ULPS = 8.0

ArrayLike = float | npt.ArrayLike


def assert_close_ulps(actual: ArrayLike, expected: ArrayLike, n_ulps: float, scale: ArrayLike | None = None,
                      what: str = 'value') -> None:
    """Assert |actual - expected| <= n_ulps * EPS * scale element-wise (scale defaults to |expected|)."""
    a = np.asarray(actual, dtype=np.float64)
    e = np.asarray(expected, dtype=np.float64)
    assert a.shape == e.shape or a.size == e.size == 1, f'{what}: shapes {a.shape} and {e.shape} differ'
    a, e = np.broadcast_arrays(a, e)
    nan_a, nan_e = np.isnan(a), np.isnan(e)
    assert np.array_equal(nan_a, nan_e), (
        f'{what}: NaN at different elements (actual {np.flatnonzero(nan_a)[:5]}, expected {np.flatnonzero(nan_e)[:5]})')
    inf = np.isinf(a) | np.isinf(e)
    assert np.array_equal(a[inf], e[inf]), f'{what}: infinities differ'
    s = np.abs(e) if scale is None else np.broadcast_to(np.abs(np.asarray(scale, dtype=np.float64)), e.shape)
    ok = ~(nan_a | inf)
    with np.errstate(invalid='ignore'):  # inf - inf at the infinities checked above
        err = np.where(ok, np.abs(a - e), 0.0)
        bound = n_ulps * EPS * s
    bad = ok & ~(err <= bound)
    if bad.any():
        i = int(np.flatnonzero(bad.reshape(-1))[np.argmax((err / np.where(bound > 0, bound, 1.0))[bad])])
        af, ef, sf = a.reshape(-1), e.reshape(-1), s.reshape(-1)
        raise AssertionError(
            f'{what}: {int(bad.sum())} of {a.size} elements differ by more than {n_ulps:g} ulps of their scale; '
            f'worst at flat index {i}: {af[i]!r} vs {ef[i]!r}, |diff| = {abs(af[i] - ef[i]) / EPS / sf[i]:.3g} '
            f'eps * scale (scale {sf[i]:.6g})')


def angle_scale(q: ArrayLike, theta: ArrayLike, dq_dtheta: ArrayLike) -> npt.NDArray[np.float64]:
    """Condition-weighted magnitude (rad) of an angle q solved from theta: 1 + |q| + |theta dq/dtheta|.

    The rounding of q itself (|q|, or pi for intermediate angles: the 1 covers them) plus that of the input
    carried through the solve (a relative eps on theta moves q by eps |theta dq/dtheta|).
    """
    return 1.0 + np.abs(q) + np.abs(np.asarray(theta) * np.asarray(dq_dtheta))


def pose_scales(cfg: Any, theta: npt.NDArray[np.float64], torque: npt.NDArray[np.float64]
                ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """Condition-weighted scales of gamma, delta (rad) and the driven rocker's torque (N m) at ``theta``.

    The angles: ``angle_scale`` of each rocker. The torque is tau = load (rocker / h) sin(s) / sin(r), with
    s = gamma + delta and r the driven rocker's transmission angle (delta - theta or gamma + theta). An error e_s in s
    moves it by |load| (rocker / h) |cos s| e_s / |sin r| (finite at the reach limit, where sin s and tau are 0), an
    error e_r in r by |tau| |cot r| e_r; each angle's error is within the ulps of its parts' scales (the rockers'
    angle scales, and |theta|). The load's own terms (the constant, and m g times lever arms below 0.2 m) are
    rounded on their own scale.
    """
    from fourbar_ros.core.antenna import Driven

    link = cfg.linkage
    gamma, delta = link.rocker_angles(theta, cfg.branch, on_invalid='nan')
    rates = link.rates_at(theta, gamma, delta)
    g_scale = angle_scale(gamma, theta, rates.dgamma_dtheta)
    d_scale = angle_scale(delta, theta, rates.ddelta_dtheta)
    gamma_driven = cfg.driven is Driven.GAMMA
    s = gamma + delta
    r = delta - theta if gamma_driven else gamma + theta
    r_scale = (d_scale if gamma_driven else g_scale) + np.abs(theta)
    load = abs(cfg.load_torque) + cfg.antenna_mass * cfg.gravity * 0.2
    rocker = link.rocker_ab if gamma_driven else link.rocker_cd
    s_term = load * rocker / link.coupler * np.abs(np.cos(s)) * (g_scale + d_scale) / np.abs(np.sin(r))
    tau = np.abs(torque)
    with np.errstate(invalid='ignore'):  # 0 * inf at the exact reach limit, where the angles' condition is unbounded
        tau_scale = tau + cfg.antenna_mass * cfg.gravity * 0.2 + s_term + tau * np.abs(np.cos(r) / np.sin(r)) * r_scale
    return g_scale, d_scale, np.where(np.isnan(tau_scale), np.inf, tau_scale)


def sine_ratio_scale(coef: ArrayLike, num_angle: ArrayLike, num_scale: ArrayLike, den_angle: ArrayLike,
                     den_scale: ArrayLike) -> npt.NDArray[np.float64]:
    """Scale of v = coef sin(num_angle) / sin(den_angle) (a rocker rate, mechanical advantage or input torque).

    An angle error of n eps * s in x changes sin(x) by n eps * s |cos x|, so with the arguments accurate to n ulps
    of num_scale and den_scale, v is accurate to n ulps of
    |v| (1 + den_scale |cot den_angle|) + num_scale |coef cos(num_angle) / sin(den_angle)|; the 1 covers the
    sines' and the division's own rounding. Near a dead point (sin(den_angle) -> 0) the cotangent is the
    amplification.
    """
    n, d = np.asarray(num_angle, dtype=np.float64), np.asarray(den_angle, dtype=np.float64)
    with np.errstate(divide='ignore', invalid='ignore'):
        sin_d = np.sin(d)
        v = np.abs(np.asarray(coef) * np.sin(n) / sin_d)
        return (v * (1.0 + np.asarray(den_scale) * np.abs(np.cos(d) / sin_d))
                + np.asarray(num_scale) * np.abs(np.asarray(coef) * np.cos(n) / sin_d))


def second_derivative_scales(ab: float, cd: float, coupler: float, theta: ArrayLike, gamma: ArrayLike,
                             delta: ArrayLike, gamma_scale: ArrayLike,
                             delta_scale: ArrayLike) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """Scales (rad/rad^2) of d2 gamma/d theta2 and d2 delta/d theta2 computed from angles accurate to the given
    scales (rad): the loop differentiated twice, q'' = F_q(theta, gamma, delta) with

        AB sin X g'' = -(h cos(delta - theta) + AB g'^2 cos X + CD d'^2),  CD sin X d'' = -(h cos(gamma + theta)
        + AB g'^2 + CD d'^2 cos X),  X = gamma + delta, g' and d' the rates (themselves functions of the angles).

    Angles n ulps of their scales off move q'' by n ulps of |dF_q/dgamma| gamma_scale + |dF_q/ddelta| delta_scale;
    q'''s own rounding is a few ulps of its terms' magnitudes (sum |term| / |AB sin X|). The partial derivatives
    are taken by complex step (F at gamma + i e: Im / e is the derivative to rounding, with no difference taken).
    Near the reach limit sin X -> 0 and the angle errors are amplified by about 3 |cot X| |q''|.
    """
    t, g, d = (np.asarray(v, dtype=np.complex128) for v in (theta, gamma, delta))
    step = 1e-60

    def second(g_: npt.NDArray[np.complex128], d_: npt.NDArray[np.complex128]
               ) -> tuple[npt.NDArray[np.complex128], ...]:
        s, c = np.sin(g_ + d_), np.cos(g_ + d_)
        g1 = coupler * np.sin(d_ - t) / (ab * s)
        d1 = -coupler * np.sin(g_ + t) / (cd * s)
        terms_g = (coupler * np.cos(d_ - t), ab * g1 * g1 * c, cd * d1 * d1)
        terms_d = (coupler * np.cos(g_ + t), ab * g1 * g1, cd * d1 * d1 * c)
        return (-sum(terms_g) / (ab * s), -sum(terms_d) / (cd * s),
                sum(np.abs(v) for v in terms_g) / np.abs(ab * s), sum(np.abs(v) for v in terms_d) / np.abs(cd * s))

    with np.errstate(divide='ignore', invalid='ignore', over='ignore'):
        _, _, round_g, round_d = second(g, d)
        by_g = second(g + 1j * step, d)
        by_d = second(g, d + 1j * step)
        sg, sd = np.abs(np.asarray(gamma_scale)), np.abs(np.asarray(delta_scale))
        scale_g = (np.abs(by_g[0].imag) * sg + np.abs(by_d[0].imag) * sd) / step + round_g.real
        scale_d = (np.abs(by_g[1].imag) * sg + np.abs(by_d[1].imag) * sd) / step + round_d.real
    return scale_g, scale_d


def completion_scales(link: Any, driven: Any, q: npt.NDArray[np.float64], theta: npt.NDArray[np.float64],
                      other: npt.NDArray[np.float64]) -> tuple[npt.NDArray[np.float64], ...]:
    """Scales of the linkage completed from a measured rocker q (rad; ``rules.completion``), for two paths that
    each round to a few ulps of them: (theta, other rocker, coupler joint, dtheta/dq, d other/dq, dq/dtheta).

    theta and the other rocker: the inverse's own rounding (pi: angles wrapped to [-pi, pi]) plus q's carried by
    the derivatives (|q| |d./dq|, with |d./dq| bounded by the sine ratio and the length ratio); the coupler joint,
    a sum, the sum of its terms'; the rates and dq/dtheta, sine ratios (``sine_ratio_scale``) of angles known to
    those scales. Infinite where the condition is (exactly at a dead point).
    """
    gamma_driven = driven.value == 'gamma'
    g, d = (q, other) if gamma_driven else (other, q)
    h, ab, cd = link.coupler, link.rocker_ab, float(link.rocker_cd or 0.0)
    x, u, v = g + d, d - theta, g + theta
    lever, across = (u, v) if gamma_driven else (v, u)
    with np.errstate(divide='ignore', invalid='ignore'):
        dtheta = np.abs(np.sin(x) / np.sin(lever))
        dother = np.abs(np.sin(across) / np.sin(lever))
        theta_scale = math.pi + np.abs(theta) + np.abs(q) * dtheta * max(ab, cd) / h
        other_scale = math.pi + np.abs(other) + np.abs(q) * dother * max(ab, cd) / min(ab, cd)
        x_scale = theta_scale + other_scale + np.abs(q)
        rate = sine_ratio_scale(max(ab, cd) / h, x, x_scale, lever, 2 * x_scale)
        other_rate = sine_ratio_scale(max(ab, cd) / min(ab, cd), across, 2 * x_scale, lever, 2 * x_scale)
        load = sine_ratio_scale(h / min(ab, cd), lever, 2 * x_scale, x, x_scale)
    for scale in (rate, other_rate, load):  # 0/0 exactly at a dead point: unbounded condition
        scale[np.isnan(scale)] = np.inf
    return theta_scale, other_scale, x_scale, rate, other_rate, load
