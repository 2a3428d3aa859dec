r"""Completing the linkage from the measured driven rocker, against the two approaches users publish today.

Claim: from the driven joint's angle, rate and effort, the core's closed form (``exact``) gives the other rocker,
theta, theta's rate and the load torque to within ulps of their condition, where a cubic fit per passive joint
(``cubic``, ``cubic-mid``) and warm-started Gauss-Newton to 1e-5 rad (``gauss-newton``, ``lm-scipy``) do not; and
what each costs per message. Errors against :mod:`benchmarks.reference_driven` (60 digits) on every geometry of
:mod:`benchmarks.cases`, mid-range and 1e-6 / 1e-12 rad from the driven rocker's reach limits; cost on Turnantenna,
scalar and vectorized, as ratios to ``exact`` in one interleaved run. Run by ``python -m benchmarks.run``
(section "Completing the linkage"; the report's text says what each method is).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

import mpmath
import numpy as np
import numpy.typing as npt

from benchmarks.cases import COMMON_GEOMETRIES, TURNANTENNA
from benchmarks.methods import linkage
from benchmarks.reference import Geometry, angle_error_mp
from benchmarks.reference_driven import DrivenPose, DrivenRange, driven_pose_mp, working_range
from benchmarks.timing import Case, interleaved
from fourbar_ros.core.antenna import Branch

FloatArray = npt.NDArray[np.float64]

Q_RATE = 0.2  #: rad/s, the driven rocker's speed in the measured stream
RATE_HZ = 100.0  #: joint_states messages per second
STEP = Q_RATE / RATE_HZ  #: rad between successive messages
EFFORT = 1.0  #: N m at the driven rocker
TOLERANCE = 1e-5  #: rad, the iterative solvers' step tolerance
MAX_STEPS = 50  #: Newton steps per message before giving up
FIT_POINTS = 100  #: exact samples the cubic is fitted to
LIMIT_DISTANCES = (1e-6, 1e-12)  #: rad short of the reach limit
APPROACH = 10  #: messages in a stream running into a limit
EPS = math.ulp(1.0)

#: What each approach gives its users (the rates and torques of the public ones are derived here, to compare).
PUBLISHES = {'exact': 'positions, rates, load torque', 'cubic': 'positions only', 'cubic-mid': 'positions only',
             'gauss-newton': 'positions only', 'lm-scipy': 'positions only'}


class Completed(NamedTuple):
    """Completion of a stream of messages: theta and delta (rad), theta_dot (rad/s), load torque (N m)."""

    theta: FloatArray
    other: FloatArray
    theta_dot: FloatArray
    load: FloatArray


@dataclass(frozen=True)
class Peer:
    """One way to complete the linkage, bound to a geometry and its working range.

    ``stream(q)`` completes the messages q in order, one at a time (state may carry over from message to
    message); ``vector(q)`` completes an array in one call (None when the method is sequential). ``stats``
    counts the iterative solvers' steps and failures.
    """

    name: str
    stream: Callable[[FloatArray], Completed]
    vector: Callable[[FloatArray], Completed] | None
    stats: dict[str, int]


# ---------------------------------------------------------------------------------------------- the methods

def _from_rows(rows: list[tuple[float, float, float, float]]) -> Completed:
    """The completion of a stream from one (theta, other, theta_dot, load) row per message."""
    return Completed(*(np.array(c, dtype=np.float64) for c in zip(*rows, strict=True)))


def exact_peer(g: Geometry, r: DrivenRange) -> Peer:
    """The core's completion: positions by from_rocker, dq/dtheta by rates_at (driven rocker AB)."""
    link = linkage(g)
    branch = Branch(r.branch)
    from_rocker, rates_at = link.from_rocker, link.rates_at

    def one(q: float) -> tuple[float, float, float, float]:
        theta, other = from_rocker(q, branch=branch)
        dq_dtheta = rates_at(theta, q, other).dgamma_dtheta
        return theta, other, Q_RATE / dq_dtheta, EFFORT * dq_dtheta  # type: ignore[return-value]

    def stream(q: FloatArray) -> Completed:
        return _from_rows([one(x) for x in q.tolist()])

    def vector(q: FloatArray) -> Completed:
        theta, other = from_rocker(q, branch=branch)
        dq_dtheta = np.asarray(rates_at(theta, q, other).dgamma_dtheta)
        return Completed(np.asarray(theta), np.asarray(other), Q_RATE / dq_dtheta, EFFORT * dq_dtheta)

    return Peer('exact', stream, vector, {})


