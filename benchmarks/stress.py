r"""Numerical stress: the shipped solver beside the annex formula (and pylinkage) on hard but valid inputs.

Every input here is reachable according to the 60-digit reference (angles are rounded toward the reachable side),
so any NaN or exception is a failure. For each case the error is divided by what the problem's conditioning
allows, nu = err / (u (kappa + |f|)) with u = 2^-53 and kappa the absolute condition number of f (gamma or delta)
for relative perturbations of every input (theta, H, AB, CD, h; see :func:`benchmarks.reference.condition`).
A backward-stable method keeps nu of order 1-10; a case with nu > NU_FLAG is reported as a defect.

Families: reach limit (relative distance 1e-1 .. 1e-16 and the last float inside; and the last float inside on
random equal-rocker geometries, where acos(Q) of the annex meets rounding), H -> h (parallelogram),
extreme link ratios, scales 1e-6 .. 1e6 m (and, beyond the specification, 1e+-150, 1e+-300 and subnormal lengths
at 1e-310), large and wrapped angles (theta + 2 pi k up to |k| = 1e15), subnormal and signed-zero angles.
"""

from __future__ import annotations

import math
import zlib
from collections.abc import Callable
from dataclasses import dataclass

import mpmath
import numpy as np

from benchmarks.cases import COMMON_GEOMETRIES, TURNANTENNA
from benchmarks.methods import NotApplicableError, Solver, annex_solver, linkage
from benchmarks.peers import pylinkage_solver
from benchmarks.reference import (
    DPS,
    UNIT_ROUNDOFF,
    Geometry,
    ReferenceSingularError,
    ReferenceUnreachableError,
    angle_error,
    condition,
    inward,
    reach_mp,
    rocker_angles_mp,
    to_double_double,
)

NU_FLAG = 32.0


@dataclass(frozen=True)
class StressCase:
    """One input: family, geometry, theta (rad, an exact float), and a note on how it was made."""

    family: str
    geometry: Geometry
    theta: float
    note: str


# ---------------------------------------------------------------------------------------------- generators

def _reach_cases(family: str, g: Geometry, distances: list[float]) -> list[StressCase]:
    gap, top = reach_mp(g)
    out = []
    with mpmath.workdps(DPS):
        for r in distances:
            if top < mpmath.pi:
                for sign in (1, -1):
                    t = inward(sign * top * (1 - mpmath.mpf(r)), 0.0)
                    out.append(StressCase(family, g, t, f'{"+" if sign > 0 else "-"}theta_max (1 - {r:g})'))
            if gap > 0:
                t = inward(gap * (1 + mpmath.mpf(r)), math.inf)
                out.append(StressCase(family, g, t, f'theta_gap (1 + {r:g})'))
    return out


REACH_DISTANCES = [10.0**-k for k in range(1, 17)] + [0.0]

UNEQUAL = Geometry('unequal-rockers', frame=0.200, rocker_ab=0.050, coupler=0.100, rocker_cd=0.070)
GAPPED = Geometry('reach-gap', frame=0.100, rocker_ab=0.030, coupler=0.090, rocker_cd=0.090)


def reach_limit_cases(quick: bool) -> list[StressCase]:
    """Toward the reach limit: theta = theta_max (1 - r) for r = 1e-1 .. 1e-16 and the last float inside."""
    dist = REACH_DISTANCES if not quick else [1e-1, 1e-4, 1e-8, 1e-12, 1e-15, 1e-16, 0.0]
    out: list[StressCase] = []
    for g in (*COMMON_GEOMETRIES[:3], UNEQUAL, GAPPED):
        out += _reach_cases('reach-limit', g, dist)
    return out


def random_equal_rocker_geometries(n: int, seed: int = 5) -> list[Geometry]:
    """n seeded random geometries with equal rockers that assemble and do not turn fully round."""
    rng = np.random.default_rng(seed)
    out: list[Geometry] = []
    while len(out) < n:
        H, h = (float(v) for v in rng.uniform(0.05, 1.0, 2))
        rocker = float(rng.uniform(0.55, 1.5) * abs(H - h) / 2 + 0.6 * min(H, h) * rng.uniform(0.1, 1.0))
        g = Geometry(f'random-{len(out)}', H, rocker, h, rocker)
        try:
            gap, top = reach_mp(g)
        except ReferenceUnreachableError:
            continue
        if gap == 0 and top < mpmath.pi:
            out.append(g)
    return out


