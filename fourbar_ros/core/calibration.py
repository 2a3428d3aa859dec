"""Calibration of the linkage as built: the four lengths and two offsets fitted to an antenna angle sensor.

The model, the fit and what the report means: docs/how-to/calibrate.md; the exact Jacobian:
docs/explanation/exactness.md."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from fourbar_ros.core.antenna import AntennaLinkage, Branch, Driven
from fourbar_ros.core.errors import FourBarError
from fourbar_ros.core.numeric import ArrayLike, FloatArray

__all__ = [
    'BOTH_WAYS_FRACTION',
    'DEFAULT_LOSS',
    'DETERMINED_RATIO',
    'GRAVITY',
    'LENGTH_BOUND',
    'LENGTH_NAMES',
    'LOSSES',
    'OFFSET_SD',
    'PARAMETER_NAMES',
    'PRIOR_SDS_LIMIT',
    'REST_SPAN',
    'SCALE_LIMITS',
    'SET_ASIDE_SDS',
    'YAW_ARC',
    'Calibration',
    'CalibrationError',
    'DirectionTerms',
    'FittedParameter',
    'MapFit',
    'Reference',
    'RestZero',
    'calibrate',
    'check_sensor_scale',
    'direction_terms',
    'far_from_prior',
    'imu_roll',
    'imu_tilt',
    'imu_valid',
    'imu_yaw',
    'linkage_of',
    'map_fit',
    'model_jacobian',
    'model_mismatch',
    'one_way',
    'predict',
    'rest_zero',
    'sensor_scale',
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
#: During the fit each length stays within this fraction of its prior (a trial step outside, or one whose linkage
#: cannot assemble or reach a measured joint angle, is refused like a step that raises the cost).
LENGTH_BOUND = 0.5
#: Robust losses of the first stage (rho of u^2, u = residual / (F_SCALE noise sd)): 'soft_l1' 2(sqrt(1 + u^2) - 1),
#: 'huber' u^2 within 1 and 2|u| - 1 beyond, 'cauchy' log(1 + u^2); 'linear' u^2 (no robust stage).
LOSSES = ('soft_l1', 'huber', 'cauchy', 'linear')
DEFAULT_LOSS = 'soft_l1'
F_SCALE = 1.0
#: The robust stage ends when a pass moves the parameters less than this (prior sds), after MAX_PASSES at most: it
#: only finds the outliers and the start of the Gaussian fit.
ROBUST_TOL = 1e-3
#: After the robust stage, readings whose residual exceeds this many robust noise sds are set aside; the Gaussian
#: fit (and its sds) uses the rest. Gaussian noise passes 6 sd once in 5e8 readings.
SET_ASIDE_SDS = 6.0
#: The sensor must move between these many times as far as the parameter file's model over the same joint motion.
SCALE_LIMITS = (0.8, 1.25)
#: A fitted parameter further than this many prior sds from its prior is refused: the prior or the data are wrong.
PRIOR_SDS_LIMIT = 4.0
#: Residuals correlated from one reading to the next (a sensor's own filter, a misfit smooth along the sweep) hold
#: fewer independent readings: when their lag-1 correlation rho exceeds this many times 1/sqrt(n) (white noise's sd
#: of it), each reading's weight is (1 - rho) / (1 + rho), an AR(1) noise's share of independent readings.
CORRELATION_SDS = 2.0
#: A recording sweeps both ways when its largest rise and its largest fall of the joint each cover this fraction of
#: the joint's span.
BOTH_WAYS_FRACTION = 0.5
#: An IMU reading counts when its acceleration's norm is within this fraction of standard gravity (9.80665 m/s^2):
#: at rest it reads gravity; an all-zero or wildly off vector is a fault.
GRAVITY = 9.80665
GRAVITY_TOLERANCE = 0.5


class CalibrationError(FourBarError):
    """Data that cannot calibrate the linkage, or a fit that does not converge (one line)."""


def linkage_of(p: FloatArray) -> AntennaLinkage:
    """The linkage of parameters ``p`` (PARAMETER_NAMES order: its first four, the lengths in m)."""
    return AntennaLinkage(frame=float(p[0]), rocker_ab=float(p[1]), coupler=float(p[2]), rocker_cd=float(p[3]))


def predict(p: FloatArray, q_measured: FloatArray, driven: Driven, branch: Branch) -> FloatArray:
    """The sensor reading (rad) the parameters ``p`` (PARAMETER_NAMES order: m, m, m, m, rad, rad) predict for the
    measured driven joint ``q_measured`` (rad); NaN where the rocker cannot take q_measured + driven_joint_offset.
    ``branch`` is ``from_rocker``'s (``AntennaConfig.measured_branch``)."""
    link = linkage_of(p)
    theta = link.from_rocker(np.asarray(q_measured, dtype=np.float64) + p[4], driven, branch, on_invalid='nan').theta
    out: FloatArray = np.asarray(theta, dtype=np.float64) + p[5]
    return out


