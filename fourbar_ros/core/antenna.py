"""The antenna's tilt linkage (Turnantenna, Annex A): antenna angle theta to rocker angles, rates and torque.

Every method takes a real scalar (a Python int or float, a numpy integer or floating scalar of any width, a 0-d
array: computed as the Python float of its value, on the math-module fast path, and answered with floats) or a numpy
array (vectorized, same shape). The geometry, sign conventions and units: docs/reference/python.md."""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field
from typing import NamedTuple, overload

import numpy as np
import numpy.typing as npt

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
from fourbar_ros.core.numeric import (
    DEAD_TOL,
    ArrayLike,
    FloatArray,
    OnInvalid,
    RealLike,
    RealScalar,
    check_length,
    real,
)

__all__ = [
    'AntennaLinkage', 'Branch', 'Driven', 'InverseSolution', 'LinkageState', 'Reach', 'RockerAngles', 'RockerRates',
    'RockerSecondDerivatives',
]

_TWO_PI = 2.0 * math.pi


class Driven(enum.Enum):
    """Which rocker the motor drives: GAMMA is AB (pivot A), DELTA is CD (pivot D)."""

    GAMMA = 'gamma'
    DELTA = 'delta'


class RockerAngles(NamedTuple):
    """Rocker angles in radians (see the module docstring for their definition)."""

    gamma: ArrayLike
    delta: ArrayLike


_new_tuple = tuple.__new__  # builds a RockerAngles without NamedTuple._make's Python-level length check


class RockerRates(NamedTuple):
    """Rocker rates per unit antenna rate, d gamma/d theta and d delta/d theta (dimensionless)."""

    dgamma_dtheta: ArrayLike
    ddelta_dtheta: ArrayLike


class RockerSecondDerivatives(NamedTuple):
    """d2 gamma/d theta2 and d2 delta/d theta2 (rad/rad^2): the rockers' angular accelerations per unit antenna
    rate squared (at constant antenna rate)."""

    d2gamma_dtheta2: ArrayLike
    d2delta_dtheta2: ArrayLike


class InverseSolution(NamedTuple):
    """Antenna angle theta and the other (not measured) rocker's angle, radians, wrapped to [-pi, pi]."""

    theta: ArrayLike
    other: ArrayLike


class LinkageState(NamedTuple):
    """Everything known at one antenna angle: angles in rad, rates dimensionless, torque in N m.

    mechanical_advantage is d q/d theta of the driven rocker q (signed); input_torque is the torque the driven
    rocker needs, in the sense of increasing q, to hold the load torque (applied in the sense of increasing theta);
    transmission_angle is the angle in [0, pi] between the coupler and the non-driven rocker (pi/2 is ideal).
    """

    theta: ArrayLike
    gamma: ArrayLike
    delta: ArrayLike
    dgamma_dtheta: ArrayLike
    ddelta_dtheta: ArrayLike
    mechanical_advantage: ArrayLike
    input_torque: ArrayLike
    transmission_angle: ArrayLike


@dataclass(frozen=True)
class Reach:
    """Reachable antenna angles: theta_gap <= |theta| <= theta_max (radians, modulo 2 pi).

    theta_gap is 0 unless the rockers differ by more than |frame - coupler|; theta_max is pi when the coupler can
    turn all the way round.
    """

    theta_gap: float
    theta_max: float
    name: str = 'theta'  #: the angle's name in messages (a rocker's reach names the rocker)

    def contains(self, theta: float) -> bool:
        """True if theta (radians, finite) is reachable; NaN and inf are not."""
        if not math.isfinite(theta):
            return False
        t = abs(math.remainder(theta, _TWO_PI))
        return self.theta_gap <= t <= self.theta_max

    def describe(self) -> str:
        """The interval(s) in radians and degrees, for messages."""
        def fmt(x: float) -> str:
            return f'{x:.12g} rad ({math.degrees(x):.6g} deg)'

        if self.theta_gap == 0.0:
            return f'[{fmt(-self.theta_max)}, {fmt(self.theta_max)}]'
        return f'{fmt(self.theta_gap)} <= |{self.name}| <= {fmt(self.theta_max)}'


