"""Design check of the antenna tilt linkage over its configured tilt range (pure: no ROS).

What it reports and when it fails: docs/how-to/design.md."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from fourbar_ros.core.antenna import Driven
from fourbar_ros.core.errors import FourBarError
from fourbar_ros.core.loads import LoadSpec, motor_torque
from fourbar_ros.core.loads import solve as solve_state
from fourbar_ros.core.numeric import FloatArray


class DesignSpec(LoadSpec, Protocol):
    """What the check reads besides the load model's inputs (the config layer's ``AntennaConfig`` provides it)."""

    @property
    def theta_min(self) -> float:
        """Lower end of the tilt range (rad)."""
    @property
    def theta_max(self) -> float:
        """Upper end of the tilt range (rad)."""
    @property
    def output_torque_limit(self) -> float:
        """Reducer rating: the most torque at the driven rocker (N m)."""
    @property
    def motor_torque_limit(self) -> float:
        """The most torque the motor gives before the reducer (N m)."""
    @property
    def transmission_angle_min(self) -> float:
        """Configured limit on the transmission angle's distance from a dead point (rad)."""

#: Rule of thumb (Alt; Norton, Design of Machinery): keep the transmission angle at least 40 deg from a dead point.
TRANSMISSION_RULE_OF_THUMB = math.radians(40.0)

#: Default grid size over the tilt range.
DEFAULT_SAMPLES = 1000
#: Most grid intervals a check samples: each costs ~20 us and ~0.4 kB (100,000: ~2 s, ~80 MB in all); the
#: extrema are refined by golden-section search, so a finer grid adds nothing but time and memory.
MAX_SAMPLES = 100_000

_GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0


@dataclass(frozen=True)
class CheckLimits:
    """Limits the verdict enforces besides the configuration's own torque limits (angles in rad).

    ``min_reach_margin``: required margin to the reach limit at both ends of the tilt range (rad).
    ``min_transmission_angle``: limit on min(mu, pi - mu) (rad); None takes the configuration's
    ``transmission_angle_min``.
    """

    min_reach_margin: float = 0.0
    min_transmission_angle: float | None = None


@dataclass(frozen=True)
class Extremum:
    """An extreme value over the tilt range and the antenna angle theta (rad) where it occurs."""

    value: float
    theta: float


