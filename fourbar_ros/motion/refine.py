"""The controller's interpolation error, bounded: insert points until the antenna follows the requested path.

The bound, why it holds between samples, and the bisection: docs/explanation/motion.md."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from fourbar_ros.config.antenna_config import AntennaConfig
from fourbar_ros.core.antenna import Driven
from fourbar_ros.core.errors import UnreachableError
from fourbar_ros.core.numeric import FloatArray
from fourbar_ros.motion.errors import TooManyPointsError, TrajectoryError
from fourbar_ros.motion.limits import range_slack
from fourbar_ros.motion.splines import derivative_bound, evaluate, hermite_coefficients
from fourbar_ros.motion.trajectory import AntennaTrajectory, DrivenTrajectory, SplineKind, on_wire, to_driven

IndexArray = npt.NDArray[np.intp]

__all__ = ['SAMPLES', 'Refined', 'deviation_bounds', 'dtheta_dq_bounds', 'q_band', 'refine']

#: Intervals per segment (S) of the deviation check.
SAMPLES = 16
#: Grid points over the admitted band of q for L1 and L2.
_GRID = 4097
#: The band of q admitted: the driven joint's range over [theta_min, theta_max], widened by this fraction each side.
_BAND = 0.05


@dataclass(frozen=True)
class Refined:
    """A refined trajectory, the number of points inserted, and the largest deviation bound (rad) of its segments."""

    trajectory: DrivenTrajectory
    inserted: int
    bound: float


def q_band(cfg: AntennaConfig) -> tuple[float, float]:
    """The band of the driven joint's angle (rad) the check admits."""
    q = cfg.linkage.rocker_angles(np.array([cfg.theta_min, cfg.theta_max]), cfg.branch)
    ends = np.sort(np.asarray(q.gamma if cfg.driven is Driven.GAMMA else q.delta))
    pad = _BAND * float(ends[1] - ends[0])
    return float(ends[0]) - pad, float(ends[1]) + pad


def dtheta_dq_bounds(cfg: AntennaConfig) -> tuple[float, float]:
    """(L1, L2): upper bounds on |d theta/d q| and |d2 theta/d q2| over the admitted band of q (module docstring)."""
    lo, hi = q_band(cfg)
    q = np.linspace(lo, hi, _GRID)
    link = cfg.linkage
    theta_a, other_a = link.from_rocker(q, cfg.driven, cfg.measured_branch)
    theta, other = np.asarray(theta_a), np.asarray(other_a)
    gamma, delta = (q, other) if cfg.driven is Driven.GAMMA else (other, q)
    rates = link.rates_at(theta, gamma, delta)
    q1 = np.asarray(rates.dgamma_dtheta if cfg.driven is Driven.GAMMA else rates.ddelta_dtheta)
    q2 = np.asarray(link.second_derivative_at(theta, gamma, delta, rates, cfg.driven))
    bounds = []
    for f in (np.abs(1.0 / q1), np.abs(q2 / q1 ** 3)):
        bounds.append(float(np.max(f) + np.max(np.abs(np.diff(f)))))
    if not all(np.isfinite(bounds)):
        raise TrajectoryError(f'the driven joint has a dead point within [{lo!r}, {hi!r}] rad: the interpolation '
                              'error cannot be bounded; narrow [theta_min, theta_max]')
    return bounds[0], bounds[1]


def _antenna_coefficients(a: AntennaTrajectory) -> FloatArray:
    return hermite_coefficients(a.times, a.theta, a.theta_dot, a.theta_ddot)


def deviation_bounds(cfg: AntennaConfig, traj: DrivenTrajectory, segments: IndexArray | None = None,
                     lam: tuple[float, float] | None = None) -> FloatArray:
    """Per segment (all, or the indices given), the bound on |antenna deviation| (rad) between its points; inf where
    Q may leave the admitted band. Raises UnreachableError where the request itself leaves [theta_min, theta_max]
    (rad) by more than ``range_slack``: its points count as given (at s = 0 and 1 the points themselves, not the
    polynomial's rounded value there), its samples between them as evaluated, so a path that ends exactly at an end
    passes and one that swings past an end between its points does not."""
    l1, l2 = dtheta_dq_bounds(cfg) if lam is None else lam
    idx = np.arange(len(traj) - 1) if segments is None else np.asarray(segments, dtype=np.intp)
    qc = hermite_coefficients(traj.times, traj.positions, traj.velocities, traj.accelerations)[idx]
    tc = _antenna_coefficients(traj.antenna)[idx]
    s = np.linspace(0.0, 1.0, SAMPLES + 1)[None, :]
    t_path = evaluate(tc, s)
    t_path[:, 0], t_path[:, -1] = traj.antenna.theta[idx], traj.antenna.theta[idx + 1]
    slack = range_slack(cfg.theta_min, cfg.theta_max)
    out = (t_path < cfg.theta_min - slack) | (t_path > cfg.theta_max + slack)
    if out.any():
        i = int(idx[np.argmax(out.any(axis=1))])
        raise UnreachableError(f'the requested path leaves [theta_min, theta_max] = [{cfg.theta_min!r}, '
                               f'{cfg.theta_max!r}] rad between points {i} and {i + 1} '
                               f'(t = {float(traj.times[i])!r} .. {float(traj.times[i + 1])!r} s)')
    lo, hi = q_band(cfg)
    reach = np.abs(qc[:, 1:]).sum(axis=1)
    inside = (qc[:, 0] - reach >= lo) & (qc[:, 0] + reach <= hi)
    bounds = np.full(idx.size, np.inf)
    if inside.any():
        q_path = evaluate(qc[inside], s)
        theta, _ = cfg.linkage.from_rocker(q_path, cfg.driven, cfg.measured_branch)
        e = np.abs(np.asarray(theta) - t_path[inside])
        qi = qc[inside]
        curvature = (l2 * derivative_bound(qi) ** 2 + l1 * derivative_bound(qi, 2)
                     + derivative_bound(tc[inside], 2))
        bounds[inside] = np.max(np.maximum(e[:, :-1], e[:, 1:]), axis=1) + curvature / (8 * SAMPLES ** 2)
    return bounds