@dataclass(frozen=True)
class AntennaLinkage:
    """The antenna's four-bar: frame AD, rockers AB and CD, coupler BC carrying the antenna (lengths in metres).

    rocker_cd defaults to rocker_ab (the annex's equal rockers). Construction validates the geometry and raises
    InvalidGeometryError if a length is not finite and positive or if the linkage can never assemble.
    """

    frame: float
    rocker_ab: float
    coupler: float
    rocker_cd: float | None = None
    _cd: float = field(init=False, repr=False, compare=False)  #: rocker_cd, resolved
    _k: DyadConstants = field(init=False, repr=False, compare=False)
    _closure: ScalarClosure = field(init=False, repr=False, compare=False)  #: closure_for(_k)
    _reach: Reach = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        frame = check_length('frame', self.frame)
        ab = check_length('rocker_ab', self.rocker_ab)
        coupler = check_length('coupler', self.coupler)
        cd = ab if self.rocker_cd is None else check_length('rocker_cd', self.rocker_cd)
        object.__setattr__(self, 'rocker_cd', cd)
        object.__setattr__(self, '_cd', cd)
        # Angles depend only on length ratios: work in units of the frame so no scale can overflow.
        # The coupler's angle theta passes 0 in normal use: keep the angles continuous there.
        k = dyad_constants(frame, coupler, ab, cd, unit=frame, continuous_at_zero=True)
        try:
            gap, top = reach_half_angles(k)
        except ValueError:
            raise InvalidGeometryError(_never_assembles(frame, ab, coupler, cd)) from None
        object.__setattr__(self, '_k', k)
        object.__setattr__(self, '_closure', closure_for(k))
        object.__setattr__(self, '_reach', Reach(theta_gap=gap, theta_max=top))

    def __reduce__(self) -> tuple[type[AntennaLinkage], tuple[float, float, float, float | None]]:
        """Pickle the lengths only (the derived constants and the bound closure are rebuilt)."""
        return AntennaLinkage, (self.frame, self.rocker_ab, self.coupler, self.rocker_cd)

    # ---------------------------------------------------------------- reach

    def reach(self) -> Reach:
        """The reachable antenna angles of this geometry, in closed form."""
        return self._reach

    @overload
    def reachable(self, theta: RealScalar) -> bool: ...
    @overload
    def reachable(self, theta: FloatArray) -> npt.NDArray[np.bool_]: ...

    def reachable(self, theta: RealLike) -> bool | npt.NDArray[np.bool_]:
        """Does rocker_angles solve theta (radians)? False for NaN, inf and out-of-reach values; a bool for a
        scalar, element-wise for an array. Change points count as reachable.

        The very test the solver applies, scalar or vectorized (so it agrees with rocker_angles, and with
        on_invalid='nan', to the last float at the limits).
        """
        t = real(theta)
        if type(t) is float:
            try:
                self._closure(t, Branch.UPPER)
            except DyadOpenError:
                return False
            except DyadChangePointError:
                pass
            return True
        return closes(self._k, np.asarray(t, dtype=np.float64))

    def _unreachable(self, theta: float) -> UnreachableError:
        if math.isnan(theta):
            return UnreachableError(f'theta={theta} is not a number; reachable: {self._reach.describe()}')
        if math.isinf(theta):
            return UnreachableError(f'theta={theta} is not finite; reachable: {self._reach.describe()}')
        return UnreachableError(
            f'theta={theta!r} rad ({math.degrees(theta):.6g} deg) is out of reach; '
            f'reachable: {self._reach.describe()}')

    def _change_point(self, theta: float) -> SingularPositionError:
        return SingularPositionError(
            f'theta={theta!r} rad is a change point of this linkage (frame = coupler and AB = CD make a '
            f'parallelogram there): the rocker angles are undetermined')

    def _invalid_array(self, theta: FloatArray) -> UnreachableError:
        """The one-line error for an array with unsolvable angles (the error path: recomputes the whole mask)."""
        bad = ~closes(self._k, theta)
        return UnreachableError(
            f'{int(bad.sum())} of {theta.size} angles cannot be solved, the first theta={float(theta[bad][0])!r}; '
            f'reachable: {self._reach.describe()}')

    # ---------------------------------------------------------------- positions

    @overload
    def rocker_angles(self, theta: RealScalar, branch: Branch = ..., on_invalid: OnInvalid = ...) -> RockerAngles: ...
    @overload
    def rocker_angles(self, theta: FloatArray, branch: Branch = ..., on_invalid: OnInvalid = ...) -> RockerAngles: ...

    def rocker_angles(self, theta: RealLike, branch: Branch = Branch.UPPER,
                      on_invalid: OnInvalid = 'raise') -> RockerAngles:
        """Rocker angles (gamma, delta) in radians for antenna angle theta (radians) on the given branch.

        Scalars raise UnreachableError for NaN, inf or an out-of-reach theta, and SingularPositionError at a
        change point (frame = coupler, AB = CD, theta = 0: a parallelogram whose rocker angle is undetermined;
        also within ~1e-154 rad of it, where 4 H h sin^2(theta/2) underflows).
        Arrays raise the same for any such element when on_invalid='raise', or return NaN at exactly those
        elements when on_invalid='nan' (reachable(theta) is the validity mask, change points aside). The exact
        reach limit is solved (the rockers are then in line).
        """
        if type(theta) is not float:
            theta = real(theta)
        if type(theta) is float:
            # The scalar hot path: the dyad's math-module closure, no numpy (theta is the dyad's angle x).
            try:
                return _new_tuple(RockerAngles, self._closure(theta, branch))
            except DyadOpenError:
                raise self._unreachable(theta) from None
            except DyadChangePointError:
                raise self._change_point(theta) from None
        t = np.asarray(theta, dtype=np.float64)
        try:
            return RockerAngles(*closure_array(self._k, t, branch, on_invalid))
        except DyadOpenError:
            raise self._invalid_array(t) from None
        except DyadChangePointError as exc:
            raise self._change_point(exc.x) from None

    # ---------------------------------------------------------------- rates

    def rocker_rates(self, theta: RealLike, branch: Branch = Branch.UPPER,
                     on_invalid: OnInvalid = 'raise') -> RockerRates:
        """d gamma/d theta and d delta/d theta at theta (radians) on the given branch.

        From differentiating the loop: d gamma/d theta = h sin(delta - theta) / (AB sin(gamma + delta)) and
        d delta/d theta = -h sin(gamma + theta) / (CD sin(gamma + delta)). Both are unbounded at the reach limit,
        where gamma + delta is 0 or pi: scalars raise SingularPositionError there; arrays give inf.
        """
        theta = real(theta)
        g, d = self.rocker_angles(theta, branch, on_invalid)
        return self.rates_at(theta, g, d)

    def rates_at(self, theta: RealLike, gamma: RealLike, delta: RealLike) -> RockerRates:
        """Rocker rates from an already solved pose (theta, gamma, delta in radians)."""
        h = self.coupler
        if not (type(theta) is float and type(gamma) is float and type(delta) is float):
            theta, gamma, delta = real(theta), real(gamma), real(delta)
        if isinstance(theta, float) and isinstance(gamma, float) and isinstance(delta, float):
            den = math.sin(gamma + delta)
            if den == 0.0:
                raise SingularPositionError(
                    f'theta={theta!r} rad is at the reach limit: the rocker rates are unbounded there')
            return RockerRates(h * math.sin(delta - theta) / (self.rocker_ab * den),
                               -h * math.sin(gamma + theta) / (self._cd * den))
        with np.errstate(divide='ignore', invalid='ignore'):
            den_a = np.sin(np.add(gamma, delta))
            return RockerRates(h * np.sin(np.subtract(delta, theta)) / (self.rocker_ab * den_a),
                               -h * np.sin(np.add(gamma, theta)) / (self._cd * den_a))

    def rocker_second_derivatives(self, theta: RealLike, branch: Branch = Branch.UPPER,
                                  on_invalid: OnInvalid = 'raise') -> RockerSecondDerivatives:
        """d2 gamma/d theta2 and d2 delta/d theta2 (rad/rad^2) at theta (radians) on the given branch.

        Unbounded at the reach limit (like the rates; they grow as 1/sin^3(gamma + delta)): scalars raise
        SingularPositionError there; arrays give NaN where sin(gamma + delta) is exactly 0 (the sign of the
        unbounded value is that of the side the limit is approached from, which the pose alone does not tell).
        """
        theta = real(theta)
        g, d = self.rocker_angles(theta, branch, on_invalid)
        return self.second_derivatives_at(theta, g, d)

    def second_derivatives_at(self, theta: RealLike, gamma: RealLike, delta: RealLike,
                              rates: RockerRates | None = None) -> RockerSecondDerivatives:
        """Both second derivatives (rad/rad^2) from an already solved pose (rad) and, if given, its rates_at."""
        g2, d2 = self._second(theta, gamma, delta, rates, True, True)
        return RockerSecondDerivatives(g2, d2)  # type: ignore[arg-type]

    def second_derivative_at(self, theta: RealLike, gamma: RealLike, delta: RealLike, rates: RockerRates | None,
                             rocker: Driven) -> ArrayLike:
        """d2 q/d theta2 (rad/rad^2) of one rocker q (gamma or delta) only; see second_derivatives_at."""
        want_g = rocker is Driven.GAMMA
        g2, d2 = self._second(theta, gamma, delta, rates, want_g, not want_g)
        return g2 if want_g else d2  # type: ignore[return-value]

    def _second(self, theta: RealLike, gamma: RealLike, delta: RealLike, rates: RockerRates | None,
                want_g: bool, want_d: bool) -> tuple[ArrayLike | None, ArrayLike | None]:
        r"""The loop differentiated twice. With X = gamma + delta and the rates g', d':

            AB g'' sin X = -(h cos(delta - theta) + AB g'^2 cos X + CD d'^2)
            CD d'' sin X = -(h cos(gamma + theta) + AB g'^2 + CD d'^2 cos X)

        For cos X < 0 the terms can cancel (as X -> pi, the rockers folding), but not beyond the condition: their
        rounding acts as a relative eps on the lengths, and near either limit it stays below the effect of the
        angles' own rounding on sin X (relative 3 eps / |sin X|). test_core_precision holds both paths to 8 ulps of
        that condition against the 60-digit reference, at either limit and near it.
        """
        a, b, h = self.rocker_ab, self._cd, self.coupler
        theta, gamma, delta = real(theta), real(gamma), real(delta)
        if rates is None:
            rates = self.rates_at(theta, gamma, delta)
        g1, d1 = (real(r) for r in rates)
        if isinstance(theta, float) and isinstance(gamma, float) and isinstance(delta, float):
            x = gamma + delta
            sx = math.sin(x)
            if sx == 0.0:
                raise SingularPositionError(
                    f'theta={theta!r} rad is at the reach limit: the rocker second derivatives are unbounded there')
            cx = math.cos(x)
            ag, bd = a * g1 * g1, b * d1 * d1
            return ((-(h * math.cos(delta - theta) + (ag * cx + bd)) / (a * sx) if want_g else None),
                    (-(h * math.cos(gamma + theta) + (bd * cx + ag)) / (b * sx) if want_d else None))
        with np.errstate(divide='ignore', invalid='ignore', over='ignore'):
            xa = np.add(gamma, delta)
            s_x = np.sin(xa)
            c_x = np.cos(xa)
            a_g = a * np.multiply(g1, g1)
            b_d = b * np.multiply(d1, d1)
            limit = s_x == 0.0
            g2 = d2 = None
            if want_g:
                g2 = np.where(limit, np.nan, -(h * np.cos(np.subtract(delta, theta)) + (a_g * c_x + b_d)) / (a * s_x))
            if want_d:
                d2 = np.where(limit, np.nan, -(h * np.cos(np.add(gamma, theta)) + (b_d * c_x + a_g)) / (b * s_x))
        return g2, d2

    def rocker_velocities(self, theta: RealLike, theta_rate: RealLike,
                          branch: Branch = Branch.UPPER) -> RockerRates:
        """Rocker angular velocities (rad/s) for an antenna angular velocity theta_rate (rad/s) at theta (rad)."""
        theta_rate = real(theta_rate)
        r = self.rocker_rates(theta, branch)
        return RockerRates(r.dgamma_dtheta * theta_rate, r.ddelta_dtheta * theta_rate)

    # ---------------------------------------------------------------- statics

    def mechanical_advantage(self, theta: RealLike, driven: Driven = Driven.GAMMA,
                             branch: Branch = Branch.UPPER) -> ArrayLike:
        """d q/d theta of the driven rocker q: the antenna torque held per unit torque at the rocker (signed).

        Positive for gamma, negative for delta (the rockers turn in opposite senses). Unbounded at the reach
        limit (scalars raise SingularPositionError there), zero at a dead point.
        """
        rates = self.rocker_rates(theta, branch)
        return rates.dgamma_dtheta if driven is Driven.GAMMA else rates.ddelta_dtheta

    def input_torque(self, theta: RealLike, load_torque: RealLike, driven: Driven = Driven.GAMMA,
                     branch: Branch = Branch.UPPER) -> ArrayLike:
        """Torque in N m the driven rocker needs (in the sense of increasing q) to hold load_torque.

        load_torque (N m) acts on the antenna in the sense of increasing theta. By power balance
        tau_in dq = tau_load dtheta, so tau_in = tau_load dtheta/dq. At a dead point (the non-driven rocker in
        line with the coupler) no torque can hold the antenna: scalars raise DeadPointError; arrays give NaN
        exactly there (np.isfinite is the validity mask).
        """
        theta = real(theta)
        g, d = self.rocker_angles(theta, branch)
        return self.torque_at(theta, g, d, load_torque, driven)

    def torque_at(self, theta: RealLike, gamma: RealLike, delta: RealLike, load_torque: RealLike,
                  driven: Driven = Driven.GAMMA) -> ArrayLike:
        """Input torque (N m) from an already solved pose; see input_torque.

        Driving gamma: tau_load AB sin(gamma + delta) / (h sin(delta - theta)); driving delta:
        -tau_load CD sin(gamma + delta) / (h sin(gamma + theta)). A dead point is where that sine is zero to
        within its own rounding (a few ulps of the angles): the torque has no correct digit there.
        """
        gamma_driven = driven is Driven.GAMMA
        lever = (self.rocker_ab if gamma_driven else -self._cd) / self.coupler
        if not (type(theta) is float and type(gamma) is float and type(delta) is float):
            theta, gamma, delta = real(theta), real(gamma), real(delta)
        if isinstance(theta, float) and isinstance(gamma, float) and isinstance(delta, float):
            q = delta if gamma_driven else gamma
            q_rate = math.sin(q - theta if gamma_driven else q + theta)
            if abs(q_rate) <= DEAD_TOL * (1.0 + abs(q) + abs(theta)):
                raise DeadPointError(
                    f'theta={theta!r} rad is a dead point for the {driven.value} rocker: the {_other(driven)} '
                    f'rocker is in line with the coupler, so no finite torque holds the antenna')
            return float(real(load_torque)) * lever * math.sin(gamma + delta) / q_rate
        q_a = np.asarray(delta if gamma_driven else gamma)
        with np.errstate(divide='ignore', invalid='ignore'):
            q_rate_a = np.sin(np.subtract(q_a, theta) if gamma_driven else np.add(q_a, theta))
            q_rate_a[np.abs(q_rate_a) <= DEAD_TOL * (1.0 + np.abs(q_a) + np.abs(theta))] = np.nan
            tau: FloatArray = np.multiply(real(load_torque), lever * np.sin(np.add(gamma, delta))) / q_rate_a
        return tau

    def transmission_angle(self, theta: RealLike, driven: Driven = Driven.GAMMA,
                           branch: Branch = Branch.UPPER) -> ArrayLike:
        """Angle in [0, pi] (rad) at the joint between the coupler and the non-driven rocker.

        Driving gamma, this is the angle at C between CB and CD; driving delta, the angle at B between BA and BC.
        pi/2 transmits best; 0 or pi is a dead point.
        """
        theta = real(theta)
        g, d = self.rocker_angles(theta, branch)
        return self.transmission_angle_at(theta, g, d, driven)

    def transmission_angle_at(self, theta: RealLike, gamma: RealLike, delta: RealLike,
                              driven: Driven = Driven.GAMMA) -> ArrayLike:
        """Transmission angle (rad) from an already solved pose; see transmission_angle."""
        if not (type(theta) is float and type(gamma) is float and type(delta) is float):
            theta, gamma, delta = real(theta), real(gamma), real(delta)
        if isinstance(theta, float) and isinstance(gamma, float) and isinstance(delta, float):
            x = delta - theta if driven is Driven.GAMMA else gamma + theta
            return math.atan2(abs(math.sin(x)), -math.cos(x))
        xa = np.subtract(delta, theta) if driven is Driven.GAMMA else np.add(gamma, theta)
        return np.arctan2(np.abs(np.sin(xa)), -np.cos(xa))

    def state(self, theta: RealLike, load_torque: RealLike = 0.0, driven: Driven = Driven.GAMMA,
              branch: Branch = Branch.UPPER, on_invalid: OnInvalid = 'raise') -> LinkageState:
        """Pose, rates, mechanical advantage, input torque (N m) and transmission angle, solving the pose once."""
        theta = real(theta)
        g, d = self.rocker_angles(theta, branch, on_invalid)
        rates = self.rates_at(theta, g, d)
        ma = rates.dgamma_dtheta if driven is Driven.GAMMA else rates.ddelta_dtheta
        return LinkageState(theta, g, d, rates.dgamma_dtheta, rates.ddelta_dtheta, ma,
                            self.torque_at(theta, g, d, load_torque, driven),
                            self.transmission_angle_at(theta, g, d, driven))

    # ---------------------------------------------------------------- inverse

    def rocker_reach(self, driven: Driven = Driven.GAMMA) -> Reach:
        """The angles (rad, modulo 2 pi) the given rocker can take: its gap and maximum, named after the rocker.

        Exactly what from_rocker takes: it solves every q this reach contains and refuses every other q (one ulp
        beyond either end included) with UnreachableError. The ends are the closed form of the exact geometry,
        rounded once (within an ulp or two of the true limit).
        """
        return self._rocker_dyad(driven)[2]

    def from_rocker(self, q: RealLike, driven: Driven = Driven.GAMMA,
                    branch: Branch = Branch.UPPER, on_invalid: OnInvalid = 'raise') -> InverseSolution:
        """Antenna angle and the other rocker's angle (radians) from a measured rocker angle q (radians).

        The motor side knows its rocker; this is the four-bar with that rocker as the crank. Branch.UPPER puts C
        to the left of the line from B to D when gamma is measured (B to the left of C to A when delta is), which
        is the annex's working pose; Branch.LOWER is the crossed pose. Raises UnreachableError if the rocker cannot
        take q: NaN, inf, or any q that ``rocker_reach(driven).contains`` refuses, to the last float (for arrays:
        if any element cannot, unless on_invalid='nan', which gives NaN there). At the reach's ends the pose is
        the dead point to within rounding.
        """
        # The four-bar with the measured rocker as crank: its diagonal (rocker end -> other pivot) is the dyad's
        # P -> Q with x = -q; the dyad's angle at P is the coupler's direction from +x (-theta with AB as the crank,
        # +theta mirrored, CD as the crank) and its angle at Q is the other rocker's angle.
        k, closure, reach = self._rocker_dyad(driven)
        which = branch if type(branch) is Branch else Branch(branch)  # also takes a plain +1 / -1
        sign = -1.0 if driven is Driven.GAMMA else 1.0
        if type(q) is not float:
            q = real(q)
        if isinstance(q, float):
            top = reach.theta_max
            # The reach decides (the closure's rounding allowance would take a few ulps beyond it); the full test
            # (modulo 2 pi, the gap) only off the common case.
            if not (-top <= q <= top and reach.theta_gap == 0.0) and not reach.contains(q):
                raise self._rocker_unreachable(driven, q)
            try:
                coupler_dir, other = closure(-q, which)
            except DyadOpenError:
                raise self._rocker_unreachable(driven, q) from None
            except DyadChangePointError:
                raise self._rocker_change_point(driven, q) from None
            return InverseSolution(_wrap(sign * coupler_dir), _wrap(other))
        qa = np.asarray(q, dtype=np.float64)
        outside = _outside(reach, qa)
        try:
            if on_invalid == 'raise' and outside.any():
                raise DyadOpenError
            coupler_a, other_a = closure_array(k, np.negative(qa), which, on_invalid)
        except DyadOpenError:
            bad = outside | ~closes(k, np.negative(qa))
            raise UnreachableError(
                f'{int(bad.sum())} of {qa.size} {driven.value} angles cannot be taken, the first '
                f'q={float(qa[bad].flat[0])!r}; the {driven.value} rocker takes {_describe_rocker(reach)}') from None
        except DyadChangePointError as exc:
            raise self._rocker_change_point(driven, -exc.x) from None
        if outside.any():
            coupler_a[outside] = np.nan
            other_a[outside] = np.nan
        return InverseSolution(_wrap(sign * coupler_a), _wrap(other_a))

    def _rocker_dyad(self, driven: Driven) -> tuple[DyadConstants, ScalarClosure, Reach]:
        """The dyad of the four-bar with the measured rocker as its crank, its scalar closure and the rocker's reach
        (built once per rocker)."""
        built: dict[Driven, tuple[DyadConstants, ScalarClosure, Reach]] = self.__dict__.setdefault(
            '_rocker_dyads', {})
        if driven not in built:  # per instance, not global; the exact constants cost ~20 us
            crank, rocker = (self.rocker_ab, self._cd) if driven is Driven.GAMMA else (self._cd, self.rocker_ab)
            k = dyad_constants(self.frame, crank, self.coupler, rocker, unit=self.frame)
            gap, top = reach_half_angles(k)
            built[driven] = (k, closure_for(k), Reach(theta_gap=gap, theta_max=top, name=driven.value))
        return built[driven]

    def _rocker_unreachable(self, driven: Driven, q: float) -> UnreachableError:
        return UnreachableError(f'q={q!r} rad: the {driven.value} rocker cannot take this angle; it takes '
                                f'{_describe_rocker(self._rocker_dyad(driven)[2])}')

    def _rocker_change_point(self, driven: Driven, q: float) -> SingularPositionError:
        return SingularPositionError(
            f'q={q!r} rad is a change point of the {driven.value} rocker (as long as the frame, it puts its end on '
            f'the other pivot): the antenna angle is undetermined')


