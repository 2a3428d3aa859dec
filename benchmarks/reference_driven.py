r"""The 60-digit reference with the driven rocker's angle as the input: the measured-linkage completion's reference.

Same conventions as :mod:`benchmarks.reference` (Annex A, eq. A.2), derived here from the loop independently of the
core's code. The driven rocker is AB (gamma = q, exact float): B = a (cos q, sin q) and D = (H, 0); C is the
meeting point of the circle (B, h) and the circle (D, b), found in Cartesian coordinates (projection p on the line
B -> D and height r off it, r > 0 on the upper branch: C to the left of B -> D, the working pose). theta and
delta are then read off C with atan2: C - B = h (cos t, -sin t), C = D + b (-cos d, sin d).

The rocker reaches q while |B - D| lies in [|h - b|, h + b], i.e. cos q in [(a^2 + H^2 - (h + b)^2) / (2 a H),
(a^2 + H^2 - (h - b)^2) / (2 a H)]: gap <= |q| <= top (mod 2 pi). At either end the coupler and the other rocker
are in line: dq/dtheta = h sin(delta - theta) / (a sin(gamma + delta)) is zero there (the driven rocker's dead
point), so theta's rate for a given q rate is unbounded and theta(q) has a square-root branch point.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import mpmath

from benchmarks.reference import DPS, Geometry, ReferenceUnreachableError, clamped_acos, inward, rocker_angles_mp


@dataclass(frozen=True)
class DrivenPose:
    """The completed pose at one driven angle q (mpf, rad): theta, the other rocker delta, and dq/dtheta.

    kappa_theta and kappa_delta (floats, rad) are the absolute condition numbers of theta and delta over the inputs
    (q, H, a, b, h), each weighted by its magnitude, as in :func:`benchmarks.reference.condition`.
    """

    theta: mpmath.mpf
    delta: mpmath.mpf
    dq_dtheta: mpmath.mpf
    kappa_theta: float
    kappa_delta: float


def _lengths(g: Geometry) -> tuple[mpmath.mpf, mpmath.mpf, mpmath.mpf, mpmath.mpf]:
    return mpmath.mpf(g.frame), mpmath.mpf(g.rocker_ab), mpmath.mpf(g.coupler), mpmath.mpf(g.rocker_cd)


def driven_pose_mp(g: Geometry, q: float, branch: int = 1) -> DrivenPose:
    """The pose for the exact float q (rad) on the given branch (+1 upper, -1 lower); raises
    ReferenceUnreachableError outside the rocker's reach. theta and delta lie in (-pi, pi]."""
    if branch not in (1, -1):
        raise ValueError(f'branch must be +1 or -1, not {branch!r}')
    with mpmath.workdps(DPS):
        H, a, h, b = _lengths(g)
        qm = mpmath.mpf(q)
        bx, by = a * mpmath.cos(qm), a * mpmath.sin(qm)
        wx, wy = H - bx, -by  # B -> D
        e2 = wx * wx + wy * wy
        e = mpmath.sqrt(e2)
        p = (h * h - b * b + e2) / (2 * e)  # C's projection on B -> D
        r2 = h * h - p * p
        if r2 < 0:
            raise ReferenceUnreachableError(f'{g.name}: q={q!r} is out of the driven rocker\'s reach')
        r = branch * mpmath.sqrt(r2)
        ux, uy = wx / e, wy / e
        cx, cy = bx + p * ux - r * uy, by + p * uy + r * ux
        t = mpmath.atan2(-(cy - by), cx - bx)
        d = mpmath.atan2(cy, H - cx)
        sgd, sdt = mpmath.sin(qm + d), mpmath.sin(d - t)
        dq_dtheta = h * sdt / (a * sgd)
        # Implicit-function derivatives of F1 = a cos g + h cos t + b cos d - H, F2 = a sin g - h sin t - b sin d
        # in (t, d): det = h b sin(t - d); column v = dF/dx for each input x, paired with |x|.
        det = h * b * mpmath.sin(t - d)
        ct, st, cd, sd, cg, sg = mpmath.cos(t), mpmath.sin(t), mpmath.cos(d), mpmath.sin(d), mpmath.cos(qm), \
            mpmath.sin(qm)
        columns = [((-a * sg, a * cg), abs(qm)), ((mpmath.mpf(-1), mpmath.mpf(0)), H), ((cg, sg), a),
                   ((cd, -sd), b), ((ct, -st), h)]
        kt = kd = mpmath.mpf(0)
        if det == 0:
            kt = kd = mpmath.inf
        else:
            for (v1, v2), x in columns:
                kt += abs(b * (cd * v1 - sd * v2) / det) * x
                kd += abs(h * (st * v2 - ct * v1) / det) * x
        return DrivenPose(t, d, dq_dtheta, float(kt), float(kd))


