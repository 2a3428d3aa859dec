"""Accuracy over the common sweep, and time per solve on the Turnantenna geometry, for every method.

Error: max over gamma and delta, over every geometry of :mod:`benchmarks.cases`, over both the scalar and the
vectorized path, of |method - reference| (radians, modulo 2 pi). A NaN or an exception on a reachable angle makes
the error infinite (the method failed on an input it must serve).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from benchmarks.cases import COMMON_GEOMETRIES, TURNANTENNA, sweep_angles, sweep_interval
from benchmarks.methods import Method, NotApplicableError, Solver, linkage, stable_constants
from benchmarks.reference import Geometry, ReferenceArrays, angle_error, reference_arrays
from benchmarks.timing import Case, interleaved, pilot, scalar_loop

FloatArray = npt.NDArray[np.float64]


@dataclass
class MethodResult:
    """Figures of one method; None where the method has no such path or does not apply."""

    name: str
    family: str
    dtype: str
    description: str
    max_error_scalar_path: float | None = None
    max_error_vector_path: float | None = None
    max_error_per_geometry: dict[str, float | None] = field(default_factory=dict)
    nan_count: int = 0
    exception_count: int = 0
    not_applicable: list[str] = field(default_factory=list)
    seconds_per_solve_scalar: float | None = None
    seconds_per_solve_vector: float | None = None
    wall_seconds_per_solve_scalar: float | None = None
    wall_seconds_per_solve_vector: float | None = None
    n_scalar: int = 0
    n_vector: int = 0
    pareto: bool = False
    pareto_scalar: bool = False

    @property
    def max_error(self) -> float | None:
        """Worst of the two paths (None if the method produced nothing)."""
        vals = [v for v in (self.max_error_scalar_path, self.max_error_vector_path) if v is not None]
        return max(vals) if vals else None


def _error(out: tuple[object, object], ref: ReferenceArrays) -> tuple[float, int]:
    g = np.asarray(out[0], dtype=np.float64)
    d = np.asarray(out[1], dtype=np.float64)
    eg = angle_error(g, ref.gamma_hi, ref.gamma_lo)
    ed = angle_error(d, ref.delta_hi, ref.delta_lo)
    nans = int(np.count_nonzero(np.isnan(eg) | np.isnan(ed)))
    if nans:
        return math.inf, nans
    return float(max(eg.max(), ed.max())), 0


def _scalar_outputs(solver: Solver, thetas: FloatArray) -> tuple[tuple[FloatArray, FloatArray], int]:
    assert solver.scalar is not None
    gs = np.empty(thetas.size)
    ds = np.empty(thetas.size)
    exceptions = 0
    for i, t in enumerate(thetas.tolist()):
        try:
            gs[i], ds[i] = solver.scalar(t)
        except (ValueError, ZeroDivisionError, ArithmeticError):
            exceptions += 1
            gs[i] = ds[i] = math.nan
    return (gs, ds), exceptions


def accuracy(methods: list[Method], n_angles: int) -> tuple[list[MethodResult], dict[str, object]]:
    """Errors of every method over the common sweep; also returns a description of the sweep."""
    refs: dict[str, tuple[FloatArray, ReferenceArrays]] = {}
    for g in COMMON_GEOMETRIES:
        th = np.sort(sweep_angles(g, n_angles))
        refs[g.name] = (th, reference_arrays(g, th))
    results = []
    for m in methods:
        r = MethodResult(m.name, m.family, m.dtype, m.description)
        worst_s: list[float] = []
        worst_v: list[float] = []
        for g in COMMON_GEOMETRIES:
            th, ref = refs[g.name]
            try:
                solver = m.build(g, sweep_interval(g))
            except NotApplicableError as exc:
                r.not_applicable.append(f'{g.name}: {exc}')
                r.max_error_per_geometry[g.name] = None
                continue
            errs = []
            if solver.scalar is not None:
                out, exc_count = _scalar_outputs(solver, th)
                e, nans = _error(out, ref)
                r.exception_count += exc_count
                r.nan_count += nans - exc_count
                worst_s.append(e)
                errs.append(e)
            if solver.vector is not None:
                try:
                    e, nans = _error(solver.vector(th), ref)
                except (ValueError, ArithmeticError):
                    e, nans = math.inf, 0
                    r.exception_count += 1
                r.nan_count += nans
                worst_v.append(e)
                errs.append(e)
            r.max_error_per_geometry[g.name] = max(errs) if errs else None
        r.max_error_scalar_path = max(worst_s) if worst_s else None
        r.max_error_vector_path = max(worst_v) if worst_v else None
        results.append(r)
    info = {
        'geometries': [
            {'name': g.name, 'frame': g.frame, 'rocker_ab': g.rocker_ab, 'coupler': g.coupler,
             'rocker_cd': g.rocker_cd, 'interval_rad': list(sweep_interval(g))}
            for g in COMMON_GEOMETRIES],
        'angles_per_geometry': n_angles,
        'order': 'ascending (an ascending sweep, as a controller traces a trajectory)',
    }
    return results, info


def floor_inputs(g: Geometry, theta: FloatArray) -> tuple[FloatArray, ...]:
    """The arrays the stable form feeds to its unavoidable ufuncs, from the core's constants, outside any timing.

    half = theta/2; prod = far * near (the factored Heron product, >= 0 inside the reach); (y, x) of the
    diagonal's direction phi; (root, x) of the triangle's angle alpha. Equal rockers: alpha serves both rockers.
    """
    k = stable_constants(g)
    half = 0.5 * theta
    s, c = np.sin(half), np.cos(half)
    w = k.four_l1_l2 * s * s
    prod = np.maximum(k.far - w, 0.0) * np.maximum(k.near + w, 0.0)
    y_phi, x_phi = k.two_l2 * s * c, k.diff + k.two_l2 * s * s
    return half, prod, y_phi, x_phi, np.sqrt(prod), k.cos_p + w


def floor_ufuncs(inputs: tuple[FloatArray, ...]) -> object:
    """The numpy ufuncs the stable form cannot avoid for equal rockers, each once on its full-size input array.

    sin and cos of the half angle, one square root (the factored Heron root) and two atan2 (the diagonal's
    direction and the triangle's angle), on the very values the stable form computes (atan2's speed depends on
    its arguments); nothing else, no arithmetic between them. Outputs are freshly allocated, as a method's are.
    """
    half, prod, y_phi, x_phi, root, x_alpha = inputs
    return np.sin(half), np.cos(half), np.sqrt(prod), np.arctan2(y_phi, x_phi), np.arctan2(root, x_alpha)


def stable_plain_scalar(g: Geometry) -> Callable[[float], tuple[float, float]]:
    """The stable form's math for equal or unequal rockers (upper branch) as a bare closure returning a plain tuple.

    No validation, no clamping, no NamedTuple: a lower bound for any scalar path that evaluates the stable form
    in CPython (sin, cos, sqrt and two or three atan2 of the half-angle diagonal and the factored Heron root).
    """
    k = stable_constants(g)
    diff, two_l2, far0, near0, cos_p, cos_q, equal = k.diff, k.two_l2, k.far, k.near, k.cos_p, k.cos_q, k.equal_links
    sin, cos, sqrt, atan2 = math.sin, math.cos, math.sqrt, math.atan2

    def solve(theta: float) -> tuple[float, float]:
        half = 0.5 * theta
        s = sin(half)
        hs = two_l2 * s
        w = 2.0 * hs * s
        root = sqrt((far0 - w) * (near0 + w))
        phi = atan2(hs * cos(half), diff + hs * s)
        alpha = atan2(root, cos_p + w)
        beta = alpha if equal else atan2(root, cos_q + w)
        return phi + alpha, beta - phi

    return solve


def timings(methods: list[Method], results: list[MethodResult], n_scalar: int, n_vector: int,
            repeats: int) -> dict[str, float]:
    """Fill seconds_per_solve_* on the Turnantenna geometry; returns the baselines measured in the same rounds.

    Baselines: ``floor`` (see :func:`floor_ufuncs`, per element of the n_vector array), ``python_call`` (the
    scalar loop calling a function that returns a tuple, per call) and ``array_path_one`` (the shipped solver
    called with a one-element array, per call: what its math-module scalar path saves); CPU-time medians, with
    ``*_wall`` beside.
    """
    g = TURNANTENNA
    interval = sweep_interval(g)
    thetas = np.sort(sweep_angles(g, n_vector, seed=7))
    scalar_thetas = np.sort(sweep_angles(g, n_scalar, seed=8)).tolist()
    by_name = {r.name: r for r in results}
    one_angle = linkage(g).rocker_angles
    scalar_cases = [Case('python_call', scalar_loop(lambda t: (t, t), scalar_thetas), n_scalar),
                    Case('stable_plain', scalar_loop(stable_plain_scalar(g), scalar_thetas), n_scalar),
                    Case('array_path_one', scalar_loop(lambda t: one_angle(np.array([t])), scalar_thetas),
                         n_scalar)]
    inputs = floor_inputs(g, thetas)
    vector_cases = [Case('floor', lambda: floor_ufuncs(inputs), n_vector)]
    for m in methods:
        try:
            solver = m.build(g, interval)
        except NotApplicableError:
            continue
        if solver.scalar is not None:
            fn = solver.scalar
            per = pilot(lambda fn=fn: fn(scalar_thetas[1]))  # type: ignore[misc]
            n = max(20, min(n_scalar, int(0.02 / max(per, 1e-9))))
            sub = scalar_thetas[:: max(1, n_scalar // n)][:n]
            scalar_cases.append(Case(m.name, scalar_loop(fn, sub), len(sub)))
            by_name[m.name].n_scalar = len(sub)
        if solver.vector is not None:
            vec = solver.vector
            small = thetas[:: max(1, n_vector // 1000)]
            per = pilot(lambda vec=vec, small=small: vec(small)) / small.size  # type: ignore[misc]
            n = max(1000, min(n_vector, int(0.25 / max(per, 1e-12))))
            arr = thetas if n >= n_vector else np.ascontiguousarray(thetas[:: n_vector // n][:n])
            vector_cases.append(Case(m.name, lambda vec=vec, arr=arr: vec(arr), arr.size))  # type: ignore[misc]
            by_name[m.name].n_vector = arr.size
    s_times = interleaved(scalar_cases, repeats)
    v_times = interleaved(vector_cases, repeats)
    for path, times in (('scalar', s_times), ('vector', v_times)):
        for name, (cpu, wall) in times.items():
            if name in by_name:
                setattr(by_name[name], f'seconds_per_solve_{path}', cpu)
                setattr(by_name[name], f'wall_seconds_per_solve_{path}', wall)
    measured = {'floor_per_element': v_times['floor'], 'python_call_per_call': s_times['python_call'],
                'stable_plain_scalar_per_call': s_times['stable_plain'],
                'array_path_one_angle_per_call': s_times['array_path_one']}
    return {**{k: cpu for k, (cpu, _) in measured.items()}, **{f'{k}_wall': wall for k, (_, wall) in measured.items()}}


def dominates(a: tuple[float, float], b: tuple[float, float]) -> bool:
    """(time, error) a is no slower and no less accurate than b, and strictly better in one of the two."""
    return a[0] <= b[0] and a[1] <= b[1] and a != b


def pareto_front(points: Sequence[tuple[str, float | None, float | None]]) -> set[str]:
    """Names of the non-dominated (time, error) points; points with a None or non-finite value are excluded."""
    valid = {n: (t, e) for n, t, e in points if t is not None and e is not None and math.isfinite(t)
             and math.isfinite(e)}
    return {n for n, p in valid.items() if not any(dominates(q, p) for m, q in valid.items() if m != n)}


def dominators(results: list[MethodResult], name: str, vector: bool = True) -> list[str]:
    """Methods that dominate ``name`` (used to explain a shipped method off the front)."""
    def point(r: MethodResult) -> tuple[float, float] | None:
        t = r.seconds_per_solve_vector if vector else r.seconds_per_solve_scalar
        return None if t is None or r.max_error is None else (t, r.max_error)

    me = point(next(r for r in results if r.name == name))
    return [f'{r.name} ({p[0]:.3g} s, {p[1]:.3g} rad)' for r in results
            if r.name != name and me is not None and (p := point(r)) is not None and dominates(p, me)]
