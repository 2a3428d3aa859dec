"""Stable closure of a two-link dyad: the triangle solve shared by every position solver in the package.

A diagonal runs from a pivot P to a point Q with Q - P = (L1 - L2 cos x, L2 sin x) for two lengths L1, L2 and an
angle x. Two links of lengths r1 (at P) and r2 (at Q) meet at a third point. With w = 4 L1 L2 sin^2(x/2):

    |Q - P|^2              = (L1 - L2)^2 + w
    (r1 + r2)^2 - |Q - P|^2 = far - w     >= 0: the dyad is not over-stretched
    |Q - P|^2 - (r1 - r2)^2 = near + w    >= 0: the dyad is not over-folded
    angle at P = atan2(sqrt((far - w)(near + w)), cos_p + w),  angle at Q = atan2(same, cos_q + w)

The constants (far, near, cos_p, cos_q) are exact rational functions of the lengths, rounded once at construction,
so each per-angle quantity is one constant plus w: its only rounding beyond the constant's is that of w, which is
the rounding the angle x itself brings. No acos, no asin, no difference of two rounded squares per call.
"""

from __future__ import annotations

import math
from fractions import Fraction
from typing import NamedTuple


class DyadConstants(NamedTuple):
    """Length combinations fixed by a geometry, in units of a chosen length (squared where squared)."""

    diff: float  #: L1 - L2
    diff_sq: float  #: (L1 - L2)^2
    four_l1_l2: float  #: 4 L1 L2
    two_l2: float  #: 2 L2
    far: float  #: (r1 + r2)^2 - (L1 - L2)^2: room left before the dyad stretches straight
    near: float  #: (L1 - L2)^2 - (r1 - r2)^2: room left before the dyad folds flat
    cos_p: float  #: (L1 - L2)^2 + r1^2 - r2^2: 2 r1 |PQ| cos(angle at P), less w
    cos_q: float  #: (L1 - L2)^2 - r1^2 + r2^2: 2 r2 |PQ| cos(angle at Q), less w
    equal_links: bool  #: r1 == r2, so both angles are equal
    tol: float  #: rounding allowance on far - w and near + w (a few ulps of their terms)


def dyad_constants(l1: float, l2: float, r1: float, r2: float, unit: float = 1.0) -> DyadConstants:
    """The geometry's constants in units of ``unit``, each computed exactly and rounded once."""
    fl1, fl2, fr1, fr2 = (Fraction(v) / Fraction(unit) for v in (l1, l2, r1, r2))
    diff = fl1 - fl2
    d2 = diff * diff
    s_sum, s_diff = (fr1 + fr2) ** 2, (fr1 - fr2) ** 2
    r_sq = fr1 * fr1 - fr2 * fr2
    scale = max(s_sum, d2, 4 * fl1 * fl2)
    return DyadConstants(
        diff=float(diff), diff_sq=float(d2), four_l1_l2=float(4 * fl1 * fl2), two_l2=float(2 * fl2),
        far=float(s_sum - d2), near=float(d2 - s_diff), cos_p=float(d2 + r_sq), cos_q=float(d2 - r_sq),
        equal_links=r1 == r2, tol=8.0 * math.ulp(1.0) * float(scale),
    )


def reach_half_angles(k: DyadConstants) -> tuple[float, float]:
    """Bounds on x for which the dyad closes: returns (x_gap, x_max) in [0, pi], closes iff x_gap <= |x| <= x_max.

    Raises ValueError when no x closes the dyad (the caller words the message for its geometry).
    """
    hi = k.far / k.four_l1_l2  # sin^2(x/2) must not exceed this
    lo = -k.near / k.four_l1_l2  # ... nor fall below this
    if hi < 0.0 or lo > 1.0 or lo > hi:
        raise ValueError('the dyad never closes')
    x_max = math.pi if hi >= 1.0 else 2.0 * math.atan2(math.sqrt(hi), math.sqrt(1.0 - hi))
    x_gap = 0.0 if lo <= 0.0 else 2.0 * math.atan2(math.sqrt(lo), math.sqrt(1.0 - lo))
    return x_gap, x_max
