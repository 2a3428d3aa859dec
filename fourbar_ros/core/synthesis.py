"""Freudenstein function-generator synthesis: link lengths from (crank angle, rocker angle) pairs.

The equations, the signs and what is refused: docs/how-to/design.md."""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
import numpy.typing as npt

from fourbar_ros.core.dyad import Branch
from fourbar_ros.core.errors import FourBarError, SingularPositionError, UnreachableError
from fourbar_ros.core.general import FourBar
from fourbar_ros.core.numeric import FloatArray

#: Default limit on the 2-norm condition number of the Freudenstein system. Beyond about 1/sqrt(eps) = 6.7e7 more
#: than half of the double-precision digits of the constants can be lost to rounding alone.
MAX_CONDITION = 1e8

#: Two branch solutions closer than this (rad) are one toggle position (C on the line B-O4): reported as TOGGLE.
#: Near a toggle t4 moves like the square root of a length change, so rounding of the lengths (~eps) alone moves
#: it by ~sqrt(eps) = 1.5e-8 rad (more for extreme length ratios): branch solutions closer than this cannot be
#: told apart.
TOGGLE_TOL = 1e-6

#: Safety factor on the first-order bound of the solve's rounding error (:func:`rounding_bound`), for the terms
#: of second order and a sin or cos a few ulps off (numpy's are within 1-2 ulps).
_ROUNDING_FACTOR = 4.0

#: PairCheck.branch where both branches meet (a toggle or a change point): no one Branch passes the pair.
TOGGLE: Literal[0] = 0


class DesignError(FourBarError):
    """A synthesis request that yields no linkage. The message is one line and names the value."""


class DegenerateDesignError(DesignError):
    """The positions do not determine the constants: the system is singular or badly conditioned."""


class UnbuildableDesignError(DesignError):
    """The constants exist but give a zero, negative, infinite or imaginary link length."""


@dataclass(frozen=True)
class PairCheck:
    """How the designed linkage passes one requested pair (angles in rad, as requested: before any flip).

    ``branch`` is Branch.UPPER (+1, open) or Branch.LOWER (-1, crossed) in the sense of :meth:`FourBar.angles`,
    TOGGLE (0) when the two branches meet there (a toggle: C on the line B-O4; or a change point, then t4_linkage
    and t4_error are None), None when the designed linkage cannot be assembled at that crank angle.
    ``t4_linkage`` is the rocker angle the linkage takes on that branch (None if unreachable) and ``t4_error`` its
    wrapped difference to the requested t4 (rad). ``equation_residual`` is the pair's Freudenstein residual
    ``K1 cos t4 - K2 cos t2 + K3 - cos(t2 - t4)`` (dimensionless).
    """

    t2: float
    t4: float
    branch: Branch | Literal[0] | None
    t4_linkage: float | None
    t4_error: float | None
    equation_residual: float


