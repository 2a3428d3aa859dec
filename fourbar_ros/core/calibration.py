"""Calibration of the linkage as built: the four lengths and two offsets fitted to an antenna angle sensor.

The model, the fit and what the report means: docs/how-to/calibrate.md; the exact Jacobian:
docs/explanation/exactness.md."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from fourbar_ros.core.antenna import AntennaLinkage, Branch, Driven
from fourbar_ros.core.errors import FourBarError
from fourbar_ros.core.numeric import ArrayLike, FloatArray

__all__ = [
    'DETERMINED_RATIO', 'LENGTH_NAMES', 'OFFSET_SD', 'PARAMETER_NAMES', 'Calibration', 'CalibrationError',
    'FittedParameter', 'MapFit', 'calibrate', 'imu_tilt', 'map_fit', 'model_jacobian', 'model_mismatch', 'predict',
]

#: The fitted parameters, in order: the four lengths (m, named as the node's parameters), then the offsets (rad).
LENGTH_NAMES = ('frame_length', 'rocker_ab_length', 'coupler_length', 'rocker_cd_length')
PARAMETER_NAMES = (*LENGTH_NAMES, 'driven_joint_offset', 'sensor_offset')
#: Default prior sd of the offsets (rad, about 5.7 deg): weak, it only keeps the problem well posed.
OFFSET_SD = 0.1
#: A parameter (or a direction) is determined by the data when its posterior sd is below this fraction of the prior's.
DETERMINED_RATIO = 0.5
#: Levenberg-Marquardt iterations per pass, and passes re-estimating sigma, before the fit counts as not converged.
MAX_ITERATIONS = 100
MAX_PASSES = 20
#: Convergence: a step below this (in prior sds), or one lowering the cost (chi-square: residuals over sigma, squared,
#: plus the prior's terms) by less than COST_TOL, ends a pass (both far below what moves a result: the posterior sds
#: are where the cost rises by 1); sigma changing by less than SIGMA_TOL (relative) ends the passes.
STEP_TOL = 1e-5
COST_TOL = 1e-6
SIGMA_TOL = 1e-4


class CalibrationError(FourBarError):
    """Data that cannot calibrate the linkage, or a fit that does not converge (one line)."""


def _linkage(p: FloatArray) -> AntennaLinkage:
    return AntennaLinkage(frame=float(p[0]), rocker_ab=float(p[1]), coupler=float(p[2]), rocker_cd=float(p[3]))


def predict(p: FloatArray, q_measured: FloatArray, driven: Driven, branch: Branch) -> FloatArray:
    """The sensor reading (rad) the parameters ``p`` (PARAMETER_NAMES order: m, m, m, m, rad, rad) predict for the
    measured driven joint ``q_measured`` (rad); NaN where the rocker cannot take q_measured + driven_joint_offset.
    ``branch`` is ``from_rocker``'s (``AntennaConfig.measured_branch``)."""
    link = _linkage(p)
    theta = link.from_rocker(np.asarray(q_measured, dtype=np.float64) + p[4], driven, branch, on_invalid='nan').theta
    out: FloatArray = np.asarray(theta, dtype=np.float64) + p[5]
    return out


def model_jacobian(p: FloatArray, q_measured: FloatArray, driven: Driven,
                   branch: Branch) -> tuple[FloatArray, FloatArray]:
    """(prediction (N,) rad, d prediction / d p (N, 6): rad/m for the lengths, rad/rad for the offsets), exact by
    implicit differentiation of the loop closure (module docstring)."""
    ab, h, cd = float(p[1]), float(p[2]), float(p[3])
    q = np.asarray(q_measured, dtype=np.float64) + p[4]
    link = _linkage(p)
    theta, other = (np.asarray(a) for a in link.from_rocker(q, driven, branch, on_invalid='nan'))
    rows = np.empty((6, q.size))  # one row per parameter (contiguous), returned transposed
    gamma_driven = driven is Driven.GAMMA
    x = q + other                                      # gamma + delta
    w = other - theta if gamma_driven else other + theta  # u = delta - theta, or v = gamma + theta
    with np.errstate(divide='ignore', invalid='ignore'):
        inv = 1.0 / (h * np.sin(w) if gamma_driven else -h * np.sin(w))   # 1 / G_theta
        if gamma_driven:
            np.multiply(np.cos(other), inv, out=rows[0])   # -G_H = cos delta
            np.multiply(-np.cos(x), inv, out=rows[1])      # -G_AB = -cos X
            np.negative(inv, out=rows[3])                  # -G_CD = -1
            rows[4] = ab * np.sin(x) * inv                 # -G_q = AB sin X
        else:
            np.multiply(np.cos(other), inv, out=rows[0])   # -G_H = cos gamma
            np.negative(inv, out=rows[1])                  # -G_AB = -1
            np.multiply(-np.cos(x), inv, out=rows[3])      # -G_CD = -cos X
            rows[4] = cd * np.sin(x) * inv                 # -G_q = CD sin X
        np.multiply(-np.cos(w), inv, out=rows[2])          # -G_h = -cos u, or -cos v
    rows[5] = 1.0
    return theta + p[5], rows.T