def model_jacobian(p: FloatArray, q_measured: FloatArray, driven: Driven,
                   branch: Branch) -> tuple[FloatArray, FloatArray]:
    """(prediction (N,) rad, d prediction / d p (N, 6): rad/m for the lengths, rad/rad for the offsets), exact by
    implicit differentiation of the loop closure (module docstring)."""
    ab, h, cd = float(p[1]), float(p[2]), float(p[3])
    q = np.asarray(q_measured, dtype=np.float64) + p[4]
    link = linkage_of(p)
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


#: The arc gravity traces over a sweep must stand this many times above its scatter for ``imu_yaw`` (a 13 deg sweep
#: read with 0.02 m/s^2 of noise: about 30).
YAW_ARC = 5.0


def imu_tilt(ax: ArrayLike, ay: ArrayLike, az: ArrayLike, yaw: float = 0.0) -> FloatArray:
    """The antenna angle theta (rad) from an accelerometer at rest on the antenna, mounted turned by ``yaw`` (rad)
    about its z axis: ``atan2(-a'_x, hypot(a'_y, a_z))`` of the reading turned back by the yaw (``a' = Rz(yaw) a``).

    The IMU's axes are the robot model's coupler frame (REP-103): x along the antenna (B -> C), y along the joint
    axes (the model's +y), z up when theta = 0. The coupler frame is the root turned by theta about +y, so at rest
    the measured specific force (gravity's reaction, +9.8 m/s^2 up) reads (-g sin theta, 0, g cos theta): positive
    theta (the antenna tilted down, x toward -z) gives a negative a_x. An IMU mounted rolled by phi about x, then
    yawed by psi about its z (frame Rx(phi) Rz(psi) of the coupler's) reads Rz(-psi) of (-g sin theta,
    g cos theta sin phi, g cos theta cos phi): undoing the yaw and taking the hypot makes theta independent of the
    roll (``imu_roll``); the yaw comes from the sweep (``imu_yaw``). A small mounting error about y is the
    calibration's sensor offset.
    """
    x, y, z = (np.asarray(a, dtype=np.float64) for a in (ax, ay, az))
    if yaw != 0.0:
        c, s = math.cos(yaw), math.sin(yaw)
        x, y = c * x - s * y, s * x + c * y
    tilt: FloatArray = np.arctan2(-x, np.hypot(y, z))
    return tilt


def imu_yaw(ax: ArrayLike, ay: ArrayLike, az: ArrayLike) -> float:
    """The IMU's yaw psi about its z axis (rad, ``imu_tilt``'s), from readings at rest over a sweep about the joint:
    the unit gravity vectors lie on a great circle whose normal is the joint axis in the IMU's frame,
    (cos phi sin psi, cos phi cos psi, -sin phi); the normal is the plane's least singular vector, turned to +y.
    NaN when the readings do not trace an arc (fewer than 3, or the arc's singular value under YAW_ARC times the
    scatter's about it or under 1e-3 of the mean direction's, about a 0.2 deg arc: one pose, or a sweep lost in
    the noise)."""
    u = np.column_stack([np.asarray(a, dtype=np.float64) for a in (ax, ay, az)])
    u = u[np.isfinite(u).all(axis=1)]
    if u.shape[0] < 3:
        return math.nan
    u = u / np.linalg.norm(u, axis=1)[:, None]
    _, singular, rows = np.linalg.svd(u, full_matrices=False)
    if not singular[1] >= max(YAW_ARC * singular[2], 1e-3 * singular[0]):
        return math.nan
    normal = rows[-1]
    if normal[1] < 0.0:
        normal = -normal
    return math.atan2(float(normal[0]), float(normal[1]))


def imu_roll(ax: ArrayLike, ay: ArrayLike, az: ArrayLike, yaw: float = 0.0) -> FloatArray:
    """The IMU's roll phi about its x axis (rad): ``atan2(a'_y, a_z)`` of the reading at rest turned back by the
    yaw (imu_tilt's), 0 when mounted as the coupler frame."""
    x, y = np.asarray(ax, dtype=np.float64), np.asarray(ay, dtype=np.float64)
    roll: FloatArray = np.arctan2(math.sin(yaw) * x + math.cos(yaw) * y, np.asarray(az, dtype=np.float64))
    return roll


