"""The general four-bar of the lecture notes: crank angle to coupler and rocker angles, velocity ratio, statics.

Every method takes a real scalar (Python int or float, numpy integer or floating scalar, 0-d array: computed as the
Python float of its value) or an array. Conventions: docs/reference/python.md; the notes' errata:
docs/explanation/errata.md."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from fourbar_ros.core.dyad import (
    Branch,
    DyadChangePointError,
    DyadConstants,
    DyadOpenError,
    ScalarClosure,
    closes,
    closure_array,
    closure_for,
    dyad_constants,
    reach_half_angles,
)
from fourbar_ros.core.errors import DeadPointError, InvalidGeometryError, SingularPositionError, UnreachableError
from fourbar_ros.core.numeric import DEAD_TOL, ArrayLike, OnInvalid, RealLike, check_length, real


class FourBarAngles(NamedTuple):
    """Coupler angle t3 and rocker angle t4 in radians (from +x, counter-clockwise)."""

    t3: ArrayLike
    t4: ArrayLike


@dataclass(frozen=True)
class FourBar:
    """A general planar four-bar (lengths in metres, any consistent unit); validated on construction.

    Assembly branch (``branch``, a :class:`~fourbar_ros.core.dyad.Branch`) of every solve: Branch.UPPER (+1) puts C to
    the left of the diagonal from B to O4 (the usual 'open' drawing of a crank-rocker with everything above the
    ground), Branch.LOWER (-1) to the right ('crossed').
    """

    ground: float
    crank: float
    coupler: float
    rocker: float
    _k: DyadConstants = field(init=False, repr=False, compare=False)
    _closure: ScalarClosure = field(init=False, repr=False, compare=False)  #: closure_for(_k)
    crank_gap: float = field(init=False, compare=False)  #: the crank closes the loop iff gap <= |t2| <= max
    crank_max: float = field(init=False, compare=False)

    def __post_init__(self) -> None:
        l1 = check_length('ground', self.ground)
        l2 = check_length('crank', self.crank)
        l3 = check_length('coupler', self.coupler)
        l4 = check_length('rocker', self.rocker)
        k = dyad_constants(l1, l2, l3, l4, unit=l1)
        try:
            gap, top = reach_half_angles(k)
        except ValueError:
            raise InvalidGeometryError(
                f'the four-bar ground={l1:.6g}, crank={l2:.6g}, coupler={l3:.6g}, rocker={l4:.6g} never '
                f'assembles: no crank angle lets the coupler and rocker close the loop') from None
        object.__setattr__(self, '_k', k)
        object.__setattr__(self, '_closure', closure_for(k))
        object.__setattr__(self, 'crank_gap', gap)
        object.__setattr__(self, 'crank_max', top)

    def __reduce__(self) -> tuple[type[FourBar], tuple[float, float, float, float]]:
        """Pickle the lengths only (the derived constants and the bound closure are rebuilt)."""
        return FourBar, (self.ground, self.crank, self.coupler, self.rocker)

    def freudenstein_constants(self) -> tuple[float, float, float]:
        """(K1, K2, K3) of Freudenstein's equation (dimensionless), in the standard form above."""
        l1, l2, l3, l4 = self.ground, self.crank, self.coupler, self.rocker
        return l1 / l2, l1 / l4, (l1 * l1 + l2 * l2 - l3 * l3 + l4 * l4) / (2.0 * l2 * l4)

    def freudenstein_residual(self, t2: RealLike, t4: RealLike) -> ArrayLike:
        """K1 cos t4 - K2 cos t2 + K3 - cos(t2 - t4): zero on any closed pose (an independent check)."""
        t2, t4 = real(t2), real(t4)
        k1, k2, k3 = self.freudenstein_constants()
        return k1 * np.cos(t4) - k2 * np.cos(t2) + k3 - np.cos(np.subtract(t2, t4))

    def is_grashof(self) -> bool:
        """Grashof's condition: shortest + longest <= sum of the other two (some link turns fully)."""
        links = sorted((self.ground, self.crank, self.coupler, self.rocker))
        return links[0] + links[3] <= links[1] + links[2]

    def angles(self, t2: RealLike, branch: Branch = Branch.UPPER, on_invalid: OnInvalid = 'raise') -> FourBarAngles:
        """Coupler and rocker angles (t3, t4) in radians for crank angle t2 (radians) on the given branch.

        Raises UnreachableError where the loop cannot close (for arrays, or NaN there with on_invalid='nan').
        """
        # The diagonal B -> O4 is the dyad's P -> Q with x = -t2; t3 is the dyad's angle at P, t4 = pi - its angle at Q.
        which = branch if type(branch) is Branch else Branch(branch)  # also takes a plain +1 / -1
        t2 = real(t2)
        if isinstance(t2, float):
            try:
                t3, q = self._closure(-t2, which)
            except DyadOpenError:
                raise self._unreachable(float(t2)) from None
            except DyadChangePointError:
                raise SingularPositionError(
                    f't2={t2!r} rad is a change point (ground = crank puts B on O4): the rocker angle is undetermined'
                ) from None
            return FourBarAngles(t3, math.pi - q)
        t = np.asarray(t2, dtype=np.float64)
        try:
            t3_a, q_a = closure_array(self._k, np.negative(t), which, on_invalid)
        except DyadOpenError:
            bad = ~closes(self._k, np.negative(t))
            raise UnreachableError(
                f'{int(bad.sum())} of {t.size} crank angles cannot close the loop, the first '
                f't2={float(t[bad].flat[0])!r}; closes for {self._describe_range()}') from None
        except DyadChangePointError:
            raise SingularPositionError('a crank angle t2 = 0 is a change point (ground = crank puts B on O4): '
                                        'the rocker angle is undetermined') from None
        return FourBarAngles(t3_a, np.subtract(np.pi, q_a, out=q_a))

    def velocity_ratio(self, t2: RealLike, branch: Branch = Branch.UPPER) -> ArrayLike:
        """dt4/dt2 = l2 sin(t2 - t3) / (l4 sin(t4 - t3)) (dimensionless, signed).

        Unbounded where the rocker is in line with the coupler (the sine is zero to within its rounding):
        scalars raise DeadPointError there, arrays give NaN.
        """
        t2 = real(t2)
        t3, t4 = self.angles(t2, branch)
        return self._ratio(t2, t3, t4, self.crank, self.rocker, 'the rocker is in line with the coupler; '
                           'dt4/dt2 is unbounded', invert=False)

    def mechanical_advantage(self, t2: RealLike, branch: Branch = Branch.UPPER) -> ArrayLike:
        """tau4/tau2 = dt2/dt4 = l4 sin(t4 - t3) / (l2 sin(t2 - t3)) by power balance (signed).

        Unbounded at the toggle where the crank is in line with the coupler: scalars raise DeadPointError there,
        arrays give NaN.
        """
        t2 = real(t2)
        t3, t4 = self.angles(t2, branch)
        return self._ratio(t2, t3, t4, self.rocker, self.crank, 'the crank is in line with the coupler; '
                           'the mechanical advantage is unbounded', invert=True)

    def _ratio(self, t2: ArrayLike, t3: ArrayLike, t4: ArrayLike, num_len: float, den_len: float, why: str,
               invert: bool) -> ArrayLike:
        """num_len sin(a - t3) / (den_len sin(b - t3)) with (a, b) = (t2, t4), or (t4, t2) when invert."""
        a, b = (t4, t2) if invert else (t2, t4)
        if isinstance(a, float) and isinstance(b, float) and isinstance(t3, float):
            den = math.sin(b - t3)
            if abs(den) <= DEAD_TOL * (1.0 + abs(b) + abs(t3)):
                raise DeadPointError(f't2={t2!r} rad: {why}')
            return num_len * math.sin(a - t3) / (den_len * den)
        with np.errstate(divide='ignore', invalid='ignore'):
            den_a = np.sin(np.subtract(b, t3))
            den_a[np.abs(den_a) <= DEAD_TOL * (1.0 + np.abs(b) + np.abs(t3))] = np.nan
            return num_len * np.sin(np.subtract(a, t3)) / (den_len * den_a)

    def _describe_range(self) -> str:
        if self.crank_gap == 0.0:
            return f'|t2| <= {self.crank_max:.12g} rad'
        return f'{self.crank_gap:.12g} <= |t2| <= {self.crank_max:.12g} rad'

    def _unreachable(self, t2: float) -> UnreachableError:
        if not math.isfinite(t2):
            return UnreachableError(f't2={t2} is not a finite angle; the loop closes for {self._describe_range()}')
        return UnreachableError(f't2={t2!r} rad cannot close the loop; it closes for {self._describe_range()}')


__all__ = ['FourBar', 'FourBarAngles']