def cubic_peer(g: Geometry, r: DrivenRange, over_mid: bool) -> Peer:
    """Cubic fits of theta(q) and delta(q) over the whole driven range (or the mid-range only); rate and torque
    from the cubic's derivative."""
    q_fit = np.linspace(r.mid_lo, r.mid_hi, FIT_POINTS) if over_mid else np.linspace(r.lo, r.hi, FIT_POINTS)
    poses = [driven_pose_mp(g, q, r.branch) for q in q_fit.tolist()]
    theta_fit = np.unwrap([float(p.theta) for p in poses])
    other_fit = np.unwrap([float(p.delta) for p in poses])
    c_theta, c_other = np.polyfit(q_fit, theta_fit, 3), np.polyfit(q_fit, other_fit, 3)
    c_rate = np.polyder(c_theta)  # dtheta/dq
    t3, t2, t1, t0 = c_theta.tolist()
    o3, o2, o1, o0 = c_other.tolist()
    r2, r1, r0 = c_rate.tolist()

    def stream(q: FloatArray) -> Completed:
        rows = []
        for x in q.tolist():
            rate = (r2 * x + r1) * x + r0
            rows.append((((t3 * x + t2) * x + t1) * x + t0, ((o3 * x + o2) * x + o1) * x + o0,
                         Q_RATE * rate, EFFORT / rate))
        return _from_rows(rows)

    def vector(q: FloatArray) -> Completed:
        rate = np.asarray(np.polyval(c_rate, q), dtype=np.float64)
        theta, other = np.asarray(np.polyval(c_theta, q), dtype=np.float64), np.polyval(c_other, q)
        return Completed(theta, np.asarray(other, dtype=np.float64), Q_RATE * rate, EFFORT / rate)

    return Peer('cubic-mid' if over_mid else 'cubic', stream, vector, {})


Residual = Callable[[float, float], tuple[float, float]]


def _residual(g: Geometry, q: float) -> Residual:
    """The loop-closure equations (A.2) at driven angle q as functions of (theta, delta), in metres."""
    H, a, h, b = g.frame, g.rocker_ab, g.coupler, g.rocker_cd
    aq_c, aq_s = a * math.cos(q), a * math.sin(q)
    cos, sin = math.cos, math.sin
    return lambda t, d: (aq_c + h * cos(t) + b * cos(d) - H, aq_s - h * sin(t) - b * sin(d))


def _warm_started(name: str, g: Geometry, r: DrivenRange,
                  solve: Callable[[Residual, float, float], tuple[float, float]], stats: dict[str, int]) -> Peer:
    """An iterative solver run message by message: ``solve(residual, theta, delta)`` from the previous message's
    solution (the first from the exact pose there: a generous start; a node would carry it over). Positions only:
    rate and torque by backward differences of successive messages (NaN for the first)."""
    from_rocker, branch = linkage(g).from_rocker, Branch(r.branch)

    def stream(q: FloatArray) -> Completed:
        x = from_rocker(float(q[0]), branch=branch)
        theta, other = np.empty(q.size), np.empty(q.size)
        for i, qi in enumerate(q.tolist()):
            x = solve(_residual(g, qi), *x)
            theta[i], other[i] = x
        stats['messages'] += q.size
        dtheta = np.diff(theta, prepend=np.nan)
        with np.errstate(divide='ignore', invalid='ignore'):
            return Completed(theta, other, dtheta * RATE_HZ, EFFORT * np.diff(q, prepend=np.nan) / dtheta)

    return Peer(name, stream, None, stats)