def driven_reach_mp(g: Geometry) -> tuple[mpmath.mpf, mpmath.mpf]:
    """(gap, top) in rad: the driven rocker AB reaches q iff gap <= |q| <= top (mod 2 pi); top = pi with no upper
    limit. Raises ReferenceUnreachableError if it reaches no angle."""
    with mpmath.workdps(DPS):
        H, a, h, b = _lengths(g)

        lo, hi = (h - b) ** 2, (h + b) ** 2  # |B - D|^2 at the two ends
        if hi < (H - a) ** 2 or lo > (H + a) ** 2:
            raise ReferenceUnreachableError(f'{g.name}: the driven rocker reaches no angle')
        return clamped_acos((a * a + H * H - lo) / (2 * a * H)), clamped_acos((a * a + H * H - hi) / (2 * a * H))


@dataclass(frozen=True)
class DrivenRange:
    """The driven rocker's working range (rad).

    ``branch`` (+1 upper, -1 lower) is the assembly holding the working pose q0 (theta = 0 on the upper theta
    branch); [lo, hi] is the reachable interval holding q0, and ``limited`` says whether both ends are reach limits
    (dead points of the driven rocker; False for a rocker turning all the way round). [mid_lo, mid_hi] is the
    mid-range: q0 plus or minus half its distance to the nearest singular point, a reach limit (dq/dtheta = 0)
    or a turning point of theta (dq/dtheta infinite: the theta reach limit, the rockers parallel).
    """

    branch: int
    lo: float
    hi: float
    limited: bool
    q0: float
    mid_lo: float
    mid_hi: float


TURNING_GRID = 256  #: samples of dq/dtheta's sign over [lo, hi] that locate theta's turning points


@functools.cache
def working_range(g: Geometry) -> DrivenRange:
    """The range of the driven rocker around the working pose (theta = 0 on the upper theta branch).

    The ends are the floats nearest the limits, rounded inward (so each is still reachable). With no upper limit
    (top = pi) and a gap the interval runs through pi: [gap, 2 pi - gap] (or its negative). Turning points are
    located to one grid step (of TURNING_GRID over the interval), on the side nearer q0.
    """
    q0_m, _ = rocker_angles_mp(g, 0.0)
    q0 = float(q0_m)
    branch = 1 if abs(driven_pose_mp(g, q0, 1).theta) < 1e-12 else -1
    gap_m, top_m = driven_reach_mp(g)
    with mpmath.workdps(DPS):
        full = top_m == mpmath.pi
        gap, top = inward(gap_m, math.inf), inward(2 * mpmath.pi - gap_m if full else top_m, -math.inf)
    if full and gap == 0.0:
        lo, hi, limited = -math.pi, math.pi, False
    elif gap == 0.0:
        lo, hi, limited = -top, top, True
    else:
        lo, hi, limited = (gap, top, True) if q0 > 0 else (-top, -gap, True)
    grid = [lo + (hi - lo) * (i + 0.5) / TURNING_GRID for i in range(TURNING_GRID)]
    signs = [mpmath.sign(driven_pose_mp(g, q, branch).dq_dtheta) for q in grid]
    below = [grid[i + 1] for i in range(TURNING_GRID - 1) if signs[i] != signs[i + 1] and grid[i + 1] <= q0]
    above = [grid[i] for i in range(TURNING_GRID - 1) if signs[i] != signs[i + 1] and grid[i] >= q0]
    half = 0.5 * min(q0 - max(below, default=lo), min(above, default=hi) - q0)
    return DrivenRange(branch, lo, hi, limited, q0, q0 - half, q0 + half)
