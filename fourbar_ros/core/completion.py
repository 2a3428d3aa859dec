"""The whole linkage from a measured driven rocker: angles, rates by the chain rule, and the load the effort holds.

Exact inverse and rates, no differencing (docs/explanation/exactness.md); dead points as in
docs/reference/python.md."""

from __future__ import annotations

import math
from typing import NamedTuple, overload

import numpy as np

from fourbar_ros.core.antenna import AntennaLinkage, Branch, Driven
from fourbar_ros.core.errors import DeadPointError
from fourbar_ros.core.numeric import DEAD_TOL, ArrayLike, FloatArray, OnInvalid, RealLike, RealScalar, real

__all__ = ['Completion', 'complete', 'coupler_joint_position', 'inverse_branch']


@overload
def coupler_joint_position(gamma: RealScalar, theta: RealScalar) -> float: ...
@overload
def coupler_joint_position(gamma: FloatArray, theta: FloatArray) -> FloatArray: ...
@overload
def coupler_joint_position(gamma: RealLike, theta: RealLike) -> ArrayLike: ...


def coupler_joint_position(gamma: RealLike, theta: RealLike) -> ArrayLike:
    """Position (rad) of the robot model's ``coupler_joint``: the coupler's angle from rocker AB, gamma + theta.
    One command (real scalars, the node: a float) or a block (arrays, fourbar process)."""
    if type(gamma) is float and type(theta) is float:
        return gamma + theta
    return real(gamma) + real(theta)


class Completion(NamedTuple):
    """The linkage completed from a measured rocker: angles in rad, rates in rad/s, torque in N m.

    The rates are None unless q_rate was given, load_torque None unless effort was given.
    """

    theta: ArrayLike
    other: ArrayLike  #: the rocker not measured (delta when gamma is driven), rad
    coupler_joint: ArrayLike  #: gamma + theta, rad
    theta_rate: ArrayLike | None
    other_rate: ArrayLike | None
    coupler_joint_rate: ArrayLike | None
    load_torque: ArrayLike | None  #: on the antenna, in the sense of increasing theta


def complete(link: AntennaLinkage, q: RealLike, driven: Driven, branch: Branch, q_rate: RealLike | None = None,
             effort: RealLike | None = None, on_invalid: OnInvalid = 'raise') -> Completion:
    """Complete the linkage from the measured rocker angle q (rad) of the ``driven`` rocker on from_rocker's
    ``branch``; q_rate (rad/s) and effort (N m) optional. Computes only what is asked, in float64 whatever the
    inputs' types (real scalars of any type as the Python float of their value; arrays as float64).

    Raises UnreachableError for a q the rocker cannot take (NaN, inf, outside link.rocker_reach(driven)); arrays
    with on_invalid='nan' give NaN there instead. See the module docstring for the singular poses.
    """
    q = real(q)
    if not isinstance(q, float):
        q = np.asarray(q, dtype=np.float64)
    if q_rate is not None:
        q_rate = real(q_rate)
    if effort is not None:
        effort = real(effort)
    theta, other = link.from_rocker(q, driven, branch, on_invalid)
    gamma_driven = driven is Driven.GAMMA
    gamma, delta = (q, other) if gamma_driven else (other, q)
    coupler = coupler_joint_position(gamma, theta)
    if q_rate is None and effort is None:
        return Completion(theta, other, coupler, None, None, None, None)
    scalar = isinstance(theta, float) and isinstance(other, float)
    theta_rate = other_rate = coupler_rate = load = None
    if q_rate is not None:
        dtheta, dother = (_inverse_rates_scalar if scalar else _inverse_rates_array)(link, q, theta, gamma, delta,
                                                                                 driven)
        theta_rate = dtheta * q_rate
        other_rate = dother * q_rate
        coupler_rate = (q_rate if gamma_driven else other_rate) + theta_rate
    if effort is not None:
        rates = link.rates_at(theta, gamma, delta)  # scalars: SingularPositionError at the antenna's reach limit
        mechanical_advantage = rates.dgamma_dtheta if gamma_driven else rates.ddelta_dtheta
        if scalar:
            load = float(effort) * mechanical_advantage
        else:
            with np.errstate(invalid='ignore'):
                load = np.multiply(effort, mechanical_advantage)
                load[~np.isfinite(load)] = np.nan
    return Completion(theta, other, coupler, theta_rate, other_rate, coupler_rate, load)


def inverse_branch(link: AntennaLinkage, theta: RealScalar, driven: Driven, branch: Branch) -> Branch:
    """The branch of ``from_rocker`` (measured ``driven`` rocker) that gives back the pose ``rocker_angles`` gives
    on ``branch`` at the antenna angle ``theta`` (rad, reachable and not a dead point of the driven rocker).

    The two count branches differently (the side of a different diagonal), so which one matches depends on the
    geometry; it holds over any interval of theta free of the driven rocker's dead points (where the measured
    rocker's branch changes) and of the antenna's reach limit (where the forward one does).
    """
    theta = float(real(theta))
    gamma, delta = link.rocker_angles(theta, branch)
    q = float(gamma if driven is Driven.GAMMA else delta)
    return min(Branch, key=lambda b: abs(math.remainder(float(link.from_rocker(q, driven, b).theta) - theta,
                                                        2.0 * math.pi)))



def _inverse_rates_scalar(link: AntennaLinkage, q: ArrayLike, theta: ArrayLike, gamma: ArrayLike, delta: ArrayLike,
                          driven: Driven) -> tuple[float, float]:
    """(dtheta/dq, d other/dq) for one pose (math module); DeadPointError at the driven rocker's reach limit."""
    t, g, d = float(theta), float(gamma), float(delta)
    h, ab, cd = link.coupler, link.rocker_ab, float(link.rocker_cd or 0.0)
    x, u, v = g + d, d - t, g + t
    lever = math.sin(u if driven is Driven.GAMMA else v)
    if abs(lever) <= DEAD_TOL * (1.0 + abs(float(q)) + abs(t)):
        raise DeadPointError(
            f'q={float(q)!r} rad is at the {driven.value} rocker\'s reach limit (a dead point: the other rocker in '
            f'line with the coupler): the antenna\'s rate is unbounded there')
    if driven is Driven.GAMMA:
        return ab * math.sin(x) / (h * lever), -ab * math.sin(v) / (cd * lever)
    return -cd * math.sin(x) / (h * lever), -cd * math.sin(u) / (ab * lever)


def _inverse_rates_array(link: AntennaLinkage, q: ArrayLike, theta: ArrayLike, gamma: ArrayLike, delta: ArrayLike,
                         driven: Driven) -> tuple[FloatArray, FloatArray]:
    """(dtheta/dq, d other/dq) element-wise (numpy); NaN at the driven rocker's reach limit."""
    h, ab, cd = link.coupler, link.rocker_ab, float(link.rocker_cd or 0.0)
    x, u, v = np.add(gamma, delta), np.subtract(delta, theta), np.add(gamma, theta)
    with np.errstate(divide='ignore', invalid='ignore'):
        lever = np.sin(u if driven is Driven.GAMMA else v)
        lever[np.abs(lever) <= DEAD_TOL * (1.0 + np.abs(q) + np.abs(theta))] = np.nan
        if driven is Driven.GAMMA:
            return ab * np.sin(x) / (h * lever), -ab * np.sin(v) / (cd * lever)
        return -cd * np.sin(x) / (h * lever), -cd * np.sin(u) / (ab * lever)
