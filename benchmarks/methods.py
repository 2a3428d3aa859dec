r"""The position solvers compared by the benchmark: theta (rad) -> (gamma, delta) (rad), upper branch.

Every method is a :class:`Method` whose ``build(geometry, interval)`` returns a :class:`Solver` bound to one
geometry: a scalar callable (Python float in, two floats out) and/or a vectorized one (float64 array in, two
arrays out). ``interval`` is the (lo, hi) range of theta the method is asked to serve (tables, Newton's start).
The list is :func:`all_methods`, each with its description; the report says what each family is.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from benchmarks.reference import Geometry
from fourbar_ros.core.antenna import AntennaLinkage
from fourbar_ros.core.dyad import DyadConstants, dyad_constants
from fourbar_ros.core.lookup import hermite_coefficients, horner_columns

FloatArray = npt.NDArray[np.float64]
ScalarFn = Callable[[float], tuple[float, float]]
VectorFn = Callable[[FloatArray], tuple[npt.NDArray[np.floating], npt.NDArray[np.floating]]]


class NotApplicableError(Exception):
    """The method does not apply to this geometry (e.g. the annex formula with unequal rockers)."""


@dataclass(frozen=True)
class Solver:
    """One method bound to one geometry. Either callable may be None when the method has no such path."""

    scalar: ScalarFn | None
    vector: VectorFn | None


@dataclass(frozen=True)
class Method:
    """A named position solver: ``build(geometry, (lo, hi))`` -> Solver (may raise NotApplicableError)."""

    name: str
    family: str
    dtype: str
    description: str
    build: Callable[[Geometry, tuple[float, float]], Solver]


def linkage(g: Geometry) -> AntennaLinkage:
    """The core's linkage object for a benchmark geometry."""
    return AntennaLinkage(frame=g.frame, rocker_ab=g.rocker_ab, coupler=g.coupler, rocker_cd=g.rocker_cd)


def stable_constants(g: Geometry) -> DyadConstants:
    """The core's constants of its stable form for a benchmark geometry, in frame units (as AntennaLinkage's)."""
    return dyad_constants(g.frame, g.coupler, g.rocker_ab, g.rocker_cd, unit=g.frame)


# ---------------------------------------------------------------------------------------------- annex formula

def _annex(atan2_fix: bool = False, dtype: type[np.floating] = np.float64) -> Callable[[Geometry, tuple[float, float]],
                                                                                    Solver]:
    """A.13-A.15 as written (``atan2_fix``: atan2(h sin t, H - h cos t) for atan P), every operation in ``dtype``;
    the scalar path (Python floats) in float64 only."""

    def build(g: Geometry, _interval: tuple[float, float]) -> Solver:
        if not g.equal_rockers:
            raise NotApplicableError('the annex formula assumes equal rockers')
        f = dtype
        H, h, ll = f(g.frame), f(g.coupler), f(g.rocker_ab)
        with np.errstate(over='ignore'):  # lengths beyond the specification overflow, as in Python floats
            hh, two_hh, two_l2 = H * H + h * h, f(2) * H * h, f(2) * ll * ll
        one, half, two = f(1), f(0.5), f(2)

        def vector(theta: FloatArray) -> tuple[npt.NDArray[np.floating], npt.NDArray[np.floating]]:
            th = theta.astype(dtype, copy=False)
            with np.errstate(invalid='ignore', divide='ignore'):
                c = np.cos(th)
                y, x = h * np.sin(th), H - h * c
                t = two * (np.arctan2(y, x) if atan2_fix else np.arctan(y / x))
                a = np.arccos((hh - two_hh * c) / two_l2 - one)
            return half * (t + a), half * (a - t)

        if dtype is not np.float64:
            return Solver(None, vector)
        Hs, hs, hhs, two_hhs, two_l2s = float(H), float(h), float(hh), float(two_hh), float(two_l2)
        atan, atan2, acos, sin, cos = math.atan, math.atan2, math.acos, math.sin, math.cos

        def scalar(theta: float) -> tuple[float, float]:  # each variant inline: a call per solve would be timed too
            c = cos(theta)
            a = acos((hhs - two_hhs * c) / two_l2s - 1.0)
            t = 2.0 * atan(hs * sin(theta) / (Hs - hs * c))
            return 0.5 * (t + a), 0.5 * (a - t)

        def scalar_atan2(theta: float) -> tuple[float, float]:
            c = cos(theta)
            a = acos((hhs - two_hhs * c) / two_l2s - 1.0)
            t = 2.0 * atan2(hs * sin(theta), Hs - hs * c)
            return 0.5 * (t + a), 0.5 * (a - t)

        return Solver(scalar_atan2 if atan2_fix else scalar, vector)

    return build