def _midpoints(a: AntennaTrajectory, segments: IndexArray) -> AntennaTrajectory:
    """The points at the middle times (``on_wire``) of the given segments, on the requested path T."""
    tc = _antenna_coefficients(a)[segments]
    t0 = a.times[segments]
    h = np.diff(a.times)[segments]
    mid = on_wire(t0 + 0.5 * h)
    half = ((mid - t0) / h)[:, None]
    theta_dot = theta_ddot = None
    if a.kind is not SplineKind.LINEAR:
        theta_dot = evaluate(tc, half, 1)[:, 0] / h
        if a.kind is SplineKind.QUINTIC:
            theta_ddot = evaluate(tc, half, 2)[:, 0] / (h * h)
    return AntennaTrajectory(mid, evaluate(tc, half)[:, 0],
                             theta_dot, theta_ddot)


def _insert(a: AntennaTrajectory, segments: IndexArray, mid: AntennaTrajectory) -> AntennaTrajectory:
    at = segments + 1

    def put(x: FloatArray | None, y: FloatArray | None) -> FloatArray | None:
        return None if x is None or y is None else np.insert(x, at, y)

    return AntennaTrajectory(np.insert(a.times, at, mid.times), np.insert(a.theta, at, mid.theta),
                             put(a.theta_dot, mid.theta_dot), put(a.theta_ddot, mid.theta_ddot))


def refine(cfg: AntennaConfig, traj: DrivenTrajectory) -> Refined:
    """``traj`` with points inserted (by bisection) until every segment's deviation bound is at most
    ``cfg.trajectory_tolerance``. Raises TrajectoryError if that needs more than ``cfg.max_trajectory_points``
    points, or a segment shorter than the float resolution of its times; UnreachableError as ``deviation_bounds``."""
    tol = cfg.trajectory_tolerance
    lam = dtheta_dq_bounds(cfg)
    start = len(traj)
    pending = np.arange(start - 1)
    bounds = np.zeros(max(start - 1, 0))
    while pending.size:
        b = deviation_bounds(cfg, traj, pending, lam)
        bounds[pending] = b
        failing = pending[b > tol]
        if not failing.size:
            break
        worst = int(failing[np.argmax(bounds[failing])])
        where = (f'between points {worst} and {worst + 1} (t = {float(traj.times[worst])!r} .. '
                 f'{float(traj.times[worst + 1])!r} s) the antenna may deviate by {float(bounds[worst]):.3g} rad '
                 f'> trajectory_tolerance {tol!r} rad')
        if len(traj) + failing.size > cfg.max_trajectory_points:
            raise TooManyPointsError(f'{where}; refining needs more than max_trajectory_points = '
                                  f'{cfg.max_trajectory_points}')
        mid = _midpoints(traj.antenna, failing)
        if not ((mid.times > traj.times[failing]) & (mid.times < traj.times[failing + 1])).all():
            raise TrajectoryError(f'{where}; the segment is too short to split')
        traj = to_driven(cfg, _insert(traj.antenna, failing, mid))
        # The halves of each failing segment are pending; every other segment keeps its bound.
        shift = np.searchsorted(failing, np.arange(bounds.size), side='left')
        new_bounds = np.zeros(len(traj) - 1)
        new_bounds[np.arange(bounds.size) + shift] = bounds
        first_halves = failing + np.arange(failing.size)
        pending = np.sort(np.concatenate([first_halves, first_halves + 1]))
        bounds = new_bounds
    return Refined(traj, len(traj) - start, float(bounds.max()) if bounds.size else 0.0)
