"""Independent high-precision reference for the antenna linkage (mpmath, 60 digits), for tests only.

Derived separately from the package's solver: B is intersected in Cartesian coordinates as the meeting point of
the circle of radius AB about A and the circle of radius CD about D' = D - h (cos theta, -sin theta); gamma and
delta are then read off with atan2. Inputs (lengths, theta) are taken as exact binary values.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import mpmath
from mpmath import mp, mpf

DIGITS = 60


def antenna_angles(frame: float, ab: float, coupler: float, cd: float, theta: float,
                   branch: int = 1) -> tuple[mpf, mpf]:
    """(gamma, delta) in radians at DIGITS digits; branch +1 puts B left of the line A -> D'."""
    with mp.workdps(DIGITS):
        big_h, a, h, c, t = (mpf(v) for v in (frame, ab, coupler, cd, theta))
        dx = big_h - h * mpmath.cos(t)
        dy = h * mpmath.sin(t)
        e2 = dx * dx + dy * dy
        e = mpmath.sqrt(e2)
        p = (a * a - c * c + e2) / (2 * e)
        q2 = a * a - p * p
        if q2 < 0:
            # The package solves an angle out of reach by no more than rounding as the limit pose; so does this.
            if q2 < -mpf(10) ** -12 * a * a:
                raise ValueError(f'theta={theta!r} is out of reach')
            q2 = mpf(0)
        q = branch * mpmath.sqrt(q2)
        ux, uy = dx / e, dy / e
        bx, by = p * ux - q * uy, p * uy + q * ux
        gamma = mpmath.atan2(by, bx)
        cx, cy = bx + h * mpmath.cos(t), by - h * mpmath.sin(t)
        delta = mpmath.atan2(cy, big_h - cx)
        return +gamma, +delta


def antenna_rates(frame: float, ab: float, coupler: float, cd: float, theta: float,
                  branch: int = 1) -> tuple[mpf, mpf]:
    """(d gamma/d theta, d delta/d theta) by high-precision numerical differentiation of the angles, DIGITS digits.

    mpmath.diff raises the working precision for its difference quotients, so the function it differentiates
    must compute at the ambient precision (a fixed workdps inside it would cap the result at ~18 digits).
    """
    def part(i: int) -> Callable[[mpf], mpf]:
        return lambda t: _angles_mp(frame, ab, coupler, cd, t, branch)[i]

    with mp.workdps(DIGITS + 20):
        x = mpf(theta)
        dg, dd = mpmath.diff(part(0), x), mpmath.diff(part(1), x)
    with mp.workdps(DIGITS):
        return +dg, +dd


def _angles_mp(frame: float, ab: float, coupler: float, cd: float, t: mpf, branch: int) -> tuple[mpf, mpf]:
    big_h, a, h, c = (mpf(v) for v in (frame, ab, coupler, cd))
    dx = big_h - h * mpmath.cos(t)
    dy = h * mpmath.sin(t)
    e2 = dx * dx + dy * dy
    e = mpmath.sqrt(e2)
    p = (a * a - c * c + e2) / (2 * e)
    q = branch * mpmath.sqrt(a * a - p * p)
    ux, uy = dx / e, dy / e
    bx, by = p * ux - q * uy, p * uy + q * ux
    cx, cy = bx + h * mpmath.cos(t), by - h * mpmath.sin(t)
    return mpmath.atan2(by, bx), mpmath.atan2(cy, big_h - cx)


def angle_error(ours: float, ref: mpf) -> float:
    """|ours - ref| modulo 2 pi, in radians (the reference is wrapped to (-pi, pi], ours is continuous)."""
    with mp.workdps(DIGITS):
        d = mpf(ours) - ref
        d = d - 2 * mp.pi * mpmath.nint(d / (2 * mp.pi))
        return abs(float(d))


def theta_limit(frame: float, ab: float, coupler: float, cd: float) -> mpf:
    """The outer reach limit theta_max at DIGITS digits (the rockers in line: |AD'| = AB + CD)."""
    with mp.workdps(DIGITS):
        big_h, a, h, c = (mpf(v) for v in (frame, ab, coupler, cd))
        cos_t = (big_h * big_h + h * h - (a + c) ** 2) / (2 * big_h * h)
        return +mpmath.acos(max(min(cos_t, mpf(1)), mpf(-1)))


EPS = math.ulp(1.0)
