"""Stable closure of a two-link dyad: the triangle solve shared by every position solver in the package.

Why it stays exact to the reach limit: docs/explanation/exactness.md."""

from __future__ import annotations

import enum
import math
from collections.abc import Callable
from fractions import Fraction
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from fourbar_ros.core.numeric import FloatArray, OnInvalid


class DyadConstants(NamedTuple):
    """Length combinations fixed by a geometry, in units of a chosen length (squared where squared)."""

    diff: float  #: L1 - L2
    diff_sq: float  #: (L1 - L2)^2
    four_l1_l2: float  #: 4 L1 L2
    two_l2: float  #: 2 L2
    far: float  #: (r1 + r2)^2 - (L1 - L2)^2: room left before the dyad stretches straight
    far_pi: float  #: (r1 + r2)^2 - (L1 + L2)^2: the same room at x = pi
    wide: bool  #: the dyad closes somewhere past |x| = pi/2 (far > 2 L1 L2), where far_pi + wc is used
    near: float  #: (L1 - L2)^2 - (r1 - r2)^2: room left before the dyad folds flat
    cos_p: float  #: (L1 - L2)^2 + r1^2 - r2^2: 2 r1 |PQ| cos(angle at P), less w
    cos_q: float  #: (L1 - L2)^2 - r1^2 + r2^2: 2 r2 |PQ| cos(angle at Q), less w
    equal_links: bool  #: r1 == r2, so both angles are equal
    tol: float  #: rounding allowance on far - w and near + w (a few ulps of their terms)
    cut_at_pi: bool  #: phi's 2 pi cut lies at x = pi (not at x = 0, where atan2 puts it when L2 > L1)