def imu_valid(ax: ArrayLike, ay: ArrayLike, az: ArrayLike) -> npt.NDArray[np.bool_]:
    """Element-wise: is the acceleration (m/s^2) a reading at rest, all finite with its norm within
    GRAVITY_TOLERANCE of GRAVITY? False for a non-finite component or an all-zero vector (a dropped reading)."""
    with np.errstate(invalid='ignore'):
        norm = np.sqrt(np.square(ax) + np.square(ay) + np.square(az))
        ok: npt.NDArray[np.bool_] = np.asarray(np.abs(norm - GRAVITY) <= GRAVITY_TOLERANCE * GRAVITY)
    return ok


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
class Reference:
    """A known antenna angle at a pose, e.g. from a precision level: the measured driven joint ``joint`` (rad, as
    the recording's joint states report it), the antenna angle ``theta`` there (rad, positive tilts the antenna
    down) and its sd (rad)."""

    joint: float
    theta: float
    sd: float


@dataclass(frozen=True)
class Calibration:
    """The result of ``calibrate``.

    ``parameters``: PARAMETER_NAMES order. ``singular_values``: of the data part of the scaled Jacobian
    (J diag(prior sd) / sigma), largest first; ``directions``: the matching right singular vectors (rows, in the
    scaled parameters). ``sigma``: the readings' noise sd estimated from the residuals (rad). ``residuals_before``
    / ``residuals_after``: sensor minus prediction (rad) with the given lengths and zero offsets, and at the fit;
    ``kept``: the readings the fit used (the rest set aside as outliers); ``correlation`` / ``independent``: the
    residuals' lag-1 correlation and the weight it left each reading (map_fit). ``sources``: each source of information
    (the readings, each prior, each reference) and its information matrix (k x k, 1/(parameter units)^2), whose sum
    is the inverse of ``covariance``.
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
    kept: npt.NDArray[np.bool_]
    sources: tuple[tuple[str, FloatArray], ...]
    driven: Driven
    branch: Branch
    references: tuple[Reference, ...] = ()
    correlation: float = 0.0
    independent: float = 1.0

    @property
    def values(self) -> FloatArray:
        return np.array([p.value for p in self.parameters])

    @property
    def set_aside(self) -> int:
        """Readings set aside as outliers (residual beyond SET_ASIDE_SDS robust noise sds)."""
        return int(np.count_nonzero(~self.kept))

    @property
    def determined_directions(self) -> int:
        """How many directions the data determine (singular value above sqrt(1/DETERMINED_RATIO^2 - 1))."""
        return int(np.count_nonzero(self.singular_values > math.sqrt(DETERMINED_RATIO ** -2 - 1.0)))

    def parameter(self, name: str) -> FittedParameter:
        return self.parameters[PARAMETER_NAMES.index(name)]

    def linkage(self) -> AntennaLinkage:
        return linkage_of(self.values)

    def _gradients(self, joint: ArrayLike, with_sensor: bool) -> tuple[FloatArray, FloatArray]:
        q = np.atleast_1d(np.asarray(joint, dtype=np.float64))
        value, jac = model_jacobian(self.values, q, self.driven, self.branch)
        if not with_sensor:
            value = value - self.values[5]
            jac = jac.copy()
            jac[:, 5] = 0.0
        return value, jac

    def angle(self, joint: ArrayLike, with_sensor: bool = False) -> tuple[FloatArray, FloatArray]:
        """(value, sd) at the measured driven joint ``joint`` (rad, as recorded): the antenna angle the node
        computes with the calibrated parameters (rad; with ``with_sensor`` the sensor's predicted reading, sensor
        offset included), and its sd (rad) from the full posterior covariance through the model's Jacobian."""
        value, jac = self._gradients(joint, with_sensor)
        var = np.einsum('ij,jk,ik->i', jac, self.covariance, jac)
        return value, np.sqrt(np.maximum(var, 0.0))

    def variance_sources(self, joint: float, with_sensor: bool = False) -> dict[str, float]:
        """The variance (rad^2) of ``angle(joint)`` split by source: (C g)^T H_s (C g) for each source's
        information H_s, C the covariance, g the gradient; the parts are non-negative and add up to sd^2."""
        g = self._gradients(joint, with_sensor)[1][0]
        cg = self.covariance @ g
        return {name: float(cg @ info @ cg) for name, info in self.sources}