def newton_peer(g: Geometry, r: DrivenRange) -> Peer:
    """Warm-started Newton on the loop equations to a 1e-5 rad step, scalar math; positions only."""
    h, b = g.coupler, g.rocker_cd
    cos, sin = math.cos, math.sin
    stats = {'messages': 0, 'steps': 0, 'not_converged': 0, 'singular': 0}

    def solve(f: Residual, t: float, d: float) -> tuple[float, float]:
        for k in range(MAX_STEPS):
            f1, f2 = f(t, d)
            det = h * b * sin(t - d)
            if det == 0.0:
                stats['singular'] += 1
                break
            st = (-b * cos(d) * f1 + b * sin(d) * f2) / det
            sd = (h * cos(t) * f1 - h * sin(t) * f2) / det
            t, d = t - st, d - sd
            if max(abs(st), abs(sd)) < TOLERANCE:
                stats['steps'] += k + 1
                break
        else:
            stats['steps'] += MAX_STEPS
            stats['not_converged'] += 1
        return t, d

    return _warm_started('gauss-newton', g, r, solve, stats)


def lm_scipy_peer(g: Geometry, r: DrivenRange) -> Peer | None:
    """scipy's Levenberg-Marquardt (MINPACK) on the same equations, warm-started; None without scipy."""
    try:
        from scipy.optimize import least_squares  # type: ignore[import-untyped, unused-ignore]
    except ImportError:
        return None
    h, b = g.coupler, g.rocker_cd
    stats = {'messages': 0, 'evaluations': 0, 'not_converged': 0}

    def jac(v: FloatArray) -> FloatArray:
        t, d = float(v[0]), float(v[1])
        return np.array([[-h * math.sin(t), -b * math.sin(d)], [-h * math.cos(t), -b * math.cos(d)]])

    def solve(f: Residual, t: float, d: float) -> tuple[float, float]:
        def fun(v: FloatArray) -> FloatArray:
            return np.array(f(float(v[0]), float(v[1])))

        sol = least_squares(fun, np.array([t, d]), jac=jac, method='lm', xtol=TOLERANCE)
        stats['evaluations'] += int(sol.nfev)
        stats['not_converged'] += int(sol.status <= 0)
        return float(sol.x[0]), float(sol.x[1])

    return _warm_started('lm-scipy', g, r, solve, stats)


def peers(g: Geometry, r: DrivenRange) -> list[Peer]:
    """The methods compared on one geometry (lm-scipy only where scipy is installed)."""
    out = [exact_peer(g, r), cubic_peer(g, r, False), cubic_peer(g, r, True), newton_peer(g, r)]
    lm = lm_scipy_peer(g, r)
    return out if lm is None else [*out, lm]


# ---------------------------------------------------------------------------------------------- the streams

def mid_stream(r: DrivenRange, max_messages: int | None = None) -> FloatArray:
    """Messages STEP apart over the mid-range (at most max_messages of them, centred)."""
    q = np.arange(r.mid_lo, r.mid_hi, STEP)
    if max_messages is not None and q.size > max_messages:
        first = (q.size - max_messages) // 2
        q = q[first:first + max_messages]
    return q


def limit_stream(r: DrivenRange, upper: bool, distance: float) -> FloatArray:
    """APPROACH messages STEP apart running into one end of the range, the last one ``distance`` short of it."""
    end, sense = (r.hi, -1.0) if upper else (r.lo, 1.0)
    last = end + sense * distance
    return np.asarray(last + sense * STEP * np.arange(APPROACH - 1, -1, -1), dtype=np.float64)


# ---------------------------------------------------------------------------------------------- the errors

