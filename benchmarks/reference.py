r"""Independent high-precision reference for the antenna linkage (mpmath, 60 working digits, >= 50 correct): the
one reference of the benchmarks and the tests.

Derived here from the loop-closure equations (Annex A, eq. A.2 convention), not from the core's code:

    A = 0, D = (H, 0), B = a (cos g, sin g), C = D + b (-cos d, sin d), C - B = h (cos t, -sin t).

With u = (cos t, -sin t), C - D = B + h u - D, so |B - D'| = b for D' = D - h u = (H - h cos t, h sin t): B is the
meeting point of the circle (A, a) and the circle (D', b), found in Cartesian coordinates (its projection p on the
line A -> D' and its height q off it, q > 0 on the upper branch: B to the left of A -> D', the annex's
gamma + delta in [0, pi]); gamma and delta are then read off B and C with atan2. (The core solves the triangle
A, D', B by its angles instead: a different route to the same pose.)

Every float input (lengths, theta) is taken as an exact binary number; results lie in (-pi, pi] and are handed
to float code as double-double pairs (hi, lo) so that errors far below one ulp can be measured.
The condition number and :func:`rates_mp` use the implicit-function derivatives of the same loop equations;
:func:`numeric_derivative_mp` differentiates the angles numerically instead (an independent check of both), for the
first and the second derivatives (:func:`second_derivatives_mp`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import mpmath
import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]

DPS = 60  #: working decimal digits; tests check agreement with 120 digits to better than 1e-50
UNIT_ROUNDOFF = 2.0**-53


class ReferenceUnreachableError(ValueError):
    """The (exact) input theta is outside the linkage's reach: no real solution exists."""


class ReferenceSingularError(ValueError):
    """The pose is undetermined (the diagonal A-D' has zero length: a parallelogram at its change point)."""


@dataclass(frozen=True)
class Geometry:
    """An antenna four-bar: frame H = AD, rockers a = AB and b = CD, coupler h = BC (metres)."""

    name: str
    frame: float
    rocker_ab: float
    coupler: float
    rocker_cd: float

    @property
    def equal_rockers(self) -> bool:
        """True when AB == CD (the annex's case; its formula applies only then)."""
        return self.rocker_ab == self.rocker_cd

    def scaled(self, factor: float, name: str | None = None) -> Geometry:
        """The same shape with every length multiplied by factor (rounded to float)."""
        return Geometry(name or f'{self.name}*{factor:g}', self.frame * factor, self.rocker_ab * factor,
                        self.coupler * factor, self.rocker_cd * factor)


def _mp_lengths(g: Geometry) -> tuple[mpmath.mpf, mpmath.mpf, mpmath.mpf, mpmath.mpf]:
    return mpmath.mpf(g.frame), mpmath.mpf(g.rocker_ab), mpmath.mpf(g.coupler), mpmath.mpf(g.rocker_cd)


def rocker_angles_mp(g: Geometry, theta: float, branch: int = 1, dps: int = DPS,
                     limit_slack: float = 0.0) -> tuple[mpmath.mpf, mpmath.mpf]:
    """(gamma, delta) in radians, in (-pi, pi], for the exact float theta; branch +1 upper, -1 lower.

    Raises ReferenceUnreachableError outside the reach and ReferenceSingularError where the diagonal vanishes.
    ``limit_slack`` > 0 solves a theta out of reach by no more than that share of AB^2 in q^2 as the limit pose
    (as the core does for a float past the limit by rounding only). The values are mpf at ``dps`` digits
    (returned outside the precision context: use them promptly or convert with :func:`to_double_double`).
    """
    if branch not in (1, -1):
        raise ValueError(f'branch must be +1 or -1, not {branch!r}')
    with mpmath.workdps(dps):
        return _angles(g, mpmath.mpf(theta), branch, limit_slack)