def calibrate(q_measured: FloatArray, sensor_theta: FloatArray, lengths: tuple[float, float, float, float],
              driven: Driven, branch: Branch, length_sd: float = 5e-4, offset_sd: float = OFFSET_SD,
              max_iterations: int | None = None, *, sensor_offset: float = 0.0,
              sensor_offset_sd: float = OFFSET_SD, references: Sequence[Reference] = (),
              loss: str = DEFAULT_LOSS) -> Calibration:
    """Fit the lengths (m, prior ``lengths`` in LENGTH_NAMES order, sd ``length_sd`` m) and the offsets (rad:
    driven_joint_offset prior 0 sd ``offset_sd``, sensor_offset prior ``sensor_offset`` sd ``sensor_offset_sd``)
    to paired readings: measured driven joint ``q_measured`` (rad) and sensor ``sensor_theta`` (rad), arrays of
    one length, in time order (the first noise estimate differences consecutive readings), and to the
    ``references`` (known antenna angles, exact rows of known sd). A robust first stage (``loss``, LOSSES) finds
    the outliers, set aside beyond SET_ASIDE_SDS; the Gaussian fit uses the rest. Raises CalibrationError (one
    line) when the given geometry cannot take the measured joint or the fit does not converge (within
    ``max_iterations`` Levenberg-Marquardt iterations per pass, default MAX_ITERATIONS). The caller checks the
    span and the sensor's scale (``check_sensor_scale``) first."""
    q = np.ascontiguousarray(q_measured, dtype=np.float64)
    y = np.ascontiguousarray(sensor_theta, dtype=np.float64)
    n = q.size
    if n != y.size or n <= len(PARAMETER_NAMES):
        raise CalibrationError(f'{n} paired readings: the fit needs more than {len(PARAMETER_NAMES)}')
    sds = (length_sd, offset_sd, sensor_offset_sd, *(r.sd for r in references))
    if not all(math.isfinite(x) and x > 0.0 for x in sds):
        raise CalibrationError(f'prior sds must be finite and positive (lengths {length_sd} m, offsets {offset_sd} '
                               f'and {sensor_offset_sd} rad, references {[r.sd for r in references]} rad)')
    if not all(math.isfinite(x) for r in references for x in (r.joint, r.theta)) or not math.isfinite(sensor_offset):
        raise CalibrationError('the references and the sensor offset must be finite')
    p0 = np.array([*map(float, lengths), 0.0, float(sensor_offset)])
    sd = np.array([length_sd] * 4 + [offset_sd, sensor_offset_sd])
    q_ref = np.array([r.joint for r in references], dtype=np.float64)
    y_ref = np.array([r.theta for r in references], dtype=np.float64)
    span = LENGTH_BOUND * p0[:4]

    def model(p: FloatArray) -> tuple[FloatArray, FloatArray]:
        if np.any(np.abs(p[:4] - p0[:4]) > span):
            nan = np.full(n + q_ref.size, np.nan)
            return nan, np.full((nan.size, p.size), np.nan)
        try:
            pred, jac = model_jacobian(p, np.concatenate((q, q_ref)), driven, branch)
        except FourBarError:  # the trial lengths make no linkage: refused like an unreachable pose
            nan = np.full(n + q_ref.size, np.nan)
            return nan, np.full((nan.size, p.size), np.nan)
        pred[n:] -= p[5]  # a reference is the antenna's angle, without the sensor's offset
        jac[n:, 5] = 0.0
        return pred, jac

    pred0 = model(p0)[0]
    r0 = np.concatenate((y, y_ref)) - pred0
    for what, joints, bad in (('measured', q, ~np.isfinite(r0[:n])), ('reference', q_ref, ~np.isfinite(r0[n:]))):
        if bad.any():
            raise CalibrationError(f'{int(np.count_nonzero(bad))} of {bad.size} {what} joint angles are out of the '
                                   f'given geometry\'s reach (first q={float(joints[bad][0])!r} rad): check the '
                                   'parameter file and the joint')
    fit = map_fit(model, np.concatenate((y, y_ref)), p0, sd, PARAMETER_NAMES, max_iterations, unit='rad',
                  known_sd=np.array([r.sd for r in references], dtype=np.float64), loss=loss)
    sources = [(f'the noise of the {int(np.count_nonzero(fit.kept))} readings', fit.data_information)]
    sources += [(f'the prior of {name} (sd {sd[i]:.3g} {"m" if i < 4 else "rad"})',
                 np.diag(np.eye(len(sd))[i] / sd[i] ** 2)) for i, name in enumerate(PARAMETER_NAMES)]
    sources += [(f'the reference at joint {r.joint:.6g} rad (sd {r.sd:.3g} rad)', np.outer(row, row))
                for r, row in zip(references, fit.known_rows, strict=True)]
    return Calibration(fit.parameters, fit.covariance, fit.singular_values, fit.directions, fit.sigma, r0[:n],
                       fit.residuals[:n], fit.iterations, fit.passes, fit.kept, tuple(sources), driven, branch,
                       tuple(references), fit.correlation, fit.independent)


