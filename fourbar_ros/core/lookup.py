"""A precomputed rocker-angle table over a tilt range: the cheap alternative to the exact solve, with a checked bound.

How it is built and what it costs: docs/reference/python.md and docs/benchmarks.md."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TypeVar, overload

import numpy as np
import numpy.typing as npt

from fourbar_ros.core.antenna import AntennaLinkage, Branch, RockerAngles
from fourbar_ros.core.errors import UnreachableError
from fourbar_ros.core.numeric import FloatArray, OnInvalid, RealLike, RealScalar, real

_SAMPLES_PER_INTERVAL = 16
_F = TypeVar('_F', bound=np.floating)
_new = tuple.__new__


@dataclass(frozen=True)
class RockerTable:
    """Cubic Hermite table of (gamma, delta) in radians over theta_min <= theta <= theta_max (radians).

    Interval i covers theta_min + i step .. theta_min + (i + 1) step; there, with f in [0, 1] the fraction,
    angle = c0 + f (c1 + f (c2 + f c3)) from row i of :meth:`coefficients`.
    """

    theta_min: float
    theta_max: float
    points: int
    branch: Branch
    max_error: float  #: radians, measured against the exact solver at build time (float64 evaluation)
    max_error_float32: float  #: radians, the same with float32 coefficients and arithmetic
    _gamma: FloatArray = field(repr=False, compare=False)
    _delta: FloatArray = field(repr=False, compare=False)
    _rows: tuple[tuple[tuple[float, float, float, float], tuple[float, float, float, float]], ...] = field(
        repr=False, compare=False)
    _inv_step: float = field(init=False, repr=False, compare=False)
    _columns: tuple[FloatArray, ...] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, '_inv_step', (self.points - 1) / (self.theta_max - self.theta_min))
        cols = tuple(np.ascontiguousarray(c[:, j]) for c in (self._gamma, self._delta) for j in range(4))
        object.__setattr__(self, '_columns', cols)

    @classmethod
    def build(cls, linkage: AntennaLinkage, theta_min: float, theta_max: float, tolerance: float = 1e-6,
              branch: Branch = Branch.UPPER, max_points: int = 1 << 16) -> RockerTable:
        """Tabulate ``linkage`` over [theta_min, theta_max] (radians) to within ``tolerance`` (radians).

        Raises ValueError if the interval is empty, not finite, leaves the reach, or if ``max_points`` points
        cannot meet the tolerance (an interval touching the reach limit, where the slope is unbounded).
        """
        lo, hi = float(theta_min), float(theta_max)
        if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
            raise ValueError(f'table interval [{lo!r}, {hi!r}] rad must be finite and non-empty')
        if not (math.isfinite(tolerance) and tolerance > 0.0):
            raise ValueError(f'tolerance={tolerance!r} rad must be finite and positive')
        probe = np.linspace(lo, hi, 4097)
        if not bool(np.all(linkage.reachable(probe))):
            raise ValueError(f'table interval [{lo!r}, {hi!r}] rad leaves the reach {linkage.reach().describe()}')
        n = 9
        while True:
            grid = np.linspace(lo, hi, n)
            g, d = (np.asarray(v, dtype=np.float64) for v in linkage.rocker_angles(grid, branch))
            rates = linkage.rates_at(grid, g, d)
            if not (np.all(np.isfinite(rates.dgamma_dtheta)) and np.all(np.isfinite(rates.ddelta_dtheta))):
                raise ValueError(f'table interval [{lo!r}, {hi!r}] rad touches the reach limit, where the rocker '
                                 'slopes are unbounded; keep it inside the reach')
            step = (hi - lo) / (n - 1)
            cg = hermite_coefficients(g, np.asarray(rates.dgamma_dtheta, dtype=np.float64) * step)
            cd = hermite_coefficients(d, np.asarray(rates.ddelta_dtheta, dtype=np.float64) * step)
            err64, err32 = _measure(linkage, branch, lo, step, cg, cd)
            if err64 <= 0.5 * tolerance:
                rows = tuple(zip(map(tuple, cg.tolist()), map(tuple, cd.tolist()), strict=True))
                return cls(lo, hi, n, branch, err64, err32, cg, cd, rows)
            if 2 * n - 1 > max_points:
                raise ValueError(
                    f'no table of at most {max_points} points meets {tolerance:g} rad over [{lo!r}, {hi!r}] '
                    f'(with {n} points: {err64:.3g} rad, float32 {err32:.3g} rad); '
                    'keep the interval away from the reach limit or loosen the tolerance')
            n = 2 * n - 1

    @property
    def step(self) -> float:
        """Grid spacing in radians."""
        return (self.theta_max - self.theta_min) / (self.points - 1)

    def coefficients(self) -> tuple[FloatArray, FloatArray]:
        """Copies of the (points - 1, 4) cubic coefficients for gamma and for delta (radians)."""
        return self._gamma.copy(), self._delta.copy()

    @overload
    def rocker_angles(self, theta: RealScalar, on_invalid: OnInvalid = ...) -> RockerAngles: ...
    @overload
    def rocker_angles(self, theta: FloatArray, on_invalid: OnInvalid = ...) -> RockerAngles: ...

    def rocker_angles(self, theta: RealLike, on_invalid: OnInvalid = 'raise') -> RockerAngles:
        """Interpolated (gamma, delta) in radians; within max_error of the exact solve.

        A theta outside [theta_min, theta_max] (or NaN) raises UnreachableError; for arrays with
        on_invalid='nan' those elements are NaN instead. No wrapping: the table covers its interval only.
        """
        lo, hi = self.theta_min, self.theta_max
        t = theta if type(theta) is float else real(theta)
        if isinstance(t, float):
            if not lo <= t <= hi:
                raise self._outside(t)
            u = (t - lo) * self._inv_step
            i = int(u)
            if i >= len(self._rows):
                i -= 1
            f = u - i
            (g0, g1, g2, g3), (d0, d1, d2, d3) = self._rows[i]
            # tuple.__new__ skips NamedTuple's Python-level __new__ (about half the cost of this call).
            return _new(RockerAngles, (g0 + f * (g1 + f * (g2 + f * g3)), d0 + f * (d1 + f * (d2 + f * d3))))
        th = np.asarray(t, dtype=np.float64)
        with np.errstate(invalid='ignore'):
            bad = ~((th >= lo) & (th <= hi))
        if bad.any():
            if on_invalid == 'raise':
                first = float(th[bad].flat[0])
                raise UnreachableError(f'{int(bad.sum())} of {th.size} angles lie outside the table, the first '
                                       f'theta={first!r}; table: [{lo!r}, {hi!r}] rad')
            th = np.where(bad, lo, th)
        ua = th - lo
        ua *= self._inv_step
        ia = ua.astype(np.intp)
        np.minimum(ia, self.points - 2, out=ia)
        ua -= ia  # now the fraction within the interval
        cols = self._columns
        gam = horner_columns(cols[:4], ia, ua)
        dlt = horner_columns(cols[4:], ia, ua)
        if bad.any():
            gam[bad] = np.nan
            dlt[bad] = np.nan
        return RockerAngles(gam, dlt)

    def _outside(self, theta: float) -> UnreachableError:
        return UnreachableError(f'theta={theta!r} rad lies outside the table [{self.theta_min!r}, '
                                f'{self.theta_max!r}] rad')

    def to_c(self, name: str = 'fourbar_table') -> str:
        """C99 source (float32) of the table and a lookup function ``void NAME_eval(float theta, float out[2])``.

        Its accuracy is max_error_float32 for theta inside [theta_min, theta_max]; outside, it clamps.
        """
        if not name.isidentifier():
            raise ValueError(f'name={name!r} is not a C identifier')

        def rows(c: FloatArray) -> str:
            return ',\n'.join('  {' + ', '.join(f'{v:.9e}f' for v in row) + '}' for row in c.tolist())

        n = self.points - 1
        return (
            f'/* fourbar_ros RockerTable: gamma, delta (rad) for theta in [{self.theta_min!r}, {self.theta_max!r}] '
            f'rad,\n   branch {self.branch.name}, {self.points} points, max error {self.max_error_float32:.3g} rad '
            '(float32). Generated; do not edit. */\n'
            f'static const float {name}_gamma[{n}][4] = {{\n{rows(self._gamma)}\n}};\n'
            f'static const float {name}_delta[{n}][4] = {{\n{rows(self._delta)}\n}};\n'
            f'void {name}_eval(float theta, float out[2]) {{\n'
            f'  float u = (theta - ({self.theta_min!r}f)) * {1.0 / self.step!r}f;\n'
            f'  int i = (int)u;\n  if (u < 0.0f) {{ i = 0; u = 0.0f; }}\n'
            f'  if (i > {n - 1}) {{ i = {n - 1}; }}\n  if (u > {float(n)!r}f) {{ u = {float(n)!r}f; }}\n'
            '  float f = u - (float)i;\n'
            f'  const float *g = {name}_gamma[i], *d = {name}_delta[i];\n'
            '  out[0] = g[0] + f * (g[1] + f * (g[2] + f * g[3]));\n'
            '  out[1] = d[0] + f * (d[1] + f * (d[2] + f * d[3]));\n}\n')


def hermite_coefficients(y: FloatArray, m: FloatArray) -> FloatArray:
    """Per-interval cubic Hermite coefficients, shape (y.size - 1, 4), from values y and slopes m (already times
    the step): on interval i, c0 + f (c1 + f (c2 + f c3)) with f in [0, 1]."""
    c = np.empty((y.size - 1, 4))
    y0, y1, m0, m1 = y[:-1], y[1:], m[:-1], m[1:]
    c[:, 0] = y0
    c[:, 1] = m0
    c[:, 2] = 3.0 * (y1 - y0) - 2.0 * m0 - m1
    c[:, 3] = 2.0 * (y0 - y1) + m0 + m1
    return c


def horner_columns(cols: Sequence[npt.NDArray[_F]], i: npt.NDArray[np.intp], f: npt.NDArray[_F]) -> npt.NDArray[_F]:
    """c0 + f (c1 + f (c2 + f c3)) with coefficient j gathered at indices i from cols[j] (contiguous columns
    gather fastest); computed in f's precision (float64 or float32)."""
    r = np.take(cols[3], i)
    r *= f
    r += np.take(cols[2], i)
    r *= f
    r += np.take(cols[1], i)
    r *= f
    r += np.take(cols[0], i)
    return r