def _angles(g: Geometry, t: mpmath.mpf, branch: int, limit_slack: float) -> tuple[mpmath.mpf, mpmath.mpf]:
    """rocker_angles_mp at the ambient precision (so that mpmath.diff can raise it)."""
    H, a, h, b = _mp_lengths(g)
    dx = H - h * mpmath.cos(t)  # D' = (dx, dy)
    dy = h * mpmath.sin(t)
    e2 = dx * dx + dy * dy
    if e2 == 0:
        raise ReferenceSingularError(f'{g.name}: theta={float(t)!r} makes a parallelogram change point')
    e = mpmath.sqrt(e2)
    p = (a * a - b * b + e2) / (2 * e)  # B's projection on A -> D'
    q2 = a * a - p * p  # B's squared height off A -> D'
    if q2 < 0:
        if q2 < -limit_slack * a * a:
            raise ReferenceUnreachableError(f'{g.name}: theta={float(t)!r} is out of reach')
        q2 = mpmath.mpf(0)
    q = branch * mpmath.sqrt(q2)
    ux, uy = dx / e, dy / e
    bx, by = p * ux - q * uy, p * uy + q * ux
    cx, cy = bx + h * mpmath.cos(t), by - h * mpmath.sin(t)
    return mpmath.atan2(by, bx), mpmath.atan2(cy, H - cx)


def loop_residual_mp(g: Geometry, theta: float, gamma: mpmath.mpf, delta: mpmath.mpf,
                     dps: int = DPS) -> tuple[mpmath.mpf, mpmath.mpf]:
    """The two loop-closure equations (A.2) evaluated at high precision, in metres (both 0 for a true pose)."""
    with mpmath.workdps(dps):
        H, a, h, b = _mp_lengths(g)
        t = mpmath.mpf(theta)
        return (a * mpmath.cos(gamma) + b * mpmath.cos(delta) - (H - h * mpmath.cos(t)),
                a * mpmath.sin(gamma) - b * mpmath.sin(delta) - h * mpmath.sin(t))


def to_double_double(x: mpmath.mpf) -> tuple[float, float]:
    """Split x into hi + lo with hi = float(x) (round to nearest) and lo the float nearest x - hi."""
    with mpmath.workdps(DPS):
        hi = float(x)
        return hi, float(x - mpmath.mpf(hi))


@dataclass(frozen=True)
class ReferenceArrays:
    """Reference (gamma, delta) for an array of angles: double-double parts, and a validity mask.

    ``status`` is 0 where a solution exists, 1 where theta is out of reach, 2 where the pose is singular.
    """

    gamma_hi: FloatArray
    gamma_lo: FloatArray
    delta_hi: FloatArray
    delta_lo: FloatArray
    status: npt.NDArray[np.int8]


def reference_arrays(g: Geometry, theta: FloatArray, branch: int = 1) -> ReferenceArrays:
    """Evaluate :func:`rocker_angles_mp` at every float in theta (a Python loop: about 0.1 ms per angle)."""
    n = theta.size
    out = np.zeros((4, n))
    status = np.zeros(n, dtype=np.int8)
    for i, t in enumerate(theta.ravel().tolist()):
        try:
            gm, dm = rocker_angles_mp(g, t, branch)
        except (ReferenceUnreachableError, ReferenceSingularError) as exc:
            status[i] = 1 if isinstance(exc, ReferenceUnreachableError) else 2
            out[:, i] = np.nan
            continue
        out[0, i], out[1, i] = to_double_double(gm)
        out[2, i], out[3, i] = to_double_double(dm)
    shape = theta.shape
    return ReferenceArrays(out[0].reshape(shape), out[1].reshape(shape), out[2].reshape(shape),
                           out[3].reshape(shape), status.reshape(shape))


def angle_error(value: npt.ArrayLike, hi: FloatArray, lo: FloatArray) -> FloatArray:
    """|value - (hi + lo)| in radians, modulo 2 pi, resolved far below one ulp when value is close to hi.

    value - hi is exact when the two are within a factor of 2 (Sterbenz), so the error of an accurate method is
    measured to about 1e-32 rad rather than rounded to half an ulp. NaN where value is NaN.
    """
    v = np.asarray(value, dtype=np.float64)
    d = (v - hi) - lo
    big = np.abs(d) > math.pi
    if big.any():
        d = np.where(big, np.remainder(d + math.pi, 2.0 * math.pi) - math.pi, d)
    return np.abs(d)