def sensor_scale(q_measured: FloatArray, sensor_theta: FloatArray, link: AntennaLinkage, driven: Driven,
                 branch: Branch) -> float:
    """How far the sensor moves per antenna angle of ``link``'s model over the same joint motion (rad/rad; 1 for a
    sensor in rad with theta's sign): the medians of the readings above and below the model's median angle,
    differenced, over the model's (robust to outliers). NaN when the model's angle does not move."""
    theta = np.asarray(link.from_rocker(np.asarray(q_measured, dtype=np.float64), driven, branch,
                                        on_invalid='nan').theta)
    y = np.asarray(sensor_theta, dtype=np.float64)
    ok = np.isfinite(theta) & np.isfinite(y)
    theta, y = theta[ok], y[ok]
    if theta.size < 2:
        return math.nan
    mid = float(np.median(theta))
    hi, lo = theta > mid, theta <= mid
    if not (hi.any() and lo.any()):
        return math.nan
    moved = float(np.median(theta[hi]) - np.median(theta[lo]))
    return float(np.median(y[hi]) - np.median(y[lo])) / moved if moved > 0.0 else math.nan


def check_sensor_scale(scale: float) -> None:
    """Raise CalibrationError (one line naming the likely cause) unless ``scale`` (``sensor_scale``) is within
    SCALE_LIMITS."""
    lo, hi = SCALE_LIMITS
    if lo <= scale <= hi:
        return
    if not math.isfinite(scale):
        cause = 'the sensor does not follow the joint'
    elif -hi <= scale <= -lo:
        cause = 'its sign is flipped (theta is positive tilting the antenna down)'
    elif abs(abs(scale) - math.degrees(1.0)) <= 0.2 * math.degrees(1.0):
        cause = 'it reports degrees, not rad'
    else:
        cause = 'the sensor or the parameter file is wrong (its unit, its axis, the joint\'s scale)'
    raise CalibrationError(f'the sensor moves {scale:.3g} times as far as the model over the same joint motion '
                           f'(expected {lo}..{hi}): {cause}')


def far_from_prior(fit: Calibration) -> list[str]:
    """The fitted parameters further than PRIOR_SDS_LIMIT prior sds from their prior, each described."""
    return [f'{p.name} {p.value:.6g} is {abs(p.value - p.prior) / p.prior_sd:.1f} prior sds from its prior '
            f'{p.prior:.6g} (sd {p.prior_sd:.3g})' for p in fit.parameters
            if abs(p.value - p.prior) > PRIOR_SDS_LIMIT * p.prior_sd]


def one_way(q_measured: FloatArray) -> float:
    """The smaller of the joint's largest rise and largest fall (in time order) over its span, 0..1: a recording
    sweeps both ways when this reaches BOTH_WAYS_FRACTION."""
    q = np.asarray(q_measured, dtype=np.float64)
    if q.size < 2:
        return 0.0
    span = float(q.max() - q.min())
    if not span > 0.0:
        return 0.0
    rise = float(np.max(q - np.minimum.accumulate(q)))
    fall = float(np.max(np.maximum.accumulate(q) - q))
    return min(rise, fall) / span


@dataclass(frozen=True)
class DirectionTerms:
    """What of the residuals depends on the direction of motion, fitted to them after the calibration: the
    sensor's ``latency`` behind the encoder (s) and the ``backlash`` between the encoder and the rocker (rad at
    the joint), with their sds and correlation; ``shift`` the RMS over the recording of the change of the sensor
    reading they make (rad). Both move a reading one way on the way up and the other way down, so sweeps both ways leave
    the fitted geometry and offsets unbiased; the noise estimate and its correlation take them in (wider sds)."""

    latency: float
    latency_sd: float
    backlash: float
    backlash_sd: float
    correlation: float
    shift: float

    def significant(self, sds: float = PRIOR_SDS_LIMIT) -> list[str]:
        """The terms further than ``sds`` of their sd from 0, each as one phrase."""
        out = []
        if abs(self.latency) > sds * self.latency_sd:
            out.append(f'the sensor lags the encoder by {1e3 * self.latency:.3g} ms (sd {1e3 * self.latency_sd:.2g})')
        if abs(self.backlash) > sds * self.backlash_sd:
            out.append(f'the drive has {1e3 * self.backlash:.3g} mrad of play at the joint between encoder and '
                       f'antenna (sd {1e3 * self.backlash_sd:.2g})')
        return out