def model_mismatch(link: AntennaLinkage, q_measured: ArrayLike, sensor_theta: ArrayLike, driven: Driven,
                   branch: Branch, driven_joint_offset: float = 0.0, sensor_offset: float = 0.0) -> ArrayLike:
    """The sensor's antenna angle minus the model's (rad): ``sensor_theta - sensor_offset`` against theta completed
    from ``q_measured + driven_joint_offset`` (rad) by ``link`` on ``from_rocker``'s ``branch``. One reading (floats:
    UnreachableError where the rocker cannot take the angle) or arrays (NaN there). A calibrated linkage with its
    offsets leaves only the sensor's noise; a live check compares this with the calibration's residual RMS."""
    if isinstance(q_measured, (float, int)) and isinstance(sensor_theta, (float, int)):
        theta = float(link.from_rocker(float(q_measured) + driven_joint_offset, driven, branch).theta)
        return float(sensor_theta) - sensor_offset - theta
    theta_a = link.from_rocker(np.asarray(q_measured, dtype=np.float64) + driven_joint_offset, driven, branch,
                               on_invalid='nan').theta
    out: FloatArray = np.asarray(sensor_theta, dtype=np.float64) - sensor_offset - np.asarray(theta_a)
    return out


def imu_tilt(ax: FloatArray, az: FloatArray) -> FloatArray:
    """The antenna angle theta (rad) from an accelerometer at rest on the antenna: ``atan2(-a_x, a_z)``.

    The IMU's axes are the robot model's coupler frame (REP-103): x along the antenna (B -> C), y along the joint
    axes (the model's +y), z up when theta = 0. The coupler frame is the root turned by theta about +y, so at rest
    the measured specific force (gravity's reaction, +9.8 m/s^2 up) reads (-g sin theta, 0, g cos theta): positive
    theta (the antenna tilted down, x toward -z) gives a negative a_x. A small mounting error about y is the
    calibration's sensor offset; a mount turned about z or x changes the sign or the axis and must be undone first.
    """
    tilt: FloatArray = np.arctan2(-np.asarray(ax, dtype=np.float64), np.asarray(az, dtype=np.float64))
    return tilt


@dataclass(frozen=True)
class FittedParameter:
    """One parameter after the fit: value and posterior sd (m or rad), prior value and sd, and whether the data
    determined it (posterior sd below DETERMINED_RATIO of the prior sd) or the prior did."""

    name: str
    value: float
    sd: float
    prior: float
    prior_sd: float

    @property
    def determined_by_data(self) -> bool:
        return self.sd < DETERMINED_RATIO * self.prior_sd


@dataclass(frozen=True)
class Calibration:
    """The result of ``calibrate``.

    ``parameters``: PARAMETER_NAMES order. ``singular_values``: of the data part of the scaled Jacobian
    (J diag(prior sd) / sigma), largest first; ``directions``: the matching right singular vectors (rows, in the
    scaled parameters). ``sigma``: the readings' noise sd estimated from the residuals (rad). ``residuals_before``
    / ``residuals_after``: sensor minus prediction (rad) with the given lengths and zero offsets, and at the fit.
    """

    parameters: tuple[FittedParameter, ...]
    covariance: FloatArray
    singular_values: FloatArray
    directions: FloatArray
    sigma: float
    residuals_before: FloatArray
    residuals_after: FloatArray
    iterations: int
    passes: int

    @property
    def values(self) -> FloatArray:
        return np.array([p.value for p in self.parameters])

    @property
    def determined_directions(self) -> int:
        """How many directions the data determine (singular value above sqrt(1/DETERMINED_RATIO^2 - 1))."""
        return int(np.count_nonzero(self.singular_values > math.sqrt(DETERMINED_RATIO ** -2 - 1.0)))

    def parameter(self, name: str) -> FittedParameter:
        return self.parameters[PARAMETER_NAMES.index(name)]

    def linkage(self) -> AntennaLinkage:
        return _linkage(self.values)