def condition(g: Geometry, theta: float, branch: int = 1) -> tuple[float, float]:
    """Absolute condition numbers (kappa_gamma, kappa_delta) in radians per unit relative input perturbation.

    kappa_f = sum over inputs x in (theta, H, a, b, h) of |d f/d x| |x|: a backward-stable method errs by about
    u * (kappa_f + |f|) (u = 2^-53). Derivatives by the implicit-function theorem on the loop equations
    F1 = a cos g + h cos t + b cos d - H, F2 = a sin g - h sin t - b sin d, whose Jacobian determinant in
    (g, d) is a b sin(g + d); infinite at the exact reach limit, where that determinant vanishes.
    """
    gm, dm = rocker_angles_mp(g, theta, branch)
    with mpmath.workdps(DPS):
        H, a, h, b = _mp_lengths(g)
        t = mpmath.mpf(theta)
        cg, sg, cd, sd = mpmath.cos(gm), mpmath.sin(gm), mpmath.cos(dm), mpmath.sin(dm)
        det = a * b * mpmath.sin(gm + dm)
        if det == 0:
            return math.inf, math.inf
        # dF/dx for x = theta, H, a, b, h; each paired with |x|.
        columns = [
            ((-h * mpmath.sin(t), -h * mpmath.cos(t)), abs(t)),
            ((mpmath.mpf(-1), mpmath.mpf(0)), H),
            ((cg, sg), a),
            ((cd, -sd), b),
            ((mpmath.cos(t), -mpmath.sin(t)), h),
        ]
        kg = mpmath.mpf(0)
        kd = mpmath.mpf(0)
        for (v1, v2), x in columns:
            kg += abs(b * (cd * v1 - sd * v2) / det) * x
            kd += abs(a * (cg * v1 + sg * v2) / det) * x
        return float(kg), float(kd)


def _first_derivatives(g: Geometry, t: mpmath.mpf, gm: mpmath.mpf, dm: mpmath.mpf) -> tuple[mpmath.mpf, ...]:
    """(d gamma/d theta, d delta/d theta, det) by the implicit-function theorem (at the ambient precision)."""
    _, a, h, b = _mp_lengths(g)
    det = a * b * mpmath.sin(gm + dm)
    v1, v2 = -h * mpmath.sin(t), -h * mpmath.cos(t)  # minus dF/dt
    return (b * (mpmath.cos(dm) * v1 - mpmath.sin(dm) * v2) / det,
            a * (mpmath.cos(gm) * v1 + mpmath.sin(gm) * v2) / det, det)


def rates_mp(g: Geometry, theta: float, branch: int = 1) -> tuple[float, float]:
    """(d gamma/d theta, d delta/d theta) from the same implicit-function formulas.

    For checks against test/data/turnantenna_reference.csv."""
    gm, dm = rocker_angles_mp(g, theta, branch)
    with mpmath.workdps(DPS):
        dg, dd, _ = _first_derivatives(g, mpmath.mpf(theta), gm, dm)
        return float(dg), float(dd)


def numeric_derivative_mp(g: Geometry, theta: float, order: int, branch: int = 1, limit_slack: float = 0.0,
                          dps: int = DPS) -> tuple[mpmath.mpf, mpmath.mpf]:
    """The ``order``-th derivatives of (gamma, delta) in theta (rad/rad^order) by numerical differentiation of
    the angles, to ``dps`` digits.

    mpmath.diff raises the working precision for its difference quotients, so the angles are computed at the
    ambient precision (a fixed precision inside would cap the result at ~18 digits); its step shrinks with the
    precision, so it stays inside the reach for a theta far closer to the limit than 1e-20 of it.
    """
    def part(i: int) -> Callable[[mpmath.mpf], mpmath.mpf]:
        return lambda t: _angles(g, t, branch, limit_slack)[i]

    with mpmath.workdps(dps + 20):
        x = mpmath.mpf(theta)
        dg, dd = mpmath.diff(part(0), x, order), mpmath.diff(part(1), x, order)
    with mpmath.workdps(dps):
        return +dg, +dd


def rates_numeric_mp(g: Geometry, theta: float, branch: int = 1, limit_slack: float = 0.0,
                     dps: int = DPS) -> tuple[mpmath.mpf, mpmath.mpf]:
    """(d gamma/d theta, d delta/d theta) by :func:`numeric_derivative_mp`."""
    return numeric_derivative_mp(g, theta, 1, branch, limit_slack, dps)