def direction_terms(fit: Calibration, q_measured: FloatArray, q_rate: FloatArray) -> DirectionTerms:
    """The latency and backlash of the readings ``fit`` was made from (``q_measured`` rad, and the joint's rate
    ``q_rate`` rad/s there), by least squares on its kept residuals: the sensor sees the rocker at
    q(t - latency) - sign(q_rate) backlash / 2, so residual = -dtheta/dq (latency q_rate + sign(q_rate) backlash / 2).
    Their sds from the fit's noise sd and its independent-readings weight. Raises CalibrationError when the joint
    never moves."""
    kept = fit.kept
    slope = model_jacobian(fit.values, np.asarray(q_measured)[kept], fit.driven, fit.branch)[1][:, 4]  # dtheta/dq
    rate = np.asarray(q_rate, dtype=np.float64)[kept]
    x = np.column_stack((-slope * rate, -0.5 * slope * np.sign(rate)))
    normal = _normal(x)
    if not (np.all(np.isfinite(normal)) and np.linalg.matrix_rank(normal) == 2):
        raise CalibrationError('the joint does not move both ways in the recording: no latency or backlash can show')
    cov = np.linalg.inv(normal) * fit.sigma ** 2 / fit.independent
    latency, backlash = np.linalg.solve(normal, np.einsum('ij,i->j', x, fit.residuals_after[kept]))
    sd = np.sqrt(np.diag(cov))
    return DirectionTerms(float(latency), float(sd[0]), float(backlash), float(sd[1]),
                          float(cov[0, 1] / (sd[0] * sd[1])), math.sqrt(_square(x @ (latency, backlash)) / rate.size))


#: A recording counts as at rest when its measured joint spans at most this (rad, 0.06 deg).
REST_SPAN = 1e-3


@dataclass(frozen=True)
class RestZero:
    """The driven joint's zero from the antenna sensor at rest (``rest_zero``): the ``correction`` (rad) to add to
    the measured joint for the true rocker angle, its ``sd`` (rad) from the readings' noise, the antenna angle
    ``theta`` (rad) the sensor gives, the readings used and set aside, and the joint's span over them (rad)."""

    correction: float
    sd: float
    theta: float
    readings: int
    set_aside: int
    joint_span: float


def rest_zero(link: AntennaLinkage, driven: Driven, branch: Branch, q_measured: FloatArray,
              sensor_theta: FloatArray, sensor_offset: float) -> RestZero:
    """The driven joint's zero from readings at rest: the antenna angle is the readings' mean (those within
    SET_ASIDE_SDS robust noise sds of their median) less ``sensor_offset`` (rad); the true rocker angle there (on
    ``branch``, the assembly) less the measured joint's mean is the correction. Its sd is the mean's (the noise sd
    over the root of the independent readings, CORRELATION_SDS) through drocker/dtheta; the calibration's own
    absolute-angle sd is not in it. Raises CalibrationError (one line) when the joint moved more than REST_SPAN, or
    the angle is out of the linkage's reach."""
    q = np.asarray(q_measured, dtype=np.float64)
    y = np.asarray(sensor_theta, dtype=np.float64)
    span = float(np.ptp(q)) if q.size else 0.0
    if q.size < 2 or span > REST_SPAN:
        raise CalibrationError(f'the joint moved {span:.3g} rad over {q.size} readings (at most {REST_SPAN:g}): '
                               'record the antenna at rest')
    noise = _robust_sd(y)
    kept = np.abs(y - np.median(y)) <= SET_ASIDE_SDS * noise if noise > 0.0 else np.ones(y.size, dtype=bool)
    n = int(np.count_nonzero(kept))
    rho = _lag1(y[kept])
    independent = (1.0 - rho) / (1.0 + rho) if rho > CORRELATION_SDS / math.sqrt(n) else 1.0
    theta = float(np.mean(y[kept])) - sensor_offset
    sd_theta = float(np.std(y[kept], ddof=1)) / math.sqrt(n * independent) if n > 1 else 0.0
    try:
        gamma, delta = link.rocker_angles(theta, branch)
        rates = link.rates_at(theta, gamma, delta)
    except FourBarError as exc:
        raise CalibrationError(f'the sensor reads theta = {theta:.6g} rad (its offset removed): {exc}') from None
    rocker, slope = (gamma, rates.dgamma_dtheta) if driven is Driven.GAMMA else (delta, rates.ddelta_dtheta)
    return RestZero(float(rocker) - float(np.mean(q)), abs(float(slope)) * sd_theta, theta, n, y.size - n, span)