def calibrate(q_measured: FloatArray, sensor_theta: FloatArray, lengths: tuple[float, float, float, float],
              driven: Driven, branch: Branch, length_sd: float = 5e-4, offset_sd: float = OFFSET_SD,
              max_iterations: int | None = None) -> Calibration:
    """Fit the lengths (m, prior ``lengths`` in LENGTH_NAMES order, sd ``length_sd`` m) and the offsets (rad, prior
    0, sd ``offset_sd``) to paired readings: measured driven joint ``q_measured`` (rad) and sensor ``sensor_theta``
    (rad), arrays of one length, in time order (the first noise estimate differences consecutive readings). Raises
    CalibrationError (one line) when the given geometry cannot take the
    measured joint or the fit does not converge (within ``max_iterations`` Levenberg-Marquardt iterations per pass,
    default MAX_ITERATIONS). The caller checks that the readings span the tilt range."""
    q = np.ascontiguousarray(q_measured, dtype=np.float64)
    y = np.ascontiguousarray(sensor_theta, dtype=np.float64)
    n = q.size
    if n != y.size or n <= len(PARAMETER_NAMES):
        raise CalibrationError(f'{n} paired readings: the fit needs more than {len(PARAMETER_NAMES)}')
    if not (length_sd > 0.0 and offset_sd > 0.0 and math.isfinite(length_sd) and math.isfinite(offset_sd)):
        raise CalibrationError(f'prior sds must be finite and positive (lengths {length_sd} m, offsets {offset_sd} '
                               'rad)')
    p0 = np.array([*map(float, lengths), 0.0, 0.0])
    sd = np.array([length_sd] * 4 + [offset_sd] * 2)

    def model(p: FloatArray) -> tuple[FloatArray, FloatArray]:
        return model_jacobian(p, q, driven, branch)

    pred0 = model(p0)[0]
    r0 = y - pred0
    if not np.all(np.isfinite(r0)):
        bad = int(np.count_nonzero(~np.isfinite(r0)))
        raise CalibrationError(f'{bad} of {n} measured joint angles are out of the given geometry\'s reach (first '
                               f'q={float(q[~np.isfinite(r0)][0])!r} rad): check the parameter file and the joint')
    fit = map_fit(model, y, p0, sd, PARAMETER_NAMES, max_iterations, unit='rad')
    return Calibration(fit.parameters, fit.covariance, fit.singular_values, fit.directions, fit.sigma, r0,
                       fit.residuals, fit.iterations, fit.passes)


@dataclass(frozen=True)
class MapFit:
    """What ``map_fit`` found: the parameters (value, posterior sd, prior), their covariance, the singular values
    and right singular vectors of the data part of the scaled Jacobian, the noise sd estimated from the residuals
    (the data's unit), the residuals (data minus model) at the fit, and the work done."""

    parameters: tuple[FittedParameter, ...]
    covariance: FloatArray
    singular_values: FloatArray
    directions: FloatArray
    sigma: float
    residuals: FloatArray
    iterations: int
    passes: int


Model = Callable[[FloatArray], tuple[FloatArray, FloatArray]]


