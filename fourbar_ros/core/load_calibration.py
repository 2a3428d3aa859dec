"""The load model fitted to the driven joint's measured effort: mass, centre of mass, friction, reducer efficiency.

Fitted after the geometry (core/calibration.py), jointly with it under the geometry's calibrated values and covariance;
the model and the report: docs/how-to/calibrate.md."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
import numpy.typing as npt

from fourbar_ros.core.antenna import AntennaLinkage, Branch, Driven
from fourbar_ros.core.calibration import (
    LENGTH_NAMES,
    CalibrationError,
    FittedParameter,
    MapFit,
    linkage_of,
    map_fit,
)
from fourbar_ros.core.numeric import FloatArray

__all__ = ['LOAD_NAMES', 'LOAD_TARGETS', 'MOMENT_NAMES', 'MOVING', 'Geometry', 'LoadPose', 'LoadPrior',
           'calibrate_load', 'effort_model', 'load_pose', 'target_sd', 'written']

#: The fitted load parameters, in order: kg, m, m, N m, N m s/rad, dimensionless.
LOAD_NAMES = ('antenna_mass', 'com_offset_along', 'com_offset_normal', 'coulomb_friction', 'viscous_friction',
              'reducer_efficiency')
#: The coordinates the load is fitted in: LOAD_NAMES with the centre of mass's offsets as moments (mass times
#: offset, kg m), in which the effort is linear in the mass and the moments: a tilt sweep fixes the moments and the
#: mass only through the sweep's curvature, a straight valley here and a curved one in the offsets.
MOMENT_NAMES = ('antenna_mass', 'moment_along', 'moment_normal', 'coulomb_friction', 'viscous_friction',
                'reducer_efficiency')
#: Readings slower than this fraction of the top |q_dot| count as at rest and are left out.
MOVING = 0.05
#: The load parameters that are node parameters, and the sd each must reach to be written to the parameter file:
#: (absolute, relative to its value), the larger counts. The mass to 5%, the centre of mass to 5 mm, the efficiency
#: to 0.05.
LOAD_TARGETS = {'antenna_mass': (0.0, 0.05), 'com_offset_along': (0.005, 0.0), 'com_offset_normal': (0.005, 0.0),
                'reducer_efficiency': (0.05, 0.0)}
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

    def moments(self) -> tuple[FloatArray, FloatArray]:
        """(means, sds) in the fit's coordinates (``MOMENT_NAMES``): the centre of mass's offsets as moments, kg m,
        of mean the mass's times the offset's and sd the offset's times the larger of the mass's mean and sd."""
        means, sds = self.means(), self.sds()
        scale = max(abs(self.antenna_mass), self.mass_sd)
        means[1:3] *= self.antenna_mass
        sds[1:3] *= scale
        return means, sds


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
    geometry's driven joint offset added here) moving at ``q_rate`` (rad/s), arrays in time order, jointly with the
    geometry under its calibrated values and covariance (``_geometry_basis``). (the load's marginal fit, mask of the
    readings used: moving, all finite). Raises CalibrationError when too few readings move or the fit does not
    converge."""
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
    basis = _geometry_basis(geometry)
    slopes = _pose_slopes(geometry.values, basis, pose_of, q.size)
    n_geometry = basis.shape[1]

    def model(p: FloatArray) -> tuple[FloatArray, FloatArray]:
        at = pose_of(geometry.values + np.pad(basis @ p[:n_geometry], (0, geometry.values.size - basis.shape[0])))
        return _moment_model(p[n_geometry:], at, slopes, gravity)

    means, sds = prior.moments()
    names = (*(f'geometry_{i}' for i in range(n_geometry)), *MOMENT_NAMES)
    fit = map_fit(model, effort[used], np.concatenate((np.zeros(n_geometry), means)),
                  np.concatenate((np.ones(n_geometry), sds)), names, unit='N m')
    return _marginal(fit, n_geometry, sds, prior), used


def _moment_model(p: FloatArray, pose: LoadPose, slopes: FloatArray, gravity: float) -> tuple[FloatArray, FloatArray]:
    """(tau_m (N m), its Jacobian by (u, ``p``)) for ``p`` in MOMENT_NAMES at ``pose``, the geometry's part from
    ``slopes`` (``_pose_slopes``): ``effort_model`` with the moments m along and m normal (kg m)."""
    m, m_along, m_normal, c, b, eta = (float(x) for x in p)
    lever, base, cos_t, sin_t = _terms(pose)
    arm = m * base - m_along * cos_t - m_normal * sin_t  # kg m/rad: tau_in = g arm lever
    tau_in = gravity * arm * lever
    driving = tau_in * pose.direction > 0.0
    k = np.where(driving, 1.0 / eta, eta)
    n_geometry = slopes.shape[2]
    jac = np.empty((lever.size, n_geometry + 6))
    kg = k * gravity
    jac[:, :n_geometry] = kg[:, None] * (arm[:, None] * slopes[0] + lever[:, None] * (
        m * slopes[1] - m_along * slopes[2] - m_normal * slopes[3]))
    jac[:, n_geometry] = kg * lever * base
    jac[:, n_geometry + 1] = -kg * lever * cos_t
    jac[:, n_geometry + 2] = -kg * lever * sin_t
    jac[:, n_geometry + 3] = pose.direction
    jac[:, n_geometry + 4] = pose.rate
    jac[:, n_geometry + 5] = np.where(driving, -tau_in / (eta * eta), tau_in)
    return k * tau_in + c * pose.direction + b * pose.rate, jac


