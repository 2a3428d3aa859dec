"""Stable closure of a two-link dyad: the triangle solve shared by every position solver in the package.

A diagonal runs from a pivot P to a point Q with Q - P = (L1 - L2 cos x, L2 sin x) for two lengths L1, L2 and an
angle x. Two links of lengths r1 (at P) and r2 (at Q) meet at a third point. Every quantity is formed without
cancellation: the diagonal through sin^2(x/2), the triangle's area through products of sums and differences of
lengths (Heron's formula in factored form), and the angles through atan2, never acos or asin.

Each function takes Python floats (math module) and the ``_np`` twins take numpy arrays of any shape.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]


class DyadConstants(NamedTuple):
    """Length combinations fixed by a geometry, computed once (all in length^2 or length units)."""

    l1: float
    l2: float
    r1: float
    r2: float
    diff: float  #: L1 - L2
    four_l1_l2: float  #: 4 L1 L2
    two_l2: float  #: 2 L2
    far: float  #: (r1 + r2)^2 - (L1 - L2)^2, factored: room left before the dyad stretches straight
    near: float  #: (L1 - L2)^2 - (r1 - r2)^2, factored: room left before the dyad folds flat
    r_sq_diff: float  #: r1^2 - r2^2, factored
    tol: float  #: rounding allowance on the area factors (a few ulps of their terms)


def dyad_constants(l1: float, l2: float, r1: float, r2: float, unit: float = 1.0) -> DyadConstants:
    """Precompute the geometry's length combinations in factored (cancellation-free) form, in units of ``unit``.

    Sums and differences are formed from the given lengths before scaling, so a near-parallelogram (L1 close to
    L2) keeps L1 - L2 to full relative precision.
    """
    diff = l1 - l2
    far = (r1 + r2 - diff) / unit * ((r1 + r2 + diff) / unit)
    near = (diff - (r1 - r2)) / unit * ((diff + (r1 - r2)) / unit)
    r_sq_diff = (r1 - r2) / unit * ((r1 + r2) / unit)
    l1, l2, r1, r2, diff = l1 / unit, l2 / unit, r1 / unit, r2 / unit, diff / unit
    scale = max((r1 + r2) ** 2, diff * diff, 4.0 * l1 * l2)
    return DyadConstants(
        l1=l1, l2=l2, r1=r1, r2=r2, diff=diff, four_l1_l2=4.0 * l1 * l2, two_l2=2.0 * l2,
        far=far, near=near, r_sq_diff=r_sq_diff, tol=8.0 * 2.220446049250313e-16 * scale,
    )


def closure_factors(k: DyadConstants, s_sq: float) -> tuple[float, float, float]:
    """Return (diag_sq, far, near) for s_sq = sin^2(x/2).

    diag_sq is |Q - P|^2; far = (r1 + r2)^2 - diag_sq and near = diag_sq - (r1 - r2)^2 are both >= 0 exactly when
    the dyad closes. Values within rounding of zero are returned as zero (the dyad is then straight or folded).
    """
    w = k.four_l1_l2 * s_sq
    far = k.far - w
    near = k.near + w
    if -k.tol <= far < 0.0:
        far = 0.0
    if -k.tol <= near < 0.0:
        near = 0.0
    return k.diff * k.diff + w, far, near


def closure_factors_np(k: DyadConstants, s_sq: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Array twin of :func:`closure_factors`."""
    w = k.four_l1_l2 * s_sq
    far = k.far - w
    near = k.near + w
    far[(far < 0.0) & (far >= -k.tol)] = 0.0
    near[(near < 0.0) & (near >= -k.tol)] = 0.0
    return k.diff * k.diff + w, far, near


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