def _describe_rocker(reach: Reach) -> str:
    gap, top = reach.theta_gap, reach.theta_max
    if gap == 0.0:
        return f'|q| <= {top:.12g} rad'
    return f'{gap:.12g} <= |q| <= {top:.12g} rad'


def _outside(reach: Reach, x: FloatArray) -> npt.NDArray[np.bool_]:
    """Element-wise: not reach.contains(x) (x in rad; NaN and inf are outside), to the last float as it."""
    with np.errstate(invalid='ignore'):
        t = np.fmod(np.abs(x), _TWO_PI)  # exact, as is 2 pi - t for t > pi (Sterbenz): |remainder(x, 2 pi)|
        t = np.minimum(t, _TWO_PI - t)
        return ~((t >= reach.theta_gap) & (t <= reach.theta_max))


def _wrap(x: ArrayLike) -> ArrayLike:
    """Wrap an angle (radians) to [-pi, pi]."""
    if isinstance(x, float):
        return math.remainder(x, _TWO_PI)
    return np.remainder(x + np.pi, _TWO_PI) - np.pi


def _other(driven: Driven) -> str:
    return 'delta' if driven is Driven.GAMMA else 'gamma'


def _never_assembles(frame: float, ab: float, coupler: float, cd: float) -> str:
    if ab + cd <= abs(frame - coupler):
        return (f'the linkage never assembles: rockers AB + CD = {ab + cd:.6g} m cannot span '
                f'|frame - coupler| = {abs(frame - coupler):.6g} m')
    return (f'the linkage never assembles: frame + coupler = {frame + coupler:.6g} m is shorter than '
            f'|AB - CD| = {abs(ab - cd):.6g} m')