@dataclass(frozen=True)
class DesignReport:
    """Result of :func:`check_design`. Angles in rad, torques in N m, sensitivities dimensionless.

    ``reach_margin_low``/``_high``: distance (rad) from theta_min down to / theta_max up to the reach limit
    (inf when the coupler can turn fully). ``peak_input_torque``: max |torque| at the driven rocker.
    ``peak_motor_torque``: that torque on the motor side. ``min_transmission``: min over the range of
    min(mu, pi - mu). ``max_rocker_rate``/``max_other_rate``: max |dq/dtheta| of the driven/other rocker.
    ``max_theta_per_rocker``: max |dtheta/dq| of the driven rocker.
    """

    theta_min: float
    theta_max: float
    driven: Driven
    reach_theta_gap: float
    reach_theta_max: float
    reach_margin_low: float
    reach_margin_high: float
    min_transmission: Extremum
    peak_input_torque: Extremum
    peak_motor_torque: float
    output_torque_limit: float
    motor_torque_limit: float
    max_rocker_rate: Extremum
    max_other_rate: Extremum
    max_theta_per_rocker: Extremum
    transmission_limit: float
    limits: CheckLimits
    failures: tuple[str, ...]
    warnings: tuple[str, ...]
    samples: int

    @property
    def passed(self) -> bool:
        """True when no configured limit is exceeded (warnings do not fail the check)."""
        return not self.failures

    @property
    def verdict(self) -> str:
        """One line: PASS or FAIL with the reasons (and the number of warnings)."""
        if self.failures:
            return 'FAIL: ' + '; '.join(self.failures)
        return 'PASS' + (f' ({len(self.warnings)} warning{"s" * (len(self.warnings) != 1)})'
                         if self.warnings else '')

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form (rad, N m); infinite margins become None."""
        def fin(x: float) -> float | None:
            return x if math.isfinite(x) else None

        def ext(e: Extremum) -> dict[str, float | None]:
            return {'value': fin(e.value), 'theta': e.theta}

        return {
            'passed': self.passed, 'verdict': self.verdict,
            'failures': list(self.failures), 'warnings': list(self.warnings),
            'theta_min': self.theta_min, 'theta_max': self.theta_max, 'driven': self.driven.value,
            'reach_theta_gap': self.reach_theta_gap, 'reach_theta_max': self.reach_theta_max,
            'reach_margin_low': fin(self.reach_margin_low), 'reach_margin_high': fin(self.reach_margin_high),
            'min_transmission_angle': ext(self.min_transmission),
            'peak_input_torque': ext(self.peak_input_torque),
            'peak_motor_torque': fin(self.peak_motor_torque),
            'output_torque_limit': self.output_torque_limit, 'motor_torque_limit': self.motor_torque_limit,
            'max_rocker_rate': ext(self.max_rocker_rate), 'max_other_rocker_rate': ext(self.max_other_rate),
            'max_theta_per_rocker': ext(self.max_theta_per_rocker),
            'min_reach_margin': self.limits.min_reach_margin,
            'transmission_angle_limit': self.transmission_limit,
            'samples': self.samples,
        }


@dataclass(frozen=True)
class Curves:
    """Quantities sampled over the tilt range, for plots: theta (rad), torques (N m), angles (rad)."""

    theta: FloatArray
    gamma: FloatArray
    delta: FloatArray
    input_torque: FloatArray
    motor_torque: FloatArray
    transmission_angle: FloatArray
    driven_rate: FloatArray
    other_rate: FloatArray


def _point(cfg: DesignSpec, theta: float) -> tuple[float, float, float, float, float, float]:
    """(gamma, delta, input torque, transmission angle, driven rate, other rate) at theta; inf torque at a dead
    point."""
    s = solve_state(cfg, theta)
    if cfg.driven is Driven.GAMMA:
        driven_rate, other_rate = float(s.dgamma_dtheta), float(s.ddelta_dtheta)
    else:
        driven_rate, other_rate = float(s.ddelta_dtheta), float(s.dgamma_dtheta)
    return (float(s.gamma), float(s.delta), float(s.input_torque), float(s.transmission_angle),
            driven_rate, other_rate)


def sample_curves(cfg: DesignSpec, samples: int = DEFAULT_SAMPLES) -> Curves:
    """Sample the tilt range at ``samples`` + 1 evenly spaced angles (both ends included)."""
    if not 2 <= samples <= MAX_SAMPLES:
        raise FourBarError(f'samples={samples} must be between 2 and {MAX_SAMPLES}')
    theta = np.linspace(cfg.theta_min, cfg.theta_max, samples + 1)
    rows = np.array([_point(cfg, float(t)) for t in theta])
    motor = np.array([motor_torque(cfg, float(v)) for v in rows[:, 2]])
    return Curves(theta, rows[:, 0], rows[:, 1], rows[:, 2], motor, rows[:, 3], rows[:, 4], rows[:, 5])


def _golden_max(f: Callable[[float], float], lo: float, hi: float, iterations: int = 80) -> tuple[float, float]:
    """Maximum of f on [lo, hi] by golden-section search (f unimodal there); returns (x, f(x))."""
    a, b = lo, hi
    c, d = b - _GOLDEN * (b - a), a + _GOLDEN * (b - a)
    fc, fd = f(c), f(d)
    for _ in range(iterations):
        if b - a <= 4.0 * np.finfo(float).eps * max(1.0, abs(a), abs(b)):
            break
        if fc >= fd:
            b, d, fd = d, c, fc
            c = b - _GOLDEN * (b - a)
            fc = f(c)
        else:
            a, c, fc = c, d, fd
            d = a + _GOLDEN * (b - a)
            fd = f(d)
    return (c, fc) if fc >= fd else (d, fd)


def _extremum(theta: FloatArray, values: FloatArray, f: Callable[[float], float]) -> Extremum:
    """The maximum of f over the range: best grid sample, refined in its neighbouring cells."""
    i = int(np.argmax(values))
    best = Extremum(float(values[i]), float(theta[i]))
    if not math.isfinite(best.value):
        return best
    lo, hi = float(theta[max(i - 1, 0)]), float(theta[min(i + 1, theta.size - 1)])
    x, fx = _golden_max(f, lo, hi)
    return Extremum(fx, x) if fx > best.value else best


def _reach_margins(cfg: DesignSpec) -> tuple[float, float]:
    """(low, high) margins in rad from the tilt range's ends to the reach limits of the interval holding it."""
    r = cfg.linkage.reach()
    if r.theta_gap == 0.0 and r.theta_max >= math.pi:
        return math.inf, math.inf
    if r.theta_gap == 0.0 or cfg.theta_max <= -r.theta_gap:
        lower, upper = -r.theta_max, (-r.theta_gap if r.theta_gap > 0.0 else r.theta_max)
    else:
        lower, upper = r.theta_gap, r.theta_max
    return cfg.theta_min - lower, upper - cfg.theta_max