def exact_limit_cases(quick: bool) -> list[StressCase]:
    """The last float inside +-theta_max of random equal-rocker geometries (where acos(Q) may see Q > 1)."""
    out: list[StressCase] = []
    for g in random_equal_rocker_geometries(30 if quick else 120):
        out += _reach_cases('exact-limit-random', g, [0.0])
    return out


def parallelogram_cases(quick: bool) -> list[StressCase]:
    """H = h (1 + eps) for eps = +-1e-1 .. +-1e-16 and 0, at small angles and theta = 0."""
    h = 0.1
    eps_list = [1e-1, 1e-4, 1e-8, 1e-12, 1e-16] if not quick else [1e-2, 1e-8, 1e-16]
    thetas = [1e-1, 1e-3, 1e-6, 1e-9, 1e-12] if not quick else [1e-2, 1e-6, 1e-12]
    out = []
    for eps in [0.0, *eps_list, *(-e for e in eps_list)]:
        H = h * (1.0 + eps) if abs(eps) >= 1e-15 else math.nextafter(h, math.copysign(math.inf, eps))
        if eps == 0.0:
            H = h
        g = Geometry(f'parallelogram eps={eps:g}', frame=H, rocker_ab=0.06, coupler=h, rocker_cd=0.06)
        for t in [*thetas, *(-x for x in thetas), 0.0]:  # H == h at theta = 0: singular, reported apart
            out.append(StressCase('parallelogram', g, t, f'H = h (1 + {eps:g}), theta = {t:g}'))
    return out


def ratio_geometries() -> list[Geometry]:
    """Extreme link ratios (all assemble)."""
    return [
        Geometry('coupler 1e-6 of frame', frame=1.0, rocker_ab=0.6, coupler=1e-6, rocker_cd=0.6),
        Geometry('coupler 1e6 of frame', frame=1e-6, rocker_ab=0.6, coupler=1.0, rocker_cd=0.6),
        Geometry('rockers 1e-6 of frame', frame=1.0, rocker_ab=1e-6, coupler=1.0 - 1e-6, rocker_cd=1e-6),
        Geometry('rockers 1e6 of frame', frame=1.0, rocker_ab=1e6, coupler=0.5, rocker_cd=1e6),
        Geometry('rockers 1:1e3', frame=1.0, rocker_ab=1e-3, coupler=0.5, rocker_cd=0.5),
        Geometry('rockers 1e3:1', frame=1.0, rocker_ab=0.5, coupler=0.5, rocker_cd=1e-3),
    ]


def _sample_cases(family: str, g: Geometry, n: int, extra_r: tuple[float, ...] = (1e-8,)) -> list[StressCase]:
    gap, top = reach_mp(g)
    lo, hi = float(gap), float(top)
    rng = np.random.default_rng(zlib.crc32(g.name.encode()))
    out = []
    for t in rng.uniform(lo, hi, n).tolist():
        for sign in (1.0, -1.0):
            out.append(StressCase(family, g, sign * t, 'uniform in the reachable interval'))
    out += _reach_cases(family, g, list(extra_r))
    return [c for c in out if _reachable(c.geometry, c.theta)]


def _reachable(g: Geometry, theta: float) -> bool:
    try:
        rocker_angles_mp(g, theta)
    except (ReferenceUnreachableError, ReferenceSingularError):
        return False
    return True


def ratio_cases(quick: bool) -> list[StressCase]:
    """Extreme link ratios: random reachable angles and angles 1e-8 from each limit."""
    out: list[StressCase] = []
    for g in ratio_geometries():
        out += _sample_cases('link-ratios', g, 4 if quick else 12)
    return out


def scale_cases(quick: bool) -> tuple[list[StressCase], list[StressCase]]:
    """Turnantenna scaled by 1e-6 .. 1e6 (specified) and by 1e+-150, 1e+-300, 1e-310 (subnormal lengths; beyond
    the specification)."""
    inside = [10.0**k for k in range(-6, 7, 1 if not quick else 3)]
    beyond = [1e-310, 1e-300, 1e-150, 1e150, 1e300]
    n = 3 if quick else 8
    spec = [c for s in inside for c in _sample_cases('scales', TURNANTENNA.scaled(s), n, (1e-12,))]
    far = [c for s in beyond for c in _sample_cases('scales-beyond-spec', TURNANTENNA.scaled(s), n, (1e-12,))]
    return spec, far