@dataclass(frozen=True)
class Reference:
    """Reference completion at a set of messages, and the exact method's error scales (condition-weighted)."""

    poses: list[DrivenPose]
    q: FloatArray

    def angle_errors(self, got: FloatArray, which: str) -> FloatArray:
        """|got - ref| in rad modulo 2 pi, resolved below one ulp."""
        return np.array([angle_error_mp(v, getattr(p, which)) for p, v in zip(self.poses, got.tolist(), strict=True)])

    def relative_errors(self, got: FloatArray, ref: Sequence[mpmath.mpf]) -> FloatArray:
        """|got - ref| / |ref| (NaN where got is NaN)."""
        with mpmath.workdps(40):
            return np.array([abs(float((mpmath.mpf(v) - x) / x)) if math.isfinite(v) else math.nan
                             for v, x in zip(got.tolist(), ref, strict=True)])

    def rates(self) -> list[mpmath.mpf]:
        """Reference theta_dot (rad/s): Q_RATE / (dq/dtheta)."""
        with mpmath.workdps(40):
            return [Q_RATE / p.dq_dtheta for p in self.poses]

    def loads(self) -> list[mpmath.mpf]:
        """Reference load torque (N m): EFFORT dq/dtheta."""
        with mpmath.workdps(40):
            return [EFFORT * p.dq_dtheta for p in self.poses]

    def angle_scales(self, which: str) -> FloatArray:
        """1 + |f| + kappa_f (rad): n ulps of this is n ulps of the angle's condition."""
        kappa = 'kappa_theta' if which == 'theta' else 'kappa_delta'
        return np.array([1.0 + abs(float(getattr(p, which))) + getattr(p, kappa) for p in self.poses])

    def rate_scales(self) -> FloatArray:
        """Relative error scale of dq/dtheta = h sin(delta - theta) / (a sin(q + delta)) from its arguments'
        scales: 1 + |cot(delta - theta)| (s_theta + s_delta) + |cot(q + delta)| (s_delta + |q|)."""
        s_t, s_d = self.angle_scales('theta'), self.angle_scales('delta')
        with mpmath.workdps(40):
            cot_n = np.array([abs(float(mpmath.cot(p.delta - p.theta))) for p in self.poses])
            cot_d = np.array([abs(float(mpmath.cot(mpmath.mpf(q) + p.delta)))
                              for p, q in zip(self.poses, self.q.tolist(), strict=True)])
        return 1.0 + cot_n * (s_t + s_d) + cot_d * (s_d + np.abs(self.q))


def reference(g: Geometry, r: DrivenRange, q: FloatArray) -> Reference:
    """The 60-digit completion at every message of q."""
    return Reference([driven_pose_mp(g, x, r.branch) for x in q.tolist()], q)


def _worst(x: FloatArray) -> float:
    """Max, with NaN (a missing output) counted as infinite."""
    return float(np.max(np.where(np.isnan(x), math.inf, x))) if x.size else math.nan


def errors(out: Completed, ref: Reference, exact: bool) -> dict[str, float]:
    """Worst errors of one method's output at the reference messages (and ulps of condition for exact)."""
    e_theta, e_other = ref.angle_errors(out.theta, 'theta'), ref.angle_errors(out.other, 'delta')
    e_rate, e_load = ref.relative_errors(out.theta_dot, ref.rates()), ref.relative_errors(out.load, ref.loads())
    row = {'theta_rad': _worst(e_theta), 'other_rad': _worst(e_other),
           'theta_dot_rel': _worst(e_rate), 'load_torque_rel': _worst(e_load)}
    if exact:
        row['position_ulps'] = max(_worst(e_theta / (EPS * ref.angle_scales('theta'))),
                                   _worst(e_other / (EPS * ref.angle_scales('delta'))))
        row['rate_ulps'] = max(_worst(e_rate / (EPS * ref.rate_scales())),
                               _worst(e_load / (EPS * ref.rate_scales())))
    return row