def second_derivatives_numeric_mp(g: Geometry, theta: float, branch: int = 1, limit_slack: float = 0.0,
                                  dps: int = DPS) -> tuple[mpmath.mpf, mpmath.mpf]:
    """(d2 gamma/d theta2, d2 delta/d theta2) by :func:`numeric_derivative_mp`."""
    return numeric_derivative_mp(g, theta, 2, branch, limit_slack, dps)


def second_derivatives_mp(g: Geometry, theta: float, branch: int = 1) -> tuple[mpmath.mpf, mpmath.mpf]:
    """The same by the implicit-function theorem: differentiating F1, F2 (see :func:`condition`) twice gives
    J (g'', d'') = (a g'^2 cos g + b d'^2 cos d + h cos t, a g'^2 sin g - b d'^2 sin d - h sin t)
    with the Jacobian J = [[-a sin g, -b sin d], [a cos g, -b cos d]] (determinant a b sin(g + d))."""
    gm, dm = rocker_angles_mp(g, theta, branch)
    with mpmath.workdps(DPS):
        _, a, h, b = _mp_lengths(g)
        t = mpmath.mpf(theta)
        dg, dd, det = _first_derivatives(g, t, gm, dm)
        w1 = -(a * dg**2 * mpmath.cos(gm) + b * dd**2 * mpmath.cos(dm) + h * mpmath.cos(t))  # minus the right side
        w2 = -(a * dg**2 * mpmath.sin(gm) - b * dd**2 * mpmath.sin(dm) - h * mpmath.sin(t))
        d2g = b * (mpmath.cos(dm) * w1 - mpmath.sin(dm) * w2) / det
        d2d = a * (mpmath.cos(gm) * w1 + mpmath.sin(gm) * w2) / det
        return d2g, d2d


def angle_error_mp(value: float, ref: mpmath.mpf) -> float:
    """|value - ref| in radians, modulo 2 pi (ref in (-pi, pi], value continuous)."""
    with mpmath.workdps(DPS):
        d = mpmath.mpf(value) - ref
        d = d - 2 * mpmath.pi * mpmath.nint(d / (2 * mpmath.pi))
        return abs(float(d))


def reach_mp(g: Geometry, dps: int = DPS) -> tuple[mpmath.mpf, mpmath.mpf]:
    """(theta_gap, theta_max) in radians: reachable iff theta_gap <= |theta| <= theta_max (mod 2 pi).

    |D'|^2 = H^2 + h^2 - 2 H h cos t grows with |t| on [0, pi]; the linkage closes iff (a - b)^2 <= |D'|^2 <= (a + b)^2.
    Raises ReferenceUnreachableError if no theta closes it.
    """
    with mpmath.workdps(dps):
        H, a, h, b = _mp_lengths(g)

        lo, hi = (a - b) ** 2, (a + b) ** 2
        if hi < (H - h) ** 2 or lo > (H + h) ** 2:
            raise ReferenceUnreachableError(f'{g.name} never assembles')
        return (clamped_acos((H * H + h * h - lo) / (2 * H * h)), clamped_acos((H * H + h * h - hi) / (2 * H * h)))


def clamped_acos(c: mpmath.mpf) -> mpmath.mpf:
    """acos(c) with c clamped to [-1, 1]: the angle of a triangle side from the law of cosines, 0 or pi at the
    ends (at the ambient precision)."""
    return mpmath.mpf(0) if c >= 1 else +mpmath.pi if c <= -1 else mpmath.acos(c)


def inward(x: mpmath.mpf, toward: float) -> float:
    """float(x), moved one ulp toward ``toward`` if rounding crossed x (so a limit rounds to the reachable side)."""
    with mpmath.workdps(DPS):
        f = float(x)
        if (toward < f and mpmath.mpf(f) > x) or (toward > f and mpmath.mpf(f) < x):
            f = math.nextafter(f, toward)
    return f


def reach_float(g: Geometry) -> tuple[float, float]:
    """(theta_gap, theta_max) rounded inward: the floats nearest the limits that are still reachable."""
    gap, top = reach_mp(g)
    return inward(gap, math.inf), inward(top, -math.inf)