def wrapped_cases(quick: bool) -> list[StressCase]:
    """theta + 2 pi k for |k| up to 1e15 (rounded to float; kept where the float is reachable)."""
    ks = [1, -1, 10, -10, 1000, -1000, 10**6, -(10**6), 10**9, 10**12, 10**15, -(10**15)]
    if quick:
        ks = [1, -1000, 10**6, 10**12, 10**15]
    out = []
    for g, bases in ((TURNANTENNA, (0.3, -0.5, 0.68)), (COMMON_GEOMETRIES[3], (3.1, -3.0, 0.2))):
        for t0 in bases:
            with mpmath.workdps(DPS + 20):
                for k in ks:
                    t = float(mpmath.mpf(t0) + 2 * mpmath.pi * k)
                    c = StressCase('large-angles', g, t, f'{t0} + 2 pi * {k}')
                    if _reachable(g, t):
                        out.append(c)
    return out


def subnormal_cases(_quick: bool) -> list[StressCase]:
    """Subnormal, smallest-normal and signed-zero angles."""
    thetas = [5e-324, -5e-324, 1e-320, 1e-310, -1e-310, 2.2250738585072014e-308, 0.0, -0.0]
    out = []
    for g in (TURNANTENNA, COMMON_GEOMETRIES[1], UNEQUAL):
        for t in thetas:
            out.append(StressCase('subnormal', g, t, f'theta = {t!r}'))
    return out


# ---------------------------------------------------------------------------------------------- evaluation

Scalar = Callable[[float], tuple[float, float]]


def _solver(build: Callable[[Geometry, tuple[float, float]], Solver], g: Geometry) -> Solver | None:
    """A benchmark method on a stress geometry; None where it does not apply."""
    try:
        return build(g, (0.0, 0.0))
    except NotApplicableError:
        return None


def _call(fn: Scalar, theta: float) -> tuple[float, float] | Exception:
    """fn(theta) as two floats, or the exception it raised."""
    try:
        gamma, delta = fn(theta)
        return float(gamma), float(delta)
    except (ValueError, ArithmeticError) as exc:
        return exc


@dataclass
class Tally:
    """Per family and method: cases, worst error, worst nu, NaN and exception counts, the worst case."""

    cases: int = 0
    max_error: float = 0.0
    max_nu: float = 0.0
    nans: int = 0
    exceptions: int = 0
    worst: str = ''
    flagged: int = 0


def _nu(err: float, kappa: float, value: float) -> float:
    return err / (UNIT_ROUNDOFF * (kappa + abs(value)))