@dataclass(frozen=True)
class Design:
    """A synthesized linkage. Lengths in metres (all > 0), angles in rad, K1..K3 and residuals dimensionless.

    ``residual`` is the 2-norm of the Freudenstein residuals over all pairs (rounding-level for three pairs, the
    least-squares misfit for more). ``condition_number`` is the 2-norm condition number of the textbook matrix
    (cos t4_i, -cos t2_i, 1). ``sensitivity`` (1/rad) bounds, to first order, the relative change of any length per
    radian of error in the input angles (see :func:`length_sensitivity`): with angles good to e rad, the lengths
    are good to about ``sensitivity * e`` relative.
    """

    k1: float
    k2: float
    k3: float
    ground: float
    crank: float
    coupler: float
    rocker: float
    crank_flipped: bool
    rocker_flipped: bool
    condition_number: float
    sensitivity: float
    residual: float
    pairs: tuple[PairCheck, ...]

    @property
    def branch(self) -> Branch | None:
        """The branch of every pair, toggle pairs (on both) aside; None when the pairs use both branches, one is
        unreachable, or all are toggles."""
        branches = {p.branch for p in self.pairs} - {TOGGLE}
        if len(branches) == 1:
            (b,) = branches
            if isinstance(b, Branch):
                return b
        return None

    @property
    def mixed_branches(self) -> bool:
        """True when reachable pairs lie on both branches (UPPER and LOWER)."""
        branches = {p.branch for p in self.pairs}
        return Branch.UPPER in branches and Branch.LOWER in branches

    @property
    def max_t4_error(self) -> float | None:
        """Largest rocker-angle error (rad) over the pairs, None if any pair is unreachable."""
        errors = [p.t4_error for p in self.pairs]
        if any(e is None for e in errors):
            return None
        return max(e for e in errors if e is not None)

    @property
    def grashof_type(self) -> str:
        """Grashof classification of the designed lengths (which link is shortest decides the motion)."""
        return grashof_type(self.ground, self.crank, self.coupler, self.rocker)

    def linkage(self) -> FourBar:
        """The designed linkage (positive lengths; flipped links are at requested angle + pi)."""
        return FourBar(self.ground, self.crank, self.coupler, self.rocker)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary; keys K1, K2, K3, ground, crank, coupler, rocker plus diagnostics."""
        return {
            'K1': self.k1, 'K2': self.k2, 'K3': self.k3,
            'ground': self.ground, 'crank': self.crank, 'coupler': self.coupler, 'rocker': self.rocker,
            'crank_flipped': self.crank_flipped, 'rocker_flipped': self.rocker_flipped,
            'condition_number': self.condition_number,
            'sensitivity': self.sensitivity,
            'residual': self.residual,
            'max_t4_error': self.max_t4_error,
            'branch': self.branch,
            'mixed_branches': self.mixed_branches,
            'grashof_type': self.grashof_type,
            'pairs': [
                {'t2': p.t2, 't4': p.t4, 'branch': p.branch, 't4_linkage': p.t4_linkage,
                 't4_error': p.t4_error, 'equation_residual': p.equation_residual}
                for p in self.pairs
            ],
        }


def _as_pairs(pairs: Iterable[Sequence[float]]) -> FloatArray:
    """Validate pairs into an (n, 2) float array of finite angles (rad); at least three."""
    try:
        arr = np.array([tuple(p) for p in pairs], dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise DesignError(f'pairs must be (t2, t4) numbers: {exc}') from None
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise DesignError(f'each pair must hold exactly two angles (t2, t4), got shape {arr.shape}')
    if arr.shape[0] < 3:
        raise DesignError(f'need at least 3 (t2, t4) pairs for three constants, got {arr.shape[0]}')
    bad = ~np.isfinite(arr).all(axis=1)
    if bad.any():
        i = int(np.argmax(bad))
        raise DesignError(f'pair {i + 1} is not finite: ({arr[i, 0]}, {arr[i, 1]})')
    return arr


def freudenstein_system(pairs: Iterable[Sequence[float]]) -> tuple[FloatArray, FloatArray]:
    """Matrix A (n x 3) and right side b (n) with A @ (K1, K2, K3) = b for (t2, t4) pairs in rad.

    Row i is (cos t4_i, -cos t2_i, 1) and b_i = cos(t2_i - t4_i).
    """
    arr = _as_pairs(pairs)
    t2, t4 = arr[:, 0], arr[:, 1]
    a = np.column_stack([np.cos(t4), -np.cos(t2), np.ones_like(t2)])
    return a, np.cos(t2 - t4)


def _cos_diff(x: FloatArray, y: float) -> FloatArray:
    """cos x - cos y without cancellation: -2 sin((x + y)/2) sin((x - y)/2)."""
    return -2.0 * np.sin(0.5 * (x + y)) * np.sin(0.5 * (x - y))


def relative_system(pairs: Iterable[Sequence[float]]) -> tuple[FloatArray, FloatArray, FloatArray]:
    """The system actually solved: Freudenstein's equations relative to the first pair (a, b).

    Writing cos t = (cos t - cos a) + cos a (and likewise for t4 and t2 - t4) and collecting the constant terms
    into C = K3 + K1 cos b - K2 cos a - cos(a - b) gives rows
    (cos t4 - cos b, -(cos t2 - cos a), 1) . (K1, K2, C) = cos(t2 - t4) - cos(a - b).
    Each residual equals the textbook one exactly, so the exact and least-squares solutions are unchanged, but
    the cosine differences are formed as products of sines: near t = 0 or pi, where cos t is flat, the textbook
    matrix keeps only the absolute digits of cos t and loses angle information that this form keeps. Columns
    are scaled to unit 2-norm (returned as ``scale``; solve for y and take K = y / scale).
    Returns (scaled matrix, right side, scale).
    """
    arr = _as_pairs(pairs)
    t2, t4 = arr[:, 0], arr[:, 1]
    a, b = float(t2[0]), float(t4[0])
    m = np.column_stack([_cos_diff(t4, b), -_cos_diff(t2, a), np.ones_like(t2)])
    rhs = _cos_diff(t2 - t4, a - b)
    scale = np.linalg.norm(m, axis=0)
    with np.errstate(divide='ignore', invalid='ignore'):
        return m / scale, rhs, scale


def rounding_bound(pairs: FloatArray, m: FloatArray, y: npt.NDArray[np.floating[Any]], residuals: FloatArray,
                   scale: FloatArray) -> tuple[float, float]:
    """Bound on the rounding error of the solved K1 and K2 (dimensionless), from the solve's own data.

    Every entry of :func:`relative_system`'s unscaled matrix and right side is ``-2 sin(s/2) sin(d/2)`` with s, d
    sums and differences of the input angles. Each angle carries up to half an ulp (u |t|) from its own
    rounding, each sum or difference another u of its magnitude, and sin has slope <= 1; the product rounds to a
    few u of its value (<= 2). So an entry of row i is off by at most ``e_i = u (4 S_i + 10)`` with
    ``S_i = |t2_i| + |t4_i| + |a| + |b|`` ((a, b) the first pair; the right side's t2 - t4 rounds once more,
    hence 4). In the scaled system (column j divided by scale_j; the ones column is exact) that is
    ``||dm|| <= ||e|| sqrt(1/scale_0^2 + 1/scale_1^2)`` (Frobenius) and ``||drhs|| <= ||e||``, plus the
    backward error of the solve itself, 3 n u ||m||. First-order perturbation of (least-squares) solutions:

        ||dy|| <= (||dm|| ||y|| + ||drhs||) / s_min + ||dm|| ||r|| / s_min^2

    (s_min the smallest singular value of m, r the residuals; the last term is least squares' own, 0 for three
    pairs), and ``dK_j = ||dy|| / scale_j``. The bound does not shrink with y, so when the exact constants are 0
    (t4 - t2 the same at every pair) no sign or size rounding produces can pass it.
    """
    u = 0.5 * np.finfo(float).eps
    t2, t4 = pairs[:, 0], pairs[:, 1]
    magnitude = np.abs(t2) + np.abs(t4) + abs(float(t2[0])) + abs(float(t4[0]))
    entry = float(np.linalg.norm(u * (4.0 * magnitude + 10.0)))
    singular = np.linalg.svd(m, compute_uv=False)
    n = m.shape[0]
    dm = entry * math.hypot(1.0 / float(scale[0]), 1.0 / float(scale[1])) + 3.0 * n * u * float(singular[0])
    s_min = float(singular[-1])
    dy = (dm * float(np.linalg.norm(y)) + entry) / s_min + dm * float(np.linalg.norm(residuals)) / s_min ** 2
    return (_ROUNDING_FACTOR * dy / float(scale[0]), _ROUNDING_FACTOR * dy / float(scale[1]))


def solve_constants(
    pairs: Iterable[Sequence[float]], max_condition: float = MAX_CONDITION,
) -> tuple[tuple[float, float, float], float, FloatArray]:
    """Solve for (K1, K2, K3); exact for three pairs, least squares for more.

    Returns (constants, condition number, per-pair residuals). The condition number is the 2-norm one of the
    textbook matrix of :func:`freudenstein_system`; the solve itself uses :func:`relative_system`. Raises
    DegenerateDesignError when the matrix is rank-deficient (singular) or its condition number exceeds
    ``max_condition``, and UnbuildableDesignError when K1 or K2 is zero within the solve's rounding
    (:func:`rounding_bound`: an infinitely long link).
    """
    arr = _as_pairs(pairs)
    a, _ = freudenstein_system(arr)
    cond = float(np.linalg.cond(a))
    m, rhs, scale = relative_system(arr)
    if not np.all(scale > 0.0):
        which = 't4' if scale[0] == 0.0 else 't2'
        raise DegenerateDesignError(
            f'degenerate positions: cos({which}) is the same at every pair, so the Freudenstein system is singular '
            f'(condition number {cond:.3g}); choose pairs with distinct cos(t2) and cos(t4)')
    if np.linalg.matrix_rank(a) < 3 or np.linalg.matrix_rank(m) < 3 or not math.isfinite(cond):
        raise DegenerateDesignError(
            f'degenerate positions: the Freudenstein system is singular (condition number {cond:.3g}); '
            'choose pairs with distinct cos(t2) and cos(t4) that are not all on one line')
    if cond > max_condition:
        raise DegenerateDesignError(
            f'degenerate positions: the Freudenstein system is badly conditioned (condition number {cond:.3g} '
            f'> limit {max_condition:.3g}); spread the positions further apart')
    y = np.linalg.solve(m, rhs) if m.shape[0] == 3 else np.linalg.lstsq(m, rhs, rcond=None)[0]
    residuals = m @ y - rhs
    k1, k2, c = (float(v) for v in y / scale)
    # A K1 or K2 within the solve's own error has no meaningful sign or size: zero, whatever sign rounding gave it.
    bound = rounding_bound(arr, m, y, residuals, scale)
    for name, link, kv, err in (('K1', 'crank', k1, bound[0]), ('K2', 'rocker', k2, bound[1])):
        if abs(kv) <= err:
            raise UnbuildableDesignError(
                f'unbuildable: {name} = {kv:.3g} is zero within rounding (+-{err:.2g}): an infinitely long {link}')
    a0, b0 = float(arr[0, 0]), float(arr[0, 1])
    k3 = c - k1 * math.cos(b0) + k2 * math.cos(a0) + math.cos(a0 - b0)
    return (k1, k2, k3), cond, residuals


def length_sensitivity(pairs: Iterable[Sequence[float]], k1: float, k2: float, k3: float,
                       ground: float = 1.0) -> float:
    """Worst-case first-order relative change of a designed length per radian of error in the input angles.

    max over crank, coupler, rocker of sum_i |d l / d angle_i| / l (1/rad): an angle error of at most e rad in
    every t2 and t4 moves a length by at most about ``sensitivity * e`` relative. From the normal equations,
    A'A dK = -A_i' dr_i - dA_i' r_i for a change of one angle in row i (r: residuals; exact for three pairs, where
    it is -A^-1 e_i dr_i); then l2 = l1/K1, l4 = l1/K2 and l3^2 = l1^2 + l2^2 + l4^2 - 2 l2 l4 K3.
    """
    arr = _as_pairs(pairs)
    a, b = freudenstein_system(arr)
    k = np.array([k1, k2, k3])
    r = a @ k - b
    pinv = np.linalg.pinv(a)
    gram_inv = pinv @ pinv.T
    t2, t4 = arr[:, 0], arr[:, 1]
    s24 = np.sin(t2 - t4)
    columns = []
    for i in range(arr.shape[0]):
        # d/dt2 and d/dt4 of row i: (dA_i, dr_i with K held)
        for da, dr in ((np.array([0.0, math.sin(t2[i]), 0.0]), k2 * math.sin(t2[i]) + s24[i]),
                       (np.array([-math.sin(t4[i]), 0.0, 0.0]), -k1 * math.sin(t4[i]) - s24[i])):
            columns.append(-pinv[:, i] * dr - gram_inv @ da * r[i])
    dk1, dk2, dk3 = np.array(columns).T
    l2, l4 = ground / k1, ground / k2
    l3 = math.sqrt(max(ground * ground + l2 * l2 + l4 * l4 - 2.0 * l2 * l4 * k3, np.finfo(float).tiny))
    dl2, dl4 = -l2 * dk1 / k1, -l4 * dk2 / k2
    dl3 = (l2 * dl2 + l4 * dl4 - k3 * (l4 * dl2 + l2 * dl4) - l2 * l4 * dk3) / l3
    return float(max(np.abs(dl2 / l2).sum(), np.abs(dl3 / l3).sum(), np.abs(dl4 / l4).sum()))


def lengths_from_constants(
    k1: float, k2: float, k3: float, ground: float = 1.0, allow_flip: bool = False,
    pairs: Iterable[Sequence[float]] | None = None,
) -> tuple[float, float, float, bool, bool]:
    """Link lengths (crank, coupler, rocker) in the unit of ``ground`` from the constants, plus the flip flags.

    Returns (crank, coupler, rocker, crank_flipped, rocker_flipped); lengths are positive. Raises
    UnbuildableDesignError for K1 or K2 zero, a negative one without ``allow_flip``, or a zero coupler.
    (:func:`solve_constants` already refuses a K1 or K2 that is zero within the solve's rounding.)

    Without ``pairs`` the coupler is sqrt(l1^2 + l2^2 + l4^2 - 2 l2 l4 K3). With the (t2, t4) pairs the constants
    were solved from, it is sqrt(mean_i |l2 e^(i t2_i) - l1 - l4 e^(i t4_i)|^2), the root mean square of the
    B-C distances: the same number in exact arithmetic (the exact or least-squares residuals of Freudenstein's
    equation sum to zero, and each is (d_i^2 - l3^2) / (2 l2 l4)), but free of the cancellation in K3 that costs
    a short coupler its digits (the rounding of K3 alone is amplified by about l2 l4 K3 / l3^2).
    """
    if not (math.isfinite(ground) and ground > 0.0):
        raise DesignError(f'ground length must be finite and > 0, got {ground}')
    for name, link, kv in (('K1', 'crank', k1), ('K2', 'rocker', k2)):
        if kv == 0.0 or not math.isfinite(ground / kv):
            raise UnbuildableDesignError(f'unbuildable: {name} = {kv:.6g} gives an infinitely long {link}')
        if kv < 0.0 and not allow_flip:
            raise UnbuildableDesignError(
                f'unbuildable: {name} = {kv:.6g} < 0 gives {link} length {ground / kv:.6g}; the {link} would point '
                'opposite (angle + pi) to the requested angles (allow_flip / --allow-flip accepts that)')
    l2 = ground / k1  # signed: the sign is the flip
    l4 = ground / k2
    if pairs is None:
        coupler_sq = ground * ground + l2 * l2 + l4 * l4 - 2.0 * l2 * l4 * k3
    else:
        arr = _as_pairs(pairs)
        t2, t4 = arr[:, 0], arr[:, 1]
        dx = l2 * np.cos(t2) - ground - l4 * np.cos(t4)
        dy = l2 * np.sin(t2) - l4 * np.sin(t4)
        coupler_sq = float(np.mean(dx * dx + dy * dy))
    if not coupler_sq > 0.0 or not math.isfinite(coupler_sq):
        raise UnbuildableDesignError(
            f'unbuildable: K3 = {k3:.6g} gives coupler length squared {coupler_sq:.6g} (no coupler: B and C '
            'coincide)')
    return abs(l2), math.sqrt(coupler_sq), abs(l4), l2 < 0.0, l4 < 0.0


def _wrap(angle: float) -> float:
    """Angle wrapped into (-pi, pi] (rad)."""
    return math.atan2(math.sin(angle), math.cos(angle))


def _check_pair(fb: FourBar, t2: float, t4: float, crank_flipped: bool, rocker_flipped: bool,
                residual: float) -> PairCheck:
    """Run the linkage at the pair's crank angle on both branches and find which one gives the requested t4."""
    t2_phys = t2 + math.pi if crank_flipped else t2
    shift = math.pi if rocker_flipped else 0.0
    found: dict[Branch, tuple[float, float]] = {}  # branch -> (t4 in the request's convention, |error|)
    for branch in (Branch.UPPER, Branch.LOWER):
        try:
            t4_branch = float(fb.angles(t2_phys, branch=branch)[1]) - shift
        except UnreachableError:
            continue
        except SingularPositionError:  # change point: B on O4, the rocker angle is undetermined
            return PairCheck(t2, t4, TOGGLE, None, None, residual)
        found[branch] = (t4_branch, abs(_wrap(t4_branch - t4)))
    if not found:
        return PairCheck(t2, t4, None, None, None, residual)
    best = min(found, key=lambda b: found[b][1])
    t4_lin, err = found[best]
    if len(found) == 2 and abs(_wrap(found[Branch.UPPER][0] - found[Branch.LOWER][0])) <= TOGGLE_TOL:
        return PairCheck(t2, t4, TOGGLE, _wrap(t4_lin), err, residual)
    return PairCheck(t2, t4, best, _wrap(t4_lin), err, residual)


def grashof_type(ground: float, crank: float, coupler: float, rocker: float) -> str:
    """Grashof class: 'crank-rocker', 'double-crank', 'rocker-crank', 'double-rocker' (Grashof),
    'change-point' (s + l = p + q, to rounding) or 'triple-rocker' (non-Grashof)."""
    links = {'ground': ground, 'crank': crank, 'coupler': coupler, 'rocker': rocker}
    ordered = sorted(links.values())
    lhs, rhs = ordered[0] + ordered[3], ordered[1] + ordered[2]
    if abs(lhs - rhs) <= 8.0 * np.finfo(float).eps * rhs:
        return 'change-point'
    if lhs > rhs:
        return 'triple-rocker'
    shortest = min(links, key=lambda name: links[name])
    return {'ground': 'double-crank', 'crank': 'crank-rocker', 'rocker': 'rocker-crank',
            'coupler': 'double-rocker'}[shortest]


def synthesize(
    pairs: Iterable[Sequence[float]], ground: float = 1.0, *, max_condition: float = MAX_CONDITION,
    allow_flip: bool = False,
) -> Design:
    """Design a four-bar whose rocker takes angle t4 when the crank is at t2, for each (t2, t4) pair (rad).

    Three pairs: exact solution. More: least squares, misfit in ``Design.residual``. ``ground`` sets the scale
    (metres). The result is verified by running the designed linkage through :meth:`FourBar.angles` on both
    branches at every pair (see :class:`PairCheck`). Raises DegenerateDesignError or UnbuildableDesignError
    (both DesignError, a FourBarError) with a one-line message.
    """
    arr = _as_pairs(pairs)
    (k1, k2, k3), cond, residuals = solve_constants(arr, max_condition)
    crank, coupler, rocker, crank_flip, rocker_flip = lengths_from_constants(k1, k2, k3, ground, allow_flip, arr)
    fb = FourBar(ground, crank, coupler, rocker)
    checks = tuple(
        _check_pair(fb, float(t2), float(t4), crank_flip, rocker_flip, float(r))
        for (t2, t4), r in zip(arr, residuals, strict=True)
    )
    return Design(
        k1=k1, k2=k2, k3=k3, ground=float(ground), crank=crank, coupler=coupler, rocker=rocker,
        crank_flipped=crank_flip, rocker_flipped=rocker_flip, condition_number=cond,
        sensitivity=length_sensitivity(arr, k1, k2, k3, ground),
        residual=float(np.linalg.norm(residuals)), pairs=checks,
    )