def _measure(linkage: AntennaLinkage, branch: Branch, lo: float, step: float, cg: FloatArray,
             cd: FloatArray) -> tuple[float, float]:
    """Max |table - exact| (radians) at 16 interior points of every interval, float64 and float32 evaluation."""
    n = cg.shape[0]
    f = (np.arange(_SAMPLES_PER_INTERVAL) + 0.5) / _SAMPLES_PER_INTERVAL
    i = np.repeat(np.arange(n), f.size)
    ff = np.tile(f, n)
    theta = lo + (i + ff) * step
    exact = [np.asarray(v, dtype=np.float64) for v in linkage.rocker_angles(theta, branch)]
    err64 = max(float(np.max(np.abs(horner_columns(_split_columns(c), i, ff) - e)))
                for c, e in zip((cg, cd), exact, strict=True))
    # float32 all the way, as the C code of RockerTable.to_c computes: theta, index and fraction included.
    one = np.float32
    u = (theta.astype(np.float32) - one(lo)) * one(1.0 / step)
    i32 = np.clip(u.astype(np.intp), 0, n - 1)
    f32 = u - i32.astype(np.float32)
    err32 = max(float(np.max(np.abs(horner_columns(_split_columns(c.astype(np.float32)), i32, f32)
                                    .astype(np.float64) - e)))
                for c, e in zip((cg, cd), exact, strict=True))
    return err64, err32


def _split_columns(c: npt.NDArray[_F]) -> list[npt.NDArray[_F]]:
    """The four coefficient columns of a (n, 4) table."""
    return [c[:, j] for j in range(4)]
