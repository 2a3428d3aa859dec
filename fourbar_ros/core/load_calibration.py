"""The load model fitted to the driven joint's measured effort: mass, centre of mass, friction, reducer efficiency.

Fitted after the geometry (core/calibration.py); the model and the report: docs/how-to/calibrate.md."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from fourbar_ros.core.antenna import AntennaLinkage, Branch, Driven
from fourbar_ros.core.calibration import CalibrationError, MapFit, map_fit
from fourbar_ros.core.numeric import FloatArray

__all__ = ['LOAD_NAMES', 'MOVING', 'LoadPose', 'LoadPrior', 'calibrate_load', 'effort_model', 'load_pose']

#: The fitted load parameters, in order: kg, m, m, N m, dimensionless.
LOAD_NAMES = ('antenna_mass', 'com_offset_along', 'com_offset_normal', 'coulomb_friction', 'reducer_efficiency')
#: Readings slower than this fraction of the top |q_dot| count as at rest and are left out.
MOVING = 0.05


@dataclass(frozen=True)
class LoadPrior:
    """Prior means and sds of the load parameters (LOAD_NAMES units). The defaults are weak."""

    antenna_mass: float = 0.0
    com_offset_along: float = 0.0
    com_offset_normal: float = 0.0
    coulomb_friction: float = 0.0
    reducer_efficiency: float = 1.0
    mass_sd: float = 10.0
    offset_sd: float = 0.05
    friction_sd: float = 1.0
    efficiency_sd: float = 0.3

    def means(self) -> FloatArray:
        return np.array([self.antenna_mass, self.com_offset_along, self.com_offset_normal, self.coulomb_friction,
                         self.reducer_efficiency])

    def sds(self) -> FloatArray:
        return np.array([self.mass_sd, self.offset_sd, self.offset_sd, self.friction_sd, self.efficiency_sd])


@dataclass(frozen=True)
class LoadPose:
    """What the effort model needs per reading: the pose's terms, fixed by the geometry."""

    lever: FloatArray     # dtheta/dq
    base: FloatArray      # AB cos(gamma) dgamma/dtheta - (h/2) cos(theta), m/rad
    cos_t: FloatArray
    sin_t: FloatArray
    direction: FloatArray  # sign(q_dot)


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
    return LoadPose(lever, base, cos_t, np.sin(theta), np.sign(q_rate))


def effort_model(p: FloatArray, pose: LoadPose, gravity: float) -> tuple[FloatArray, FloatArray]:
    """(tau_m (N m), d tau_m / d p (N, 5)) for the load parameters ``p`` (LOAD_NAMES order) at the poses."""
    m, along, normal, c, eta = (float(x) for x in p)
    height_rate = pose.base - along * pose.cos_t - normal * pose.sin_t
    tau_in = m * gravity * height_rate * pose.lever
    driving = tau_in * pose.direction > 0.0
    k = np.where(driving, 1.0 / eta, eta)
    jac = np.empty((5, pose.lever.size))
    np.multiply(k * gravity * height_rate, pose.lever, out=jac[0])
    np.multiply(-k * m * gravity * pose.cos_t, pose.lever, out=jac[1])
    np.multiply(-k * m * gravity * pose.sin_t, pose.lever, out=jac[2])
    jac[3] = pose.direction
    jac[4] = np.where(driving, -tau_in / (eta * eta), tau_in)
    return k * tau_in + c * pose.direction, jac.T


def calibrate_load(link: AntennaLinkage, q: FloatArray, q_rate: FloatArray, effort: FloatArray, driven: Driven,
                   branch: Branch, gravity: float, prior: LoadPrior = LoadPrior()
                   ) -> tuple[MapFit, npt.NDArray[np.bool_]]:
    """Fit the load parameters to the measured effort (N m) at the true driven joint ``q`` (rad, offset corrected)
    moving at ``q_rate`` (rad/s), arrays in time order, with the calibrated ``link``. (fit, mask of the readings
    used: moving, all finite). Raises CalibrationError when too few readings move or the fit does not converge."""
    q, q_rate, effort = (np.asarray(a, dtype=np.float64) for a in (q, q_rate, effort))
    top = float(np.max(np.abs(q_rate[np.isfinite(q_rate)]), initial=0.0))
    used = np.isfinite(q) & np.isfinite(q_rate) & np.isfinite(effort) & (np.abs(q_rate) > MOVING * top)
    if top == 0.0 or int(np.count_nonzero(used)) <= 10 * len(LOAD_NAMES):
        raise CalibrationError(f'{int(np.count_nonzero(used))} readings of a moving joint with an effort: too few '
                               'for the load model')
    pose = load_pose(link, q[used], q_rate[used], driven, branch)
    keep = np.isfinite(pose.lever) & np.isfinite(pose.base)
    if not keep.all():
        raise CalibrationError(f'{int(np.count_nonzero(~keep))} readings at a dead point or out of reach')

    def model(p: FloatArray) -> tuple[FloatArray, FloatArray]:
        return effort_model(p, pose, gravity)

    return map_fit(model, effort[used], prior.means(), prior.sds(), LOAD_NAMES, unit='N m'), used