@dataclass(frozen=True)
class MapFit:
    """What ``map_fit`` found: the parameters (value, posterior sd, prior), their covariance, the singular values
    and right singular vectors of the data part of the scaled Jacobian, the noise sd estimated from the residuals
    (the data's unit), the residuals (data minus model, every row) at the fit, and the work done; ``kept``: the data
    rows used (the rest set aside); ``data_information``: J^T J / sigma^2 of the kept rows, times
    ``independent`` (k x k, in the parameters' units); ``known_rows``: the known-sd rows' Jacobian over their sd
    (m x k); ``correlation``: the kept residuals' lag-1 correlation, ``independent`` the weight it gives each
    reading (CORRELATION_SDS)."""

    parameters: tuple[FittedParameter, ...]
    covariance: FloatArray
    singular_values: FloatArray
    directions: FloatArray
    sigma: float
    residuals: FloatArray
    iterations: int
    passes: int
    kept: npt.NDArray[np.bool_]
    data_information: FloatArray
    known_rows: FloatArray
    correlation: float = 0.0
    independent: float = 1.0


Model = Callable[[FloatArray], tuple[FloatArray, FloatArray]]


def _robust_sd(r: FloatArray) -> float:
    """The sd of Gaussian noise from its median absolute deviation (1.4826 MAD): outliers barely move it."""
    return 1.482602218505602 * float(np.median(np.abs(r - np.median(r)))) if r.size else 0.0


def _weights(u: FloatArray, loss: str) -> FloatArray:
    """Iteratively reweighted least squares: rho'(u^2) of LOSSES' rho, per residual u in F_SCALE noise sds."""
    u2 = u * u
    if loss == 'soft_l1':
        w: FloatArray = 1.0 / np.sqrt(1.0 + u2)
    elif loss == 'huber':
        w = np.where(u2 <= 1.0, 1.0, 1.0 / np.sqrt(np.maximum(u2, 1.0)))
    elif loss == 'cauchy':
        w = 1.0 / (1.0 + u2)
    else:
        w = np.ones_like(u2)
    return w


def map_fit(model: Model, y: FloatArray, p0: FloatArray, sd: FloatArray, names: Sequence[str],
            max_iterations: int | None = None, unit: str = '', *, known_sd: FloatArray | None = None,
            loss: str = 'linear') -> MapFit:
    """Maximum a posteriori fit of ``model`` (parameters -> (prediction, Jacobian)) to ``y``: its first rows data
    in time order whose noise sd is estimated from the residuals (passes re-estimating it until it settles), its
    last ``known_sd.size`` rows of known sd (never robustified nor set aside), under the Gaussian prior
    N(p0, diag(sd^2)). With a robust ``loss`` (LOSSES) a first stage reweights the data rows and sets aside those
    beyond SET_ASIDE_SDS robust noise sds. Raises CalibrationError when it does not converge; a model returning
    NaN refuses the trial step."""
    if loss not in LOSSES:
        raise CalibrationError(f'loss {loss!r}: one of {", ".join(LOSSES)}')
    known = np.zeros(0) if known_sd is None else np.asarray(known_sd, dtype=np.float64)
    m = known.size
    n, k = y.size - m, p0.size
    iteration_limit = MAX_ITERATIONS if max_iterations is None else max_iterations
    r0 = y[:n] - model(p0)[0][:n]
    z = np.zeros(k)  # scaled parameters: p = p0 + sd * z
    floor = 1e-12 * max(float(np.max(np.abs(y))), 1.0)
    # First noise estimate: consecutive readings differ by their noise and little else (the model's error is smooth
    # along a sweep), so the passes re-estimating sigma start next to where they end.
    diffs = np.diff(r0)
    first = _robust_sd(diffs) if loss != 'linear' else float(np.std(diffs))
    sigma = max(first / math.sqrt(2.0), floor)
    iterations = passes = 0
    kept = np.ones(n, dtype=bool)
    if loss != 'linear':
        weights = np.ones(n)
        for _ in range(MAX_PASSES):
            passes += 1
            scale = np.concatenate((np.sqrt(weights) / sigma, 1.0 / known))
            new_z, used = _levenberg_marquardt(z, p0, sd, scale, y, model, iteration_limit)
            iterations += used
            r = y[:n] - model(p0 + sd * new_z)[0][:n]
            sigma = max(_robust_sd(r), floor)
            weights = _weights(r / (F_SCALE * sigma), loss)
            moved = float(np.max(np.abs(new_z - z)))
            z = new_z
            if moved < ROBUST_TOL:
                break
        kept = np.abs(r) <= SET_ASIDE_SDS * sigma
        if int(np.count_nonzero(kept)) <= k:
            raise CalibrationError(f'{int(np.count_nonzero(kept))} of {n} readings within {SET_ASIDE_SDS:g} noise '
                                   f'sds of the robust fit: too few for the Gaussian fit')
        sigma = max(math.sqrt(_square(r[kept]) / (int(np.count_nonzero(kept)) - k)), floor)
    n_kept = int(np.count_nonzero(kept))
    independent = 1.0
    for _ in range(MAX_PASSES):
        passes += 1
        scale = np.concatenate((kept * math.sqrt(independent) / sigma, 1.0 / known))
        z, used = _levenberg_marquardt(z, p0, sd, scale, y, model, iteration_limit)
        iterations += used
        r = y[:n] - model(p0 + sd * z)[0][:n]
        new_sigma = max(math.sqrt(_square(r[kept]) / (n_kept - k)), 1e-300)
        correlation = _lag1(r[kept])
        new_independent = ((1.0 - correlation) / (1.0 + correlation)
                           if correlation > CORRELATION_SDS / math.sqrt(n_kept) else 1.0)
        settled = (abs(new_sigma - sigma) <= SIGMA_TOL * sigma
                   and abs(new_independent - independent) <= SIGMA_TOL * independent)
        sigma, independent = new_sigma, new_independent
        if settled:
            break
    else:
        raise CalibrationError(f'the fit did not converge: the noise estimate still moved after {MAX_PASSES} '
                               f'passes (sigma {sigma:.3g} {unit})')
    p = p0 + sd * z
    pred, jac = model(p)
    js = jac[:n][kept] * (sd * math.sqrt(independent) / sigma)
    jk = jac[n:] / known[:, None]
    cov_scaled = np.linalg.inv(_normal(js) + _normal(jk * sd) + np.eye(k))
    covariance: FloatArray = np.asarray(cov_scaled * np.outer(sd, sd), dtype=np.float64)
    singular, directions = np.linalg.svd(js, full_matrices=False)[1:]
    params = tuple(FittedParameter(name, float(p[i]), float(math.sqrt(covariance[i, i])), float(p0[i]),
                                   float(sd[i])) for i, name in enumerate(names))
    data_information = _normal(jac[:n][kept] * (math.sqrt(independent) / sigma))
    return MapFit(params, covariance, singular, directions, sigma, y - pred, iterations, passes, kept,
                  data_information, jk, correlation, independent)


