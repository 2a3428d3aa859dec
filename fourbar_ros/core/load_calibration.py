"""The load model fitted to the driven joint's measured effort: mass, centre of mass, friction, reducer efficiency.

Fitted after the geometry (core/calibration.py), whose covariance it carries into its own; the model and the report:
docs/how-to/calibrate.md."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
import numpy.typing as npt

from fourbar_ros.core.antenna import AntennaLinkage, Branch, Driven
from fourbar_ros.core.calibration import LENGTH_NAMES, CalibrationError, MapFit, linkage_of, map_fit
from fourbar_ros.core.numeric import FloatArray

__all__ = ['LOAD_NAMES', 'LOAD_TARGETS', 'MOVING', 'Geometry', 'LoadPose', 'LoadPrior', 'calibrate_load',
           'effort_model', 'load_pose', 'target_sd', 'written']

#: The fitted load parameters, in order: kg, m, m, N m, N m s/rad, dimensionless.
LOAD_NAMES = ('antenna_mass', 'com_offset_along', 'com_offset_normal', 'coulomb_friction', 'viscous_friction',
              'reducer_efficiency')
#: Readings slower than this fraction of the top |q_dot| count as at rest and are left out.
MOVING = 0.05
#: The load parameters that are node parameters, and the sd each must reach to be written to the parameter file:
#: (absolute, relative to its value), the larger counts. The mass to 5%, the centre of mass to 5 mm, the efficiency
#: to 0.05.
LOAD_TARGETS = {'antenna_mass': (0.0, 0.05), 'com_offset_along': (0.005, 0.0), 'com_offset_normal': (0.005, 0.0),
                'reducer_efficiency': (0.05, 0.0)}
#: Levenberg-Marquardt iterations per pass of the load fit: over a tilt sweep the mass and the centre of mass are
#: nearly collinear, and on a geometry a fraction of a mm off the fit walks a long valley (up to 320 iterations seen).
LOAD_ITERATIONS = 2000
#: Central-difference step (m for the lengths, rad for the driven joint's offset) of the effort's derivative by the
#: geometry: far above the effort's rounding (1e-16 relative), far below the geometry's sds (1e-4 m, 1e-3 rad).
GEOMETRY_STEP = 1e-7


def written(fit: MapFit) -> dict[str, float]:
    """The fitted load parameters to write to the parameter file (name -> value): those whose sd meets its target
    (``target_sd``); the centre of mass only with the mass (the node's torque takes the mass times the offsets, and
    an offset fitted beside a mass that moved is wrong with it); the efficiency only within (0, 1]."""
    fitted = {p.name: p for p in fit.parameters}
    out = {name: fitted[name].value for name in LOAD_TARGETS
           if fitted[name].sd <= (target_sd(name, fitted[name].value) or 0.0)}
    if 'antenna_mass' not in out:
        out.pop('com_offset_along', None)
        out.pop('com_offset_normal', None)
    if not 0.0 < out.get('reducer_efficiency', 1.0) <= 1.0:
        del out['reducer_efficiency']
    return out


def target_sd(name: str, value: float) -> float | None:
    """The sd (LOAD_NAMES units) a load parameter of ``value`` must reach to be written (``LOAD_TARGETS``), or None
    for one that is not written."""
    if name not in LOAD_TARGETS:
        return None
    absolute, relative = LOAD_TARGETS[name]
    return max(absolute, relative * abs(value))


@dataclass(frozen=True)
class Geometry:
    """The calibrated geometry the load model stands on: its ``values`` (``calibration.PARAMETER_NAMES`` order: four
    lengths m, driven joint offset rad, sensor offset rad) and their posterior ``covariance`` (6 x 6)."""

    values: FloatArray
    covariance: FloatArray



@dataclass(frozen=True)
class LoadPrior:
    """Prior means and sds of the load parameters (LOAD_NAMES units). The defaults are weak."""

    antenna_mass: float = 0.0
    com_offset_along: float = 0.0
    com_offset_normal: float = 0.0
    coulomb_friction: float = 0.0
    viscous_friction: float = 0.0
    reducer_efficiency: float = 1.0
    mass_sd: float = 10.0
    offset_sd: float = 0.05
    friction_sd: float = 1.0
    viscous_sd: float = 100.0
    efficiency_sd: float = 0.3

    def means(self) -> FloatArray:
        return np.array([self.antenna_mass, self.com_offset_along, self.com_offset_normal, self.coulomb_friction,
                         self.viscous_friction, self.reducer_efficiency])

    def sds(self) -> FloatArray:
        return np.array([self.mass_sd, self.offset_sd, self.offset_sd, self.friction_sd, self.viscous_sd,
                         self.efficiency_sd])


@dataclass(frozen=True)
class LoadPose:
    """What the effort model needs per reading: the pose's terms, fixed by the geometry."""

    lever: FloatArray     # dtheta/dq
    base: FloatArray      # AB cos(gamma) dgamma/dtheta - (h/2) cos(theta), m/rad
    cos_t: FloatArray
    sin_t: FloatArray
    direction: FloatArray  # sign(q_dot)
    rate: FloatArray       # q_dot, rad/s