def dyad_constants(l1: float, l2: float, r1: float, r2: float, unit: float = 1.0,
                   continuous_at_zero: bool = False) -> DyadConstants:
    """The geometry's constants in units of ``unit``, each computed exactly and rounded once.

    With L2 > L1 the direction phi of P -> Q passes pi at x = 0, where atan2 has its cut: the angles then jump by
    2 pi at x = 0 unless ``continuous_at_zero`` moves the cut to x = pi (the same angles modulo 2 pi).
    """
    fl1, fl2, fr1, fr2 = (Fraction(v) / Fraction(unit) for v in (l1, l2, r1, r2))
    diff = fl1 - fl2
    d2 = diff * diff
    s_sum, s_diff = (fr1 + fr2) ** 2, (fr1 - fr2) ** 2
    r_sq = fr1 * fr1 - fr2 * fr2
    scale = max(s_sum, d2, 4 * fl1 * fl2)
    return DyadConstants(
        diff=float(diff), diff_sq=float(d2), four_l1_l2=float(4 * fl1 * fl2), two_l2=float(2 * fl2),
        far=float(s_sum - d2), far_pi=float(s_sum - (fl1 + fl2) ** 2), wide=s_sum - d2 > 2 * fl1 * fl2,
        near=float(d2 - s_diff), cos_p=float(d2 + r_sq), cos_q=float(d2 - r_sq),
        equal_links=r1 == r2, tol=8.0 * math.ulp(1.0) * float(scale), cut_at_pi=continuous_at_zero and diff < 0,
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


class Branch(enum.IntEnum):
    """Assembly branch: on which side of the diagonal P -> Q the dyad's third point lies.

    UPPER (+1) puts it to the left of P -> Q, LOWER (-1) to the right (its mirror image across the diagonal).
    For ``AntennaLinkage`` (theta given) UPPER is the annex's branch (A.14, A.15): B to the left of the diagonal
    from A to D - h (cos theta, -sin theta), so gamma + delta is in [0, pi]. For ``FourBar`` (crank angle given)
    UPPER is the 'open' assembly, C to the left of the diagonal from B to O4, and LOWER the 'crossed' one; so for
    ``AntennaLinkage.from_rocker`` (a rocker angle given), where UPPER is the annex's working pose.
    """

    UPPER = 1
    LOWER = -1


class DyadOpenError(ValueError):
    """The dyad does not close at this angle (out of reach, NaN or inf); the caller words the message."""


class DyadChangePointError(ValueError):
    """The diagonal P -> Q has zero length (a change point): the dyad's angles are undetermined.

    ``x`` is the angle (rad) where it happened (the first such element of an array).
    """

    def __init__(self, x: float) -> None:
        super().__init__(f'x={x!r} is a change point')
        self.x = x


_UPPER = Branch.UPPER
_sin, _cos, _sqrt, _atan2, _PI = math.sin, math.cos, math.sqrt, math.atan2, math.pi
_SQRT_HALF = math.sqrt(0.5)  #: |sin(x/2)| above this: |x| past pi/2 (mod 2 pi)
_BLOCK = 8192  #: elements per block of the vectorized solve: its working arrays (64 KiB each) stay in L2


#: closure_for's result: (x in rad, branch) -> (angle_p, angle_q) in rad.
ScalarClosure = Callable[[float, Branch], tuple[float, float]]


def closure_for(k: DyadConstants) -> ScalarClosure:
    """The scalar closure of one geometry: a function (x, branch) -> (angle_p, angle_q) for x a Python float (rad).

    angle_p = phi + alpha on UPPER (phi - alpha on LOWER) is the direction of link r1 from P (from +x,
    counter-clockwise); angle_q = beta - phi on UPPER (-beta - phi on LOWER) is pi minus the direction of link r2
    from Q, i.e. its angle measured clockwise from -x. phi is the direction of P -> Q, alpha and beta the triangle's
    angles at P and Q (see the module docstring). The function raises DyadOpenError where the dyad does not close
    (NaN, inf, out of reach) and DyadChangePointError where P = Q. The constants are bound once, as the closure's
    own variables: the per-call cost is the math alone (this is the solvers' scalar hot path).
    """
    diff, diff_sq, _, two_l2, far0, far_pi, wide, near0, cos_p, cos_q, equal_links, tol, cut_at_pi = k

    def closure(x: float, branch: Branch) -> tuple[float, float]:
        half = 0.5 * x
        try:
            s = _sin(half)
        except ValueError:  # math.sin(inf)
            raise DyadOpenError from None
        hs = two_l2 * s  # 2 L2 sin(x/2), L1 being the unit
        w = 2.0 * hs * s  # 4 L1 L2 sin^2(x/2)
        c = _cos(half)
        if wide and (s > _SQRT_HALF or s < -_SQRT_HALF):  # past |x| = pi/2: see the module docstring
            hc = two_l2 * c
            far = far_pi + 2.0 * hc * c
        else:
            far = far0 - w
        near = near0 + w
        if not far * near >= 0.0:  # rare: zero a factor negative only by rounding at the reach limit, else open
            if -tol <= far < 0.0:
                far = 0.0
            if -tol <= near < 0.0:
                near = 0.0
            if not (far >= 0.0 and near >= 0.0):
                raise DyadOpenError
        if diff_sq + w == 0.0:
            raise DyadChangePointError(float(x))
        root = _sqrt(far * near)
        if cut_at_pi:
            phi = _PI + _atan2(-hs * c, -diff - hs * s)
        else:
            phi = _atan2(hs * c, diff + hs * s)
        alpha = _atan2(root, cos_p + w)
        beta = alpha if equal_links else _atan2(root, cos_q + w)
        if branch is _UPPER:
            return phi + alpha, beta - phi
        return phi - alpha, -beta - phi

    return closure


def open_factors(k: DyadConstants, far: FloatArray, near: FloatArray) -> npt.NDArray[np.bool_]:
    """Where (far - w, near + w) say 'does not close', after zeroing factors negative only by rounding (in place)."""
    tol = k.tol
    far[(far < 0.0) & (far >= -tol)] = 0.0
    near[(near < 0.0) & (near >= -tol)] = 0.0
    with np.errstate(invalid='ignore'):
        return ~((far >= 0.0) & (near >= 0.0))


def closes(k: DyadConstants, x: FloatArray) -> npt.NDArray[np.bool_]:
    """Element-wise: does the dyad close at x (rad)? False for NaN, inf and out-of-reach values.

    The very test closure_array applies (so it agrees with on_invalid='nan' to the last float at the limits).
    """
    with np.errstate(invalid='ignore'):  # NaN for inf: not closed, like NaN itself
        half = 0.5 * np.asarray(x, dtype=np.float64)
        s = np.sin(half)
        w = 2.0 * (s * k.two_l2) * s
        far = k.far - w
        if k.wide:
            _far_from_pi(k, s, np.cos(half), far)
        return ~open_factors(k, far, w + k.near)


def closure_array(k: DyadConstants, x: FloatArray, branch: Branch,
                  on_invalid: OnInvalid) -> tuple[FloatArray, FloatArray]:
    """closure_for(k)'s closure on every element of a float64 array x (rad): (angle_p, angle_q) arrays of x's shape.

    With on_invalid='raise' an element where the dyad does not close raises DyadOpenError, a change point
    DyadChangePointError (block by block, in order); with 'nan' those elements are NaN. Solved in cache-sized
    blocks: the dozen arithmetic passes around the five unavoidable ufuncs then cost far less than on arrays
    streamed through memory. The loop is over blocks, not elements.
    """
    flat = np.ascontiguousarray(x).reshape(-1)
    out_p = np.empty_like(flat)
    out_q = np.empty_like(flat)
    for start in range(0, flat.size, _BLOCK):
        stop = start + _BLOCK
        _closure_block(k, flat[start:stop], branch, on_invalid, out_p[start:stop], out_q[start:stop])
    return out_p.reshape(x.shape), out_q.reshape(x.shape)


def _closure_block(k: DyadConstants, t: FloatArray, branch: Branch, on_invalid: OnInvalid, out_p: FloatArray,
                   out_q: FloatArray) -> None:
    """closure_for(k)'s operations, in the same order, on one block; results written to out_p, out_q."""
    with np.errstate(invalid='ignore'):
        half = t * 0.5
        s = np.sin(half)
        c = np.cos(half, out=half)
    hs = s * k.two_l2
    w = hs * s
    w *= 2.0
    far = k.far - w
    if k.wide:
        _far_from_pi(k, s, c, far)
    near = w + k.near
    prod = far * near
    if not prod.min() >= 0.0:
        bad = open_factors(k, far, near)
        if bad.any() and on_invalid == 'raise':
            raise DyadOpenError
        far[bad] = np.nan
        np.multiply(far, near, out=prod)
    if k.diff == 0.0 and (w == 0.0).any():  # only a geometry with L1 = L2 can have P = Q
        change = w == 0.0
        if on_invalid == 'raise':
            raise DyadChangePointError(float(t[change][0]))
        prod[change] = np.nan
    root = np.sqrt(prod, out=prod)
    y = np.multiply(hs, c, out=c)  # L2 sin(x)
    hs *= s
    xx = np.add(hs, k.diff, out=hs)  # L1 - L2 cos(x)
    if k.cut_at_pi:
        phi = np.arctan2(np.negative(y, out=y), np.negative(xx, out=xx), out=y)
        phi += math.pi
    else:
        phi = np.arctan2(y, xx, out=y)
    alpha = np.arctan2(root, np.add(w, k.cos_p, out=far), out=far)
    if k.equal_links:
        beta = alpha
    else:
        w += k.cos_q
        beta = np.arctan2(root, w, out=w)
    if branch is _UPPER:
        np.add(phi, alpha, out=out_p)
        np.subtract(beta, phi, out=out_q)
    else:
        np.subtract(phi, alpha, out=out_p)
        np.negative(beta, out=out_q)
        out_q -= phi


def _far_from_pi(k: DyadConstants, s: FloatArray, c: FloatArray, far: FloatArray) -> None:
    """Where |x| is past pi/2 (|sin(x/2)| > sqrt(1/2)), replace far - w by far_pi + wc (in place)."""
    with np.errstate(invalid='ignore'):
        past = np.abs(s) > _SQRT_HALF
    if past.any():
        cp = c[past]
        far[past] = (cp * k.two_l2) * cp * 2.0 + k.far_pi