annex_solver = _annex()


# ---------------------------------------------------------------------------------------------- the core

def _shipped(g: Geometry, _interval: tuple[float, float]) -> Solver:
    link = linkage(g)
    solve = link.rocker_angles
    return Solver(solve, solve)  # type: ignore[arg-type]


def _stable_f32(g: Geometry, _interval: tuple[float, float]) -> Solver:
    """The half-angle / factored-Heron / atan2 form, every operation in float32 (lengths in frame units)."""
    f = np.float32
    k = stable_constants(g)
    diff, four_l1_l2, two_l2, far, near = (f(v) for v in (k.diff, k.four_l1_l2, k.two_l2, k.far, k.near))
    r_sq_diff = f(0.5 * (k.cos_p - k.cos_q))  # (AB^2 - CD^2) / H^2
    half = f(0.5)

    def vector(theta: FloatArray) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.float32]]:
        t = theta.astype(np.float32) * half
        s, c = np.sin(t), np.cos(t)
        w = four_l1_l2 * s * s
        prod = np.maximum(far - w, f(0)) * np.maximum(near + w, f(0))
        root = np.sqrt(prod)
        diag = diff * diff + w
        phi = np.arctan2(two_l2 * s * c, diff + two_l2 * s * s)
        alpha = np.arctan2(root, diag + r_sq_diff)
        beta = np.arctan2(root, diag - r_sq_diff)
        return phi + alpha, beta - phi

    return Solver(None, vector)


# ---------------------------------------------------------------------------------------------- Newton

def newton_functions(g: Geometry, interval: tuple[float, float], iterations: int) -> tuple[
        Callable[..., tuple[float, float]], Callable[..., tuple[FloatArray, FloatArray]]]:
    """``iterations`` Newton steps on the loop-closure equations, scalar and vectorized: ``f(theta, gam, dlt)``
    from (gam, dlt) (rad), by default the solution at the middle of ``interval`` (a cold start)."""
    H, a, h, b = g.frame, g.rocker_ab, g.coupler, g.rocker_cd
    g0, d0 = (float(v) for v in linkage(g).rocker_angles(0.5 * (interval[0] + interval[1])))
    sin, cos = math.sin, math.cos
    ab = a * b

    def scalar(theta: float, gam: float = g0, dlt: float = d0) -> tuple[float, float]:
        hc, hs = h * cos(theta), h * sin(theta)
        for _ in range(iterations):  # inline, as the vector path's: a call per step would be timed too
            cg, sg, cd, sd = cos(gam), sin(gam), cos(dlt), sin(dlt)
            f1 = a * cg + hc + b * cd - H
            f2 = a * sg - hs - b * sd
            det = ab * (sg * cd + cg * sd)
            gam += b * (cd * f1 - sd * f2) / det
            dlt += a * (cg * f1 + sg * f2) / det
        return gam, dlt

    def vector(theta: FloatArray, gam: FloatArray | None = None,
               dlt: FloatArray | None = None) -> tuple[FloatArray, FloatArray]:
        hc, hs = h * np.cos(theta), h * np.sin(theta)
        gam = np.full_like(theta, g0) if gam is None else gam
        dlt = np.full_like(theta, d0) if dlt is None else dlt
        for _ in range(iterations):
            cg, sg, cd, sd = np.cos(gam), np.sin(gam), np.cos(dlt), np.sin(dlt)
            f1 = a * cg + hc + b * cd - H
            f2 = a * sg - hs - b * sd
            det = ab * (sg * cd + cg * sd)
            gam += b * (cd * f1 - sd * f2) / det
            dlt += a * (cg * f1 + sg * f2) / det
        return gam, dlt

    return scalar, vector