def _deg(angle: float) -> str:
    return f'{math.degrees(angle):+.3f} deg'


def check_design(cfg: DesignSpec, limits: CheckLimits | None = None,
                 samples: int = DEFAULT_SAMPLES) -> DesignReport:
    """Check the configured linkage, load and drive over [theta_min, theta_max]; see the module docstring."""
    limits = limits or CheckLimits()
    curves = sample_curves(cfg, samples)
    th = curves.theta
    eff_mu = np.minimum(curves.transmission_angle, math.pi - curves.transmission_angle)

    def at(theta: float, index: int) -> float:
        return _point(cfg, theta)[index]

    min_mu_neg = _extremum(th, -eff_mu, lambda t: -min(at(t, 3), math.pi - at(t, 3)))
    min_mu = Extremum(-min_mu_neg.value, min_mu_neg.theta)
    peak_tau = _extremum(th, np.abs(curves.input_torque), lambda t: abs(at(t, 2)))
    peak_motor = abs(motor_torque(cfg, peak_tau.value))
    rate = _extremum(th, np.abs(curves.driven_rate), lambda t: abs(at(t, 4)))
    other = _extremum(th, np.abs(curves.other_rate), lambda t: abs(at(t, 5)))
    with np.errstate(divide='ignore'):
        inv = 1.0 / np.abs(curves.driven_rate)
    theta_per_q = _extremum(th, inv, lambda t: 1.0 / abs(at(t, 4)) if at(t, 4) else math.inf)
    low, high = _reach_margins(cfg)

    failures: list[str] = []
    warnings: list[str] = []
    if not math.isfinite(peak_tau.value):
        failures.append(f'dead point of the driven rocker at theta {_deg(peak_tau.theta)}: unbounded torque')
    else:
        if peak_tau.value > cfg.output_torque_limit:
            failures.append(f'peak input torque {peak_tau.value:.4g} N m at theta {_deg(peak_tau.theta)} exceeds '
                            f'the reducer rating {cfg.output_torque_limit:.4g} N m')
        if peak_motor > cfg.motor_torque_limit:
            failures.append(f'peak motor torque {peak_motor:.4g} N m exceeds the motor limit '
                            f'{cfg.motor_torque_limit:.4g} N m (ratio {cfg.reducer_ratio:g}, efficiency '
                            f'{cfg.reducer_efficiency:g})')
    for end, margin in (('theta_min', low), ('theta_max', high)):
        if margin < limits.min_reach_margin:
            failures.append(f'reach margin at {end} {math.degrees(margin):.3f} deg is below the required '
                            f'{math.degrees(limits.min_reach_margin):.3f} deg')
    mu_limit = cfg.transmission_angle_min if limits.min_transmission_angle is None else limits.min_transmission_angle
    if min_mu.value < mu_limit:
        failures.append(f'minimum transmission angle {math.degrees(min_mu.value):.2f} deg at theta '
                        f'{_deg(min_mu.theta)} is below the limit {math.degrees(mu_limit):.2f} deg')
    elif min_mu.value < TRANSMISSION_RULE_OF_THUMB:
        warnings.append(f'minimum transmission angle {math.degrees(min_mu.value):.2f} deg at theta '
                        f'{_deg(min_mu.theta)} is below the {math.degrees(TRANSMISSION_RULE_OF_THUMB):.0f} deg '
                        'rule of thumb')
    r = cfg.linkage.reach()
    return DesignReport(
        theta_min=cfg.theta_min, theta_max=cfg.theta_max, driven=cfg.driven,
        reach_theta_gap=r.theta_gap, reach_theta_max=r.theta_max, reach_margin_low=low, reach_margin_high=high,
        min_transmission=min_mu, peak_input_torque=peak_tau, peak_motor_torque=peak_motor,
        output_torque_limit=cfg.output_torque_limit, motor_torque_limit=cfg.motor_torque_limit,
        max_rocker_rate=rate, max_other_rate=other, max_theta_per_rocker=theta_per_q,
        transmission_limit=mu_limit, limits=limits,
        failures=tuple(failures), warnings=tuple(warnings), samples=samples,
    )