def _geometry_basis(geometry: Geometry) -> FloatArray:
    """B (5 x r) with the geometry's lengths and driven joint offset = values + B u, u ~ N(0, I): the square root of
    their covariance over the directions it leaves free (the sensor's offset plays no part in the effort)."""
    k = len(LENGTH_NAMES) + 1
    variances, vectors = np.linalg.eigh(geometry.covariance[:k, :k])
    free = variances > 0.0
    basis: FloatArray = vectors[:, free] * np.sqrt(variances[free])
    return basis


def _terms(pose: LoadPose) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """The pose terms the geometry moves: lever, base, cos(theta), sin(theta)."""
    return pose.lever, pose.base, pose.cos_t, pose.sin_t


def _pose_slopes(values: FloatArray, basis: FloatArray, pose_of: Callable[[FloatArray], LoadPose],
                 n: int) -> FloatArray:
    """d(pose term)/du (4 x ``n`` readings x r; ``_terms`` order) at the calibrated geometry, by central differences
    of GEOMETRY_STEP in each geometry coordinate. The fit evaluates the pose where it is and takes these slopes for
    its Jacobian: over the few sds the fit moves the geometry they change by a few tenths of a percent, which moves
    the optimum the fit finds by as little (its residuals are noise) and saves ten pose evaluations a step."""
    k = basis.shape[0]
    by_coordinate = np.empty((4, n, k))
    for i in range(k):
        up, down = values.copy(), values.copy()
        up[i] += GEOMETRY_STEP
        down[i] -= GEOMETRY_STEP
        for j, (a, b) in enumerate(zip(_terms(pose_of(up)), _terms(pose_of(down)), strict=True)):
            by_coordinate[j, :, i] = (a - b) / (2.0 * GEOMETRY_STEP)
    if not np.isfinite(by_coordinate).all():
        raise CalibrationError('the load model is not differentiable in the geometry at every reading: a reading '
                               'lies at a dead point')
    slopes: FloatArray = by_coordinate @ basis
    return slopes


def _marginal(fit: MapFit, n_geometry: int, sds: FloatArray, prior: LoadPrior) -> MapFit:
    """The load's part of a joint fit in MOMENT_NAMES (the geometry's ``n_geometry`` first), in LOAD_NAMES: the
    offsets the moments over the mass, the covariance carried through that map (first order: exact where the mass's
    sd is a small part of it, as ``written`` asks); singular values and directions of the data's information on
    the load alone, in the moments' coordinates scaled by their prior ``sds`` (as ``map_fit`` gives them)."""
    load = slice(n_geometry, None)
    values = np.array([x.value for x in fit.parameters[load]])
    m, m_along, m_normal = values[:3]
    if m == 0.0:
        raise CalibrationError('the fitted antenna mass is 0 kg: the centre of mass is not defined')
    to_offsets = np.eye(len(LOAD_NAMES))
    to_offsets[1, :3] = (-m_along / m ** 2, 1.0 / m, 0.0)
    to_offsets[2, :3] = (-m_normal / m ** 2, 0.0, 1.0 / m)
    covariance = to_offsets @ fit.covariance[load, load] @ to_offsets.T
    values[1:3] /= m
    parameters = tuple(FittedParameter(name, float(v), float(math.sqrt(covariance[i, i])), float(mean), float(sd))
                       for i, (name, v, mean, sd) in enumerate(zip(LOAD_NAMES, values, prior.means(), prior.sds(),
                                                                   strict=True)))
    information = fit.data_information[load, load]
    eigenvalues, vectors = np.linalg.eigh(information * np.outer(sds, sds))
    order = np.argsort(eigenvalues)[::-1]
    inverse = np.linalg.inv(to_offsets)
    return replace(fit, parameters=parameters, covariance=covariance,
                   data_information=inverse.T @ information @ inverse, known_rows=fit.known_rows[:, load] @ inverse,
                   singular_values=np.sqrt(np.clip(eigenvalues[order], 0.0, None)), directions=vectors[:, order].T)