def _lag1(r: FloatArray) -> float:
    """The lag-1 autocorrelation of ``r`` (in time order): sum r_i r_(i+1) over sum r_i^2, about its mean."""
    d = r - float(np.mean(r)) if r.size else r
    total = _square(d)
    return float(np.einsum('i,i->', d[1:], d[:-1])) / total if total > 0.0 else 0.0


def _normal(js: FloatArray) -> FloatArray:
    """J^T J (k x k) without BLAS threads, which cost more than they save on a few columns."""
    out: FloatArray = np.einsum('ij,ik->jk', js, js)
    return out


def _square(r: FloatArray) -> float:
    """|r|^2 (einsum: no BLAS threads for a dot product)."""
    return float(np.einsum('i,i->', r, r))


def _cost(z: FloatArray, r: FloatArray, scale: FloatArray) -> float:
    return _square(r * scale) + _square(z)


def _levenberg_marquardt(z: FloatArray, p0: FloatArray, sd: FloatArray, scale: FloatArray, y: FloatArray,
                         model: Model, max_iterations: int) -> tuple[FloatArray, int]:
    """Minimise |scale (y - model(z))|^2 + |z|^2 over the scaled parameters z (``scale``: per row, 1/sd); (z,
    iterations). Raises CalibrationError if it does not converge within max_iterations. Damped by lam I
    (Levenberg): in the scaled parameters the prior adds I to the normal matrix, so every direction has curvature
    at least 1; Marquardt's diag(A) would damp the directions the data barely see (mixtures of parameters the data
    see well) by the stiff ones' curvature and crawl along them. A trial whose prediction is not finite (the model
    refuses it) counts as a higher cost."""
    lam = 1e-3
    k = z.size
    pred, jac = model(p0 + sd * z)
    r = y - pred
    cost = _cost(z, r, scale)
    for it in range(1, max_iterations + 1):
        js = jac * (sd * scale[:, None])     # d pred / dz, whitened
        g = np.einsum('ij,i->j', js, r * scale) - z  # minus half the gradient of the cost
        a = _normal(js) + np.eye(k)
        while True:
            try:
                step = np.linalg.solve(a + lam * np.eye(k), g)
            except np.linalg.LinAlgError:
                step = np.full(k, np.nan)
            trial = z + step
            t_pred, t_jac = model(p0 + sd * trial) if np.all(np.isfinite(step)) else (np.full_like(y, np.nan), jac)
            t_r = y - t_pred
            t_cost = _cost(trial, t_r, scale) if np.all(np.isfinite(t_r)) else math.inf
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