def evaluate(cases: list[StressCase]) -> tuple[dict[str, dict[str, Tally]], list[dict[str, object]],
                                                  list[dict[str, object]]]:
    """Run shipped (scalar and vector), annex (scalar and vector) and pylinkage on every case.

    Returns tallies[family][method], the flagged defects (nu > NU_FLAG, NaN or exception on a reachable input),
    and the singular cases (what each method returns where the pose is undetermined).
    """
    tallies: dict[str, dict[str, Tally]] = {}
    defects: list[dict[str, object]] = []
    singular: list[dict[str, object]] = []
    groups: dict[tuple[str, Geometry], list[StressCase]] = {}
    for c in cases:
        groups.setdefault((c.family, c.geometry), []).append(c)
    for (family, g), group in groups.items():
        fam = tallies.setdefault(family, {})
        th = np.array([c.theta for c in group])
        link, annex, pylinkage = linkage(g), _solver(annex_solver, g), _solver(pylinkage_solver, g)
        scalars: dict[str, Scalar | None] = {
            'shipped': link.rocker_angles,  # type: ignore[dict-item]
            'annex': annex and annex.scalar, 'pylinkage': pylinkage and pylinkage.scalar}
        vec_out = {'shipped-vector': link.rocker_angles(th, on_invalid='nan'),
                   'annex-vector': annex.vector(th) if annex and annex.vector else None}
        for i, c in enumerate(group):
            try:
                gm, dm = rocker_angles_mp(g, c.theta)
            except ReferenceSingularError:
                singular.append(_singular_row(c, scalars))
                continue
            g_hi, g_lo = to_double_double(gm)
            d_hi, d_lo = to_double_double(dm)
            kg, kd = condition(g, c.theta)
            outputs = {name: None if fn is None else _call(fn, c.theta) for name, fn in scalars.items()}
            for name, arrs in vec_out.items():
                outputs[name] = None if arrs is None else (float(arrs[0][i]), float(arrs[1][i]))
            for name, out in outputs.items():
                if out is None:
                    continue
                t = fam.setdefault(name, Tally())
                t.cases += 1
                if isinstance(out, Exception):
                    t.exceptions += 1
                    if name.startswith('shipped'):
                        defects.append(_defect(c, name, 'exception', f'{type(out).__name__}: {out}', g_hi, d_hi))
                    continue
                eg = float(angle_error(np.array(out[0]), np.array(g_hi), np.array(g_lo)))
                ed = float(angle_error(np.array(out[1]), np.array(d_hi), np.array(d_lo)))
                if math.isnan(eg) or math.isnan(ed):
                    t.nans += 1
                    if name.startswith('shipped'):
                        defects.append(_defect(c, name, 'NaN', repr(out), g_hi, d_hi))
                    continue
                err = max(eg, ed)
                nu = max(_nu(eg, kg, g_hi), _nu(ed, kd, d_hi))
                t.max_error = max(t.max_error, err)
                if nu > t.max_nu:
                    t.max_nu = nu
                    t.worst = f'{g.name}, theta={c.theta!r} ({c.note}): err {err:.3g} rad, kappa {max(kg, kd):.3g}'
                if nu > NU_FLAG:
                    t.flagged += 1
                    if name.startswith('shipped'):
                        defects.append(_defect(c, name, f'nu={nu:.3g} > {NU_FLAG:g}', repr(out), g_hi, d_hi,
                                               err=err, kappa=max(kg, kd)))
    return tallies, defects, singular


def _defect(c: StressCase, method: str, what: str, got: str, g_ref: float, d_ref: float,
            err: float | None = None, kappa: float | None = None) -> dict[str, object]:
    g = c.geometry
    return {
        'family': c.family, 'method': method, 'what': what, 'note': c.note,
        'geometry': {'frame': g.frame, 'rocker_ab': g.rocker_ab, 'coupler': g.coupler, 'rocker_cd': g.rocker_cd},
        'theta': c.theta, 'expected': [g_ref, d_ref], 'got': got, 'error_rad': err, 'kappa': kappa,
        'reproducer': (f'AntennaLinkage(frame={g.frame!r}, rocker_ab={g.rocker_ab!r}, coupler={g.coupler!r}, '
                       f'rocker_cd={g.rocker_cd!r}).rocker_angles({c.theta!r}'
                       f'{"" if method == "shipped" else "  # as a 1-element array"})'),
    }


def _singular_row(c: StressCase, scalars: dict[str, Scalar | None]) -> dict[str, object]:
    row: dict[str, object] = {'geometry': c.geometry.name, 'theta': c.theta}
    for name, fn in scalars.items():
        if fn is not None:
            out = _call(fn, c.theta)
            row[name] = f'{type(out).__name__}: {out}' if isinstance(out, Exception) else list(out)
    return row


def all_cases(quick: bool) -> list[StressCase]:
    """Every stress case, in family order."""
    spec, beyond = scale_cases(quick)
    return [*reach_limit_cases(quick), *exact_limit_cases(quick), *parallelogram_cases(quick), *ratio_cases(quick),
            *spec, *beyond, *wrapped_cases(quick), *subnormal_cases(quick)]


def run(quick: bool) -> dict[str, object]:
    """The stress report as a JSON-ready dict."""
    cases = all_cases(quick)
    tallies, defects, singular = evaluate(cases)
    return {
        'nu_flag': NU_FLAG,
        'cases': len(cases),
        'families': {fam: {m: vars(t) for m, t in per.items()} for fam, per in tallies.items()},
        'defects': defects,
        'singular': singular,
    }
