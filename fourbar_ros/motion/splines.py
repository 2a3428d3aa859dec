"""The segment polynomials joint_trajectory_controller interpolates with, for many segments at once.

Segment i runs from point i to point i + 1 over h = t[i+1] - t[i]; with s = (t - t[i]) / h in [0, 1] it is the
Hermite polynomial of degree 1, 3 or 5 matching the positions (and velocities, and accelerations) at both ends:
the unique polynomial of that degree, so it is the controller's segment whatever basis the controller writes it in.
Coefficients are in powers of s, lowest first, one row per segment; derivatives in s divide by h^k for time.
"""

from __future__ import annotations

import numpy as np

from fourbar_ros.core.numeric import FloatArray

__all__ = ['derivative_bound', 'derivatives_at', 'evaluate', 'hermite_coefficients']


def hermite_coefficients(times: FloatArray, p: FloatArray, v: FloatArray | None = None,
                         a: FloatArray | None = None) -> FloatArray:
    """Power-basis coefficients in s, shape (segments, degree + 1): linear from p, cubic from p and v (per time),
    quintic from p, v and a. Units: those of p."""
    h = np.diff(times)
    p0, p1 = p[:-1], p[1:]
    dp = p1 - p0
    if v is None:
        return np.stack([p0, dp], axis=1)
    v0, v1 = v[:-1] * h, v[1:] * h
    if a is None:
        return np.stack([p0, v0, 3.0 * dp - 2.0 * v0 - v1, -2.0 * dp + v0 + v1], axis=1)
    a0, a1 = a[:-1] * h * h, a[1:] * h * h
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