def format_report(report: DesignReport) -> str:
    """Human-readable multi-line report (degrees alongside radians, N m)."""
    def ext(e: Extremum, unit: str = '') -> str:
        return f'{e.value:.6g}{unit} at theta {_deg(e.theta)}'

    def margin(m: float) -> str:
        return 'unlimited (full rotation)' if math.isinf(m) else f'{m:.6g} rad ({math.degrees(m):.3f} deg)'

    lines = [
        f'tilt range: theta {_deg(report.theta_min)} .. {_deg(report.theta_max)}; driven rocker '
        f'{report.driven.value}; reach |theta| <= {math.degrees(report.reach_theta_max):.3f} deg'
        + (f' and >= {math.degrees(report.reach_theta_gap):.3f} deg' if report.reach_theta_gap else ''),
        f'reach margin: below theta_min {margin(report.reach_margin_low)}, above theta_max '
        f'{margin(report.reach_margin_high)}',
        f'min transmission angle (from dead point): {math.degrees(report.min_transmission.value):.3f} deg at '
        f'theta {_deg(report.min_transmission.theta)} (limit {math.degrees(report.transmission_limit):.2f} deg)',
        f'peak input torque at the driven rocker: {ext(report.peak_input_torque, " N m")} '
        f'(reducer rating {report.output_torque_limit:g} N m, '
        f'{_ratio(report.peak_input_torque.value, report.output_torque_limit)})',
        f'peak motor torque: {report.peak_motor_torque:.6g} N m (motor limit {report.motor_torque_limit:g} N m, '
        f'{_ratio(report.peak_motor_torque, report.motor_torque_limit)})',
        f'max |dq/dtheta| driven rocker: {ext(report.max_rocker_rate)}; other rocker: '
        f'{ext(report.max_other_rate)}',
        f'max |dtheta/dq| (antenna error per rocker error): {ext(report.max_theta_per_rocker)}',
    ]
    lines += [f'warning: {w}' for w in report.warnings]
    lines.append(f'verdict: {report.verdict}')
    return '\n'.join(lines)


def _ratio(value: float, limit: float) -> str:
    return f'{100.0 * value / limit:.1f}% of it' if math.isfinite(value) else 'unbounded'