def _newton(iterations: int) -> Callable[[Geometry, tuple[float, float]], Solver]:
    return lambda g, interval: Solver(*newton_functions(g, interval, iterations))


def loop_residual(g: Geometry, theta: FloatArray, gam: FloatArray, dlt: FloatArray) -> tuple[FloatArray, FloatArray]:
    """The two loop-closure equations Newton drives to zero (metres): x and y of C(left chain) - C(right chain)."""
    H, a, h, b = g.frame, g.rocker_ab, g.coupler, g.rocker_cd
    return (a * np.cos(gam) + h * np.cos(theta) + b * np.cos(dlt) - H,
            a * np.sin(gam) - h * np.sin(theta) - b * np.sin(dlt))


# ---------------------------------------------------------------------------------------------- tables

@dataclass(frozen=True)
class Table:
    """Uniform table over [lo, hi]: per-interval cubic coefficients c0 + f (c1 + f (c2 + f c3)), f in [0, 1]."""

    lo: float
    inv_step: float
    n: int
    gamma: npt.NDArray[np.floating]  #: shape (n - 1, 4)
    delta: npt.NDArray[np.floating]


def build_table(g: Geometry, interval: tuple[float, float], n: int, hermite: bool,
                dtype: type[np.floating] = np.float64) -> Table:
    """Tabulate the core's solution at n angles; linear tables leave c2 = c3 = 0."""
    lo, hi = interval
    grid = np.linspace(lo, hi, n)
    link = linkage(g)
    gam, dlt = (np.asarray(v) for v in link.rocker_angles(grid))
    step = (hi - lo) / (n - 1)

    def linear(y: FloatArray) -> FloatArray:
        c = np.zeros((n - 1, 4))
        c[:, 0] = y[:-1]
        c[:, 1] = y[1:] - y[:-1]
        return c

    if hermite:  # fourbar_ros.core.lookup's coefficients, from the core's rates times the step
        rates = link.rates_at(grid, gam, dlt)
        cg = hermite_coefficients(gam, np.asarray(rates.dgamma_dtheta) * step)
        cd = hermite_coefficients(dlt, np.asarray(rates.ddelta_dtheta) * step)
    else:
        cg, cd = linear(gam), linear(dlt)
    return Table(lo, 1.0 / step, n, cg.astype(dtype), cd.astype(dtype))


def _lut(n: int, hermite: bool, dtype: type[np.floating] = np.float64,
         polish: bool = False) -> Callable[[Geometry, tuple[float, float]], Solver]:
    def build(g: Geometry, interval: tuple[float, float]) -> Solver:
        tab = build_table(g, interval, n, hermite, dtype)
        last = n - 2
        cg_list = tab.gamma.astype(np.float64).tolist()
        cd_list = tab.delta.astype(np.float64).tolist()
        lo, inv = tab.lo, tab.inv_step
        is64 = dtype is np.float64

        def scalar(theta: float) -> tuple[float, float]:
            u = (theta - lo) * inv
            i = int(u)
            if i < 0:
                i = 0
            elif i > last:
                i = last
            f = u - i
            g0, g1, g2, g3 = cg_list[i]
            d0, d1, d2, d3 = cd_list[i]
            if hermite:  # inline, as lookup's own scalar path: a call per element would be timed, not the table
                return g0 + f * (g1 + f * (g2 + f * g3)), d0 + f * (d1 + f * (d2 + f * d3))
            return g0 + f * g1, d0 + f * d1

        lo_t, inv_t = dtype(lo), dtype(inv)
        cols_g = [np.ascontiguousarray(tab.gamma[:, j]) for j in range(4)]
        cols_d = [np.ascontiguousarray(tab.delta[:, j]) for j in range(4)]
        grid = lo + np.arange(n) / inv
        ends_g = np.append(cols_g[0], cols_g[0][-1] + cols_g[1][-1])
        ends_d = np.append(cols_d[0], cols_d[0][-1] + cols_d[1][-1])

        def vector(theta: FloatArray) -> tuple[npt.NDArray[np.floating], npt.NDArray[np.floating]]:
            if is64 and not hermite:  # numpy's own linear interpolation is the fastest float64 table here
                gam, dlt = np.interp(theta, grid, ends_g), np.interp(theta, grid, ends_d)
            else:
                u = theta.astype(dtype)
                u -= lo_t
                u *= inv_t
                i = u.astype(np.intp)
                np.clip(i, 0, last, out=i)
                u -= i
                if hermite:
                    gam, dlt = horner_columns(cols_g, i, u), horner_columns(cols_d, i, u)
                else:
                    gam = np.take(cols_g[1], i)
                    gam *= u
                    gam += np.take(cols_g[0], i)
                    dlt = np.take(cols_d[1], i)
                    dlt *= u
                    dlt += np.take(cols_d[0], i)
            return gam, dlt

        if polish:
            newton_scalar, newton_vector = newton_functions(g, interval, 1)
            return Solver(lambda theta: newton_scalar(theta, *scalar(theta)),
                          lambda theta: newton_vector(theta, *vector(theta)))
        return Solver(scalar if is64 else None, vector)

    return build