def geometry_errors(g: Geometry, max_mid: int | None = None) -> dict[str, Any]:
    """Errors of every method on one geometry: mid-range and each limit distance (worst of both ends)."""
    r = working_range(g)
    ps = peers(g, r)
    q_mid = mid_stream(r, max_mid)
    ref_mid = reference(g, r, q_mid[1:])  # the first message has no predecessor to difference against
    def worst(p: Peer, q: FloatArray, ref: Reference) -> dict[str, float]:
        """Errors of both paths at the reference's messages, the last ones of q."""
        skip = q.size - len(ref.poses)
        rows = [errors(_tail(path(q), skip), ref, p.name == 'exact') for path in (p.stream, p.vector) if path]
        return {k: max(r[k] for r in rows) for k in rows[0]}

    where: dict[str, dict[str, dict[str, float]]] = {p.name: {'mid': worst(p, q_mid, ref_mid)} for p in ps}
    if r.limited:
        for dist in LIMIT_DISTANCES:
            key = f'limit_{dist:g}'
            for upper in (False, True):
                q = limit_stream(r, upper, dist)
                ref = reference(g, r, q[-1:])
                for p in ps:
                    row = worst(p, q, ref)
                    old = where[p.name].setdefault(key, row)
                    where[p.name][key] = {k: max(old[k], row[k]) for k in row}
    return {'range_rad': [r.lo, r.hi], 'mid_range_rad': [r.mid_lo, r.mid_hi], 'branch': r.branch,
            'limited': r.limited, 'mid_messages': int(q_mid.size),
            'methods': where, 'solver_stats': {p.name: dict(p.stats) for p in ps if p.stats}}


def _tail(c: Completed, start: int) -> Completed:
    return Completed(*(x[start:] for x in c))


# ---------------------------------------------------------------------------------------------- the cost

def costs(n_scalar: int, n_vector: int, repeats: int) -> dict[str, Any]:
    """CPU seconds per message (median of interleaved rounds), scalar and vectorized, and ratios to exact.

    The scalar stream walks back and forth over the mid-range STEP by STEP (n_scalar
    messages, fewer for lm-scipy: a tenth); the vectorized input is n_vector angles spread over the same span.
    """
    g = TURNANTENNA
    r = working_range(g)
    span = mid_stream(r)
    walk = np.concatenate([span, span[::-1]])
    q_scalar = np.resize(walk, n_scalar)
    q_vector = np.linspace(span[0], span[-1], n_vector)
    cases: list[Case] = []
    for p in peers(g, r):
        q = q_scalar[:max(n_scalar // 10, 20)] if p.name == 'lm-scipy' else q_scalar
        cases.append(Case(f'{p.name}/scalar', functools.partial(p.stream, q), q.size))
        if p.vector is not None:
            cases.append(Case(f'{p.name}/vector', functools.partial(p.vector, q_vector), n_vector))
    timed = interleaved(cases, repeats)
    out: dict[str, Any] = {'geometry': g.name, 'n_scalar': n_scalar, 'n_vector': n_vector, 'repeats': repeats,
                           'methods': {}}
    base = {path: timed[f'exact/{path}'][0] for path in ('scalar', 'vector')}
    for c in cases:
        name, path = c.name.split('/')
        m = out['methods'].setdefault(name, {})
        m[f'{path}_seconds'] = timed[c.name][0]
        m[f'{path}_wall_seconds'] = timed[c.name][1]
        m[f'{path}_ratio_to_exact'] = timed[c.name][0] / base[path]
        m[f'{path}_messages'] = c.count
    return out


def run(quick: bool) -> dict[str, Any]:
    """Errors on every geometry and the cost on Turnantenna (smaller streams and fewer repeats when quick)."""
    max_mid, n_scalar, n_vector, repeats = (60, 300, 20_000, 3) if quick else (None, 2000, 200_000, 7)
    return {
        'driven': 'gamma (rocker AB)',
        'stream': {'q_rate_rad_s': Q_RATE, 'rate_hz': RATE_HZ, 'step_rad': STEP, 'effort_n_m': EFFORT,
                   'approach_messages': APPROACH},
        'tolerance_rad': TOLERANCE,
        'fit_points': FIT_POINTS,
        'publishes': PUBLISHES,
        'geometries': {g.name: geometry_errors(g, max_mid) for g in COMMON_GEOMETRIES},
        'cost': costs(n_scalar, n_vector, repeats),
    }