def load_pose(link: AntennaLinkage, q: FloatArray, q_rate: FloatArray, driven: Driven, branch: Branch) -> LoadPose:
    """The pose terms of the effort model at the true driven joint ``q`` (rad) moving at ``q_rate`` (rad/s)."""
    theta, other = (np.asarray(a) for a in link.from_rocker(q, driven, branch, on_invalid='nan'))
    gamma, delta = (q, other) if driven is Driven.GAMMA else (other, q)
    rates = link.rates_at(theta, gamma, delta)
    advantage = np.asarray(rates.dgamma_dtheta if driven is Driven.GAMMA else rates.ddelta_dtheta)
    with np.errstate(divide='ignore'):
        lever = 1.0 / advantage
    cos_t = np.cos(theta)
    base = link.rocker_ab * np.cos(gamma) * np.asarray(rates.dgamma_dtheta) - 0.5 * link.coupler * cos_t
    return LoadPose(lever, base, cos_t, np.sin(theta), np.sign(q_rate), np.asarray(q_rate, dtype=np.float64))


def effort_model(p: FloatArray, pose: LoadPose, gravity: float) -> tuple[FloatArray, FloatArray]:
    """(tau_m (N m), d tau_m / d p (N, 6)) for the load parameters ``p`` (LOAD_NAMES order) at the poses."""
    m, along, normal, c, b, eta = (float(x) for x in p)
    height_rate = pose.base - along * pose.cos_t - normal * pose.sin_t
    tau_in = m * gravity * height_rate * pose.lever
    driving = tau_in * pose.direction > 0.0
    k = np.where(driving, 1.0 / eta, eta)
    jac = np.empty((6, pose.lever.size))
    np.multiply(k * gravity * height_rate, pose.lever, out=jac[0])
    np.multiply(-k * m * gravity * pose.cos_t, pose.lever, out=jac[1])
    np.multiply(-k * m * gravity * pose.sin_t, pose.lever, out=jac[2])
    jac[3] = pose.direction
    jac[4] = pose.rate
    jac[5] = np.where(driving, -tau_in / (eta * eta), tau_in)
    return k * tau_in + c * pose.direction + b * pose.rate, jac.T


def calibrate_load(geometry: Geometry, q_measured: FloatArray, q_rate: FloatArray, effort: FloatArray,
                   driven: Driven, branch: Branch, gravity: float, prior: LoadPrior = LoadPrior()
                   ) -> tuple[MapFit, npt.NDArray[np.bool_]]:
    """Fit the load parameters to the measured effort (N m) at the measured driven joint ``q_measured`` (rad, the
    geometry's driven joint offset added here) moving at ``q_rate`` (rad/s), arrays in time order, on the calibrated
    ``geometry``. (fit, mask of the readings used: moving, all finite); the fit's covariance and sds include the
    geometry's uncertainty carried through (``_geometry_covariance``). Raises CalibrationError when too few readings
    move or the fit does not converge."""
    q_measured, q_rate, effort = (np.asarray(a, dtype=np.float64) for a in (q_measured, q_rate, effort))
    top = float(np.max(np.abs(q_rate[np.isfinite(q_rate)]), initial=0.0))
    used = np.isfinite(q_measured) & np.isfinite(q_rate) & np.isfinite(effort) & (np.abs(q_rate) > MOVING * top)
    if top == 0.0 or int(np.count_nonzero(used)) <= 10 * len(LOAD_NAMES):
        raise CalibrationError(f'{int(np.count_nonzero(used))} readings of a moving joint with an effort: too few '
                               'for the load model')
    q, rate = q_measured[used], q_rate[used]

    def pose_of(values: FloatArray) -> LoadPose:
        return load_pose(linkage_of(values), q + values[4], rate, driven, branch)

    pose = pose_of(geometry.values)
    keep = np.isfinite(pose.lever) & np.isfinite(pose.base)
    if not keep.all():
        raise CalibrationError(f'{int(np.count_nonzero(~keep))} readings at a dead point or out of reach')

    def model(p: FloatArray) -> tuple[FloatArray, FloatArray]:
        return effort_model(p, pose, gravity)

    fit = map_fit(model, effort[used], prior.means(), prior.sds(), LOAD_NAMES, LOAD_ITERATIONS, unit='N m')
    return _with_geometry(fit, geometry, pose_of, gravity), used


def _with_geometry(fit: MapFit, geometry: Geometry, pose_of: Callable[[FloatArray], LoadPose],
                   gravity: float) -> MapFit:
    """``fit`` with the geometry's covariance carried into its covariance and sds: to first order the fitted load
    moves by S dg when the geometry moves by dg, S = -C J^T W G (C the fit's covariance, J its Jacobian, W the
    kept readings' weights, G the effort's derivative by the geometry), so the covariance gains S Cov(g) S^T."""
    p = np.array([x.value for x in fit.parameters])
    values = geometry.values
    jac = effort_model(p, pose_of(values), gravity)[1][fit.kept]
    by_geometry = np.zeros((jac.shape[0], values.size))
    for i in range(len(LENGTH_NAMES) + 1):  # the lengths and the driven joint's offset; the sensor's plays no part
        up, down = values.copy(), values.copy()
        up[i] += GEOMETRY_STEP
        down[i] -= GEOMETRY_STEP
        by_geometry[:, i] = ((effort_model(p, pose_of(up), gravity)[0] - effort_model(p, pose_of(down), gravity)[0])
                             [fit.kept] / (2.0 * GEOMETRY_STEP))
    if not np.isfinite(by_geometry).all():
        raise CalibrationError('the load model is not differentiable in the geometry at every reading: a reading '
                               'lies at a dead point')
    weight = fit.independent / fit.sigma ** 2
    sensitivity = fit.covariance @ (jac.T @ by_geometry) * weight
    covariance = fit.covariance + sensitivity @ geometry.covariance @ sensitivity.T
    sds = np.sqrt(np.diag(covariance))
    return replace(fit, covariance=covariance,
                   parameters=tuple(replace(x, sd=float(sd)) for x, sd in zip(fit.parameters, sds, strict=True)))