def _lookup(tolerance: float) -> Callable[[Geometry, tuple[float, float]], Solver]:
    """The offered fourbar_ros.core.lookup.RockerTable, built over the interval to the given tolerance (radians)."""

    def build(g: Geometry, interval: tuple[float, float]) -> Solver:
        from fourbar_ros.core.lookup import RockerTable

        table = RockerTable.build(linkage(g), interval[0], interval[1], tolerance=tolerance)
        return Solver(table.rocker_angles, table.rocker_angles)  # type: ignore[arg-type]

    return build


# ---------------------------------------------------------------------------------------------- the list

SHIPPED = 'shipped'
NEWTON_ITERATIONS = (1, 2, 3, 4, 5, 6, 8)
LINEAR_SIZES = (64, 256, 1024, 4096, 16384, 65536)
HERMITE_SIZES = (16, 64, 256, 1024, 4096)


def all_methods(quick: bool = False) -> list[Method]:
    """Every method of the common sweep (ours and the formula of the annex; peers are in benchmarks.peers)."""
    methods = [
        Method('annex', 'annex', 'float64', 'Annex A.13-A.15 as written (atan P, acos Q)', annex_solver),
        Method('annex-atan2', 'annex', 'float64', 'annex with atan2 for atan P (acos Q kept)', _annex(True)),
        Method('annex-f32', 'annex', 'float32', 'annex as written, float32 arrays', _annex(dtype=np.float32)),
        Method(SHIPPED, 'shipped', 'float64', 'fourbar_ros AntennaLinkage.rocker_angles', _shipped),
        Method('stable-f32', 'stable', 'float32', "the core's stable form transcribed in float32", _stable_f32),
    ]
    for k in NEWTON_ITERATIONS if not quick else (1, 2, 4, 8):
        methods.append(Method(f'newton-{k}', 'newton', 'float64',
                              f'{k} Newton step(s) on the loop closure, cold start at mid-interval', _newton(k)))
    for n in LINEAR_SIZES if not quick else (256, 4096, 65536):
        methods.append(Method(f'lut-linear-{n}', 'lut', 'float64', f'{n}-point table, linear', _lut(n, False)))
    for n in HERMITE_SIZES if not quick else (64, 1024):
        methods.append(Method(f'lut-hermite-{n}', 'lut', 'float64', f'{n}-point table, cubic Hermite',
                              _lut(n, True)))
    for n in (256, 4096) if not quick else (4096,):
        methods.append(Method(f'lut-linear-{n}-f32', 'lut', 'float32', f'{n}-point float32 table, linear',
                              _lut(n, False, np.float32)))
    methods.append(Method('lut-hermite-256-f32', 'lut', 'float32', '256-point float32 table, cubic Hermite',
                          _lut(256, True, np.float32)))
    for tol in (1e-6, 1e-9):
        methods.append(Method(f'lookup-{tol:g}', 'lookup', 'float64',
                              f'fourbar_ros.core.lookup.RockerTable built to {tol:g} rad', _lookup(tol)))
    methods.append(Method('lut-linear-256+newton1', 'hybrid', 'float64',
                          '256-point linear table, then one Newton step', _lut(256, False, polish=True)))
    return methods
