"""The segment polynomials joint_trajectory_controller interpolates with, for many segments at once.

Hermite of degree 1, 3 or 5 in s = (t - t[i]) / h, the unique such polynomial (the controller's in any basis);
coefficients in powers of s, lowest first, one row per segment; derivatives in s divide by h^k for time."""

from __future__ import annotations

import numpy as np

from fourbar_ros.core.numeric import FloatArray

__all__ = ['derivative_bound', 'derivatives_at', 'evaluate', 'hermite_coefficients', 'segment_extremes']


def hermite_coefficients(times: FloatArray, p: FloatArray, v: FloatArray | None = None,
                         a: FloatArray | None = None) -> FloatArray:
    """Power-basis coefficients in s, shape (segments, degree + 1): linear from p, cubic from p and v (per time),
    quintic from p, v and a. Units: those of p."""
    def ends(x: FloatArray | None) -> tuple[FloatArray | None, FloatArray | None]:
        return (None, None) if x is None else (x[:-1], x[1:])

    return hermite_segments(np.diff(times), p[:-1], p[1:], *ends(v), *ends(a))


def hermite_segments(h: FloatArray, p0: FloatArray, p1: FloatArray, v0: FloatArray | None = None,
                     v1: FloatArray | None = None, a0: FloatArray | None = None,
                     a1: FloatArray | None = None) -> FloatArray:
    """Power-basis coefficients in s of segments lasting ``h`` (s) from (p0, v0, a0) to (p1, v1, a1), one entry per
    segment, shape (segments, degree + 1): linear, cubic with the velocities, quintic with the accelerations too."""
    dp = p1 - p0
    if v0 is None or v1 is None:
        return np.stack([p0, dp], axis=1)
    v0, v1 = v0 * h, v1 * h
    if a0 is None or a1 is None:
        return np.stack([p0, v0, 3.0 * dp - 2.0 * v0 - v1, -2.0 * dp + v0 + v1], axis=1)
    a0, a1 = a0 * h * h, a1 * h * h
    return np.stack([p0, v0, 0.5 * a0,
                     10.0 * dp - 6.0 * v0 - 4.0 * v1 - 0.5 * (3.0 * a0 - a1),
                     -15.0 * dp + 8.0 * v0 + 7.0 * v1 + 0.5 * (3.0 * a0 - 2.0 * a1),
                     6.0 * dp - 3.0 * (v0 + v1) - 0.5 * (a0 - a1)], axis=1)


def evaluate(coefficients: FloatArray, s: FloatArray, order: int = 0) -> FloatArray:
    """The order-th derivative in s of each segment's polynomial at the values s (shape (segments, samples) or
    broadcastable to it), by Horner's rule."""
    c = coefficients
    for _ in range(order):
        c = c[:, 1:] * np.arange(1, c.shape[1], dtype=np.float64)
    if c.shape[1] == 0:
        return np.zeros(np.broadcast_shapes((c.shape[0], 1), np.shape(s)))
    out = np.broadcast_to(c[:, -1:], np.broadcast_shapes((c.shape[0], 1), np.shape(s))).copy()
    for k in range(c.shape[1] - 2, -1, -1):
        out = out * s + c[:, k:k + 1]
    return out


def derivative_bound(coefficients: FloatArray, order: int = 1) -> FloatArray:
    """Per segment, an upper bound on |d^order p/d s^order| over s in [0, 1]: the sum over k of
    k (k - 1) ... (k - order + 1) |c_k| (as |s^(k - order)| <= 1)."""
    k = np.arange(coefficients.shape[1], dtype=np.float64)
    falling = np.ones_like(k)
    for i in range(order):
        falling *= k - i
    bound: FloatArray = np.abs(coefficients) @ falling
    return bound


def derivatives_at(times: FloatArray, coefficients: FloatArray, order: int) -> tuple[FloatArray, FloatArray]:
    """The order-th time derivative of each segment at its start (s = 0) and at its end (s = 1): the one-sided
    values at the points, (segments,) each, in units of p per s^order."""
    h = np.diff(times)
    scale = h ** order
    ends = evaluate(coefficients, np.array([[0.0, 1.0]]), order)
    return ends[:, 0] / scale, ends[:, 1] / scale


def _real_roots_in_unit(c: FloatArray) -> FloatArray:
    """Per row, the real roots in [0, 1] of the polynomial with power-basis coefficients ``c`` (lowest first, degree
    at most 3), as candidates (NaN where a row has fewer): closed form for degrees 1 and 2, the eigenvalues of the
    companion matrix for 3. Where a leading coefficient is 0 (or tiny against the others, so the roots it adds lie
    far out) the lower degree's roots are candidates too: a candidate too many costs an evaluation, one too few
    would miss an extreme."""
    n, m = c.shape
    found: list[FloatArray] = []
    with np.errstate(divide='ignore', invalid='ignore', over='ignore'):
        if m >= 2:  # the linear part's root: c0 + c1 s = 0
            found.append((-c[:, 0] / c[:, 1])[:, None])
        if m >= 3:  # the quadratic's: c0 + c1 s + c2 s^2 = 0
            a, b, c0 = c[:, 2], c[:, 1], c[:, 0]
            disc = np.sqrt(np.maximum(b * b - 4.0 * a * c0, 0.0))
            q = -0.5 * (b + np.copysign(disc, b))  # the stable form: no cancellation
            found.append(np.column_stack([q / a, c0 / q]))
        if m >= 4:  # the cubic's: companion matrix of the monic polynomial
            lead = c[:, 3]
            ok = lead != 0.0
            roots = np.full((n, 3), np.nan)
            if ok.any():
                monic = c[ok, :3] / lead[ok, None]
                companion = np.zeros((int(ok.sum()), 3, 3))
                companion[:, 1, 0] = companion[:, 2, 1] = 1.0
                companion[:, :, 2] = -monic
                eig = np.linalg.eigvals(companion)
                real = np.abs(eig.imag) <= 1e-9 * (1.0 + np.abs(eig.real))
                roots[ok] = np.where(real, eig.real, np.nan)
            found.append(roots)
    out = np.concatenate(found, axis=1) if found else np.empty((n, 0))
    return np.where((out >= 0.0) & (out <= 1.0), out, np.nan)


def segment_extremes(times: FloatArray, coefficients: FloatArray, order: int) -> FloatArray:
    """Per segment, the largest |order-th time derivative| over the whole segment (s in [0, 1]), in units of p per
    s^order: the derivative's values at both ends and at the real roots in (0, 1) of the next derivative, found in
    closed form (``_real_roots_in_unit``; the next derivative of a quintic's velocity is a cubic), not by sampling.
    A polynomial of degree below ``order`` gives 0 (a linear segment has no acceleration between its points)."""
    c = coefficients
    for _ in range(order):
        c = c[:, 1:] * np.arange(1, c.shape[1], dtype=np.float64)
    h = np.diff(times)
    if c.shape[1] == 0:
        return np.zeros(h.size)
    ends = np.abs(evaluate(c, np.array([[0.0, 1.0]]))).max(axis=1)
    if c.shape[1] >= 2:
        slope = c[:, 1:] * np.arange(1, c.shape[1], dtype=np.float64)
        s = _real_roots_in_unit(slope)
        inside = np.abs(evaluate(c, np.nan_to_num(s, nan=0.0)))
        ends = np.maximum(ends, np.where(np.isnan(s), 0.0, inside).max(axis=1, initial=0.0))
    extremes: FloatArray = ends / h ** order
    return extremes