def map_fit(model: Model, y: FloatArray, p0: FloatArray, sd: FloatArray, names: Sequence[str],
            max_iterations: int | None = None, unit: str = '') -> MapFit:
    """Maximum a posteriori fit of ``model`` (parameters -> (prediction (N,), Jacobian (N, k))) to data ``y`` (in
    time order) under the Gaussian prior N(p0, diag(sd^2)), the noise sd estimated from the residuals (passes
    re-estimating it until it settles). Raises CalibrationError when it does not converge."""
    n, k = y.size, p0.size
    iteration_limit = MAX_ITERATIONS if max_iterations is None else max_iterations
    r0 = y - model(p0)[0]
    z = np.zeros(k)  # scaled parameters: p = p0 + sd * z
    # First noise estimate: consecutive readings differ by their noise and little else (the model's error is smooth
    # along a sweep), so the passes re-estimating sigma start next to where they end.
    sigma = max(float(np.std(np.diff(r0))) / math.sqrt(2.0), 1e-12 * max(float(np.max(np.abs(y))), 1.0))
    iterations = passes = 0
    for _ in range(MAX_PASSES):
        passes += 1
        z, used = _levenberg_marquardt(z, p0, sd, sigma, y, model, iteration_limit)
        iterations += used
        r = y - model(p0 + sd * z)[0]
        new_sigma = max(math.sqrt(_square(r) / (n - k)), 1e-300)
        settled = abs(new_sigma - sigma) <= SIGMA_TOL * sigma
        sigma = new_sigma
        if settled:
            break
    else:
        raise CalibrationError(f'the fit did not converge: the noise estimate still moved after {MAX_PASSES} '
                               f'passes (sigma {sigma:.3g} {unit})')
    p = p0 + sd * z
    pred, jac = model(p)
    js = jac * (sd / sigma)
    cov_scaled = np.linalg.inv(_normal(js) + np.eye(k))
    covariance: FloatArray = np.asarray(cov_scaled * np.outer(sd, sd), dtype=np.float64)
    singular, directions = np.linalg.svd(js, full_matrices=False)[1:]
    params = tuple(FittedParameter(name, float(p[i]), float(math.sqrt(covariance[i, i])), float(p0[i]),
                                   float(sd[i])) for i, name in enumerate(names))
    return MapFit(params, covariance, singular, directions, sigma, y - pred, iterations, passes)


def _normal(js: FloatArray) -> FloatArray:
    """J^T J (k x k) without BLAS threads, which cost more than they save on a few columns."""
    out: FloatArray = np.einsum('ij,ik->jk', js, js)
    return out


def _square(r: FloatArray) -> float:
    """|r|^2 (einsum: no BLAS threads for a dot product)."""
    return float(np.einsum('i,i->', r, r))


def _cost(z: FloatArray, r: FloatArray, sigma: float) -> float:
    return _square(r) / (sigma * sigma) + _square(z)


def _levenberg_marquardt(z: FloatArray, p0: FloatArray, sd: FloatArray, sigma: float, y: FloatArray, model: Model,
                         max_iterations: int) -> tuple[FloatArray, int]:
    """Minimise |r(z)|^2 / sigma^2 + |z|^2 over the scaled parameters z; (z, iterations). Raises CalibrationError
    if it does not converge within max_iterations. Damped by lam I (Levenberg): in the scaled parameters the prior
    adds I to the normal matrix, so every direction has curvature at least 1; Marquardt's diag(A) would damp the
    directions the data barely see (mixtures of parameters the data see well) by the stiff ones' curvature and
    crawl along them."""
    lam = 1e-3
    k = z.size
    pred, jac = model(p0 + sd * z)
    r = y - pred
    cost = _cost(z, r, sigma)
    for it in range(1, max_iterations + 1):
        js = jac * (sd / sigma)          # d pred / dz, whitened
        g = np.einsum('ij,i->j', js, r) / sigma - z  # minus half the gradient of the cost
        a = _normal(js) + np.eye(k)
        while True:
            try:
                step = np.linalg.solve(a + lam * np.eye(k), g)
            except np.linalg.LinAlgError:
                step = np.full(k, np.nan)
            trial = z + step
            t_pred, t_jac = model(p0 + sd * trial) if np.all(np.isfinite(step)) else (np.full_like(y, np.nan), jac)
            t_r = y - t_pred
            t_cost = _cost(trial, t_r, sigma) if np.all(np.isfinite(t_r)) else math.inf
            if t_cost <= cost:
                break
            lam *= 10.0
            if lam > 1e12:
                # No step lowers the cost: z is a minimum to the precision of the model.
                return z, it
        decrease = cost - t_cost
        z, r, jac, cost = trial, t_r, t_jac, t_cost
        lam = max(lam / 10.0, 1e-12)
        if float(np.max(np.abs(step))) < STEP_TOL or decrease <= COST_TOL:
            return z, it
    raise CalibrationError(f'the fit did not converge in {max_iterations} iterations (last step '
                           f'{float(np.max(np.abs(step))):.3g} prior sds)')
