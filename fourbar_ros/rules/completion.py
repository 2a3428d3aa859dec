"""What fourbar_node publishes for a measured driven joint (the actuator modes), and ``fourbar process`` for a
recorded one. No ROS.

From the measured driven rocker q (rad), and where given its velocity q_dot (rad/s) and effort (N m at the rocker,
in the sense of increasing q), through the core's exact inverse (``core.completion.complete``, on the branch of
``from_rocker`` that matches the configured one, ``AntennaConfig.measured_branch``):

- ``joint_states``: names [the other rocker's joint, the coupler joint], positions [other rocker, gamma + theta]
  rad (each the turn nearest the open-loop pose at mid-range, so they lie within the URDF's limits), velocities
  rad/s by the chain rule (empty without q_dot, or at the driven rocker's dead point where they are
  unbounded), efforts empty (the passive joints carry no actuator effort). The driven joint is the measurement's.
- ``antenna_angle``: theta (rad); ``antenna_rate``: theta_dot (rad/s) where q_dot is given and bounded.
- ``load_torque``: effort * dq/dtheta (N m about theta, + in the sense of increasing theta; power balance, no
  reducer losses since the effort is measured at the rocker) where the effort is given and bounded (not at the
  antenna's reach limit).

A NaN velocity or effort means *not measured* (``measured``): ros2_control's joint_state_broadcaster publishes NaN
for a state interface the joint does not have; the message is completed without the rates or without the load
torque. A measurement is *refused* when q is NaN or inf or q_dot or effort is infinite, and *out of range* when the
rocker cannot take q (outside ``AntennaLinkage.rocker_reach``): nothing is published for either.

Two paths over the same core calls: ``CompletionRule.one`` per message (Python floats, the math module: the node)
and ``complete_block`` on arrays (numpy: ``fourbar process``). They agree within a few ulps (numpy's SIMD
transcendentals against libm), held together by test/test_rules_completion.py.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from fourbar_ros.config.antenna_config import AntennaConfig
from fourbar_ros.core.antenna import Driven
from fourbar_ros.core.completion import complete
from fourbar_ros.core.errors import DeadPointError, SingularPositionError
from fourbar_ros.core.loads import pose
from fourbar_ros.core.numeric import FloatArray

__all__ = ['Completed', 'CompletedBlock', 'CompletionRule', 'complete_block', 'completed_names', 'measured']

_TWO_PI = 2.0 * math.pi


def completed_names(cfg: AntennaConfig) -> tuple[str, str]:
    """JointState names of the completed joints: the rocker not driven, then the coupler joint."""
    other = cfg.delta_joint if cfg.driven is Driven.GAMMA else cfg.gamma_joint
    return other, cfg.coupler_joint


def measured(q: float, q_dot: float | None, effort: float | None) -> tuple[float, float | None, float | None] | None:
    """The driven joint's (position rad, velocity rad/s, effort N m) as completed, None where not measured (absent
    or NaN); None for the whole measurement when it is refused (q NaN or inf, an infinite velocity or effort)."""
    if not math.isfinite(q):
        return None
    if q_dot is not None and not math.isfinite(q_dot):
        if not math.isnan(q_dot):
            return None
        q_dot = None
    if effort is not None and not math.isfinite(effort):
        if not math.isnan(effort):
            return None
        effort = None
    return q, q_dot, effort


class Completed(NamedTuple):
    """One measurement completed: what the node publishes (see the module docstring)."""

    theta: float  #: antenna angle, rad
    positions: list[float]  #: [other rocker, coupler joint], rad
    velocities: list[float]  #: [other rocker, coupler joint] rad/s, or empty
    theta_rate: float | None  #: rad/s
    load_torque: float | None  #: N m about theta


class CompletionRule:
    """The per-message path: ``one(q, q_dot, effort)`` for finite inputs within the rocker's reach."""

    def __init__(self, cfg: AntennaConfig) -> None:
        self.link = cfg.linkage
        self.driven = cfg.driven
        self.branch = cfg.measured_branch
        self.reach = cfg.linkage.rocker_reach(cfg.driven)
        self.driven_joint = cfg.driven_joint
        self.names = list(completed_names(cfg))
        mid = pose(cfg, 0.5 * (cfg.theta_min + cfg.theta_max))
        gamma_driven = cfg.driven is Driven.GAMMA
        #: The forward solve's [other rocker, coupler joint] at mid-range: from_rocker wraps angles to [-pi, pi],
        #: the published ones are taken the turn nearest these (as the open-loop pose and the URDF limits have them).
        self.reference = ((mid.delta if gamma_driven else mid.gamma), mid.gamma + 0.5 * (cfg.theta_min + cfg.theta_max))

    def in_reach(self, q: float) -> bool:
        """Can the driven rocker take q (rad, finite)?"""
        return self.reach.contains(q)

    def out_of_range(self, q: float) -> str:
        """One line naming the measured value and the driven joint's range."""
        return (f'measured {self.driven_joint} = {q!r} rad ({math.degrees(q):.6g} deg) is outside the '
                f'{self.driven.value} rocker\'s reachable range {self.reach.describe()}: nothing published for it '
                '(a wrong encoder offset or a failed homing?)')

    def one(self, q: float, q_dot: float | None = None, effort: float | None = None) -> Completed:
        """Complete one measurement (q, q_dot, effort finite, q in reach: ``in_reach``). Raises the core's
        UnreachableError otherwise. Velocities are left out at the driven rocker's dead point, the load torque at
        the antenna's reach limit (both unbounded there)."""
        link, driven, branch = self.link, self.driven, self.branch
        while True:
            try:
                c = complete(link, q, driven, branch, q_dot, effort)
                break
            except DeadPointError:  # only the rates divide by the driven rocker's lever
                if q_dot is None:
                    raise
                q_dot = None
            except SingularPositionError:  # the load torque divides by sin(gamma + delta); or a change point
                if effort is None:
                    raise
                effort = None
        theta = float(c.theta)
        ref_other, ref_coupler = self.reference
        other, coupler = float(c.other), float(c.coupler_joint)
        positions = [other - _TWO_PI * round((other - ref_other) / _TWO_PI),
                     coupler - _TWO_PI * round((coupler - ref_coupler) / _TWO_PI)]
        if c.theta_rate is None:
            return Completed(theta, positions, [], None, None if c.load_torque is None else float(c.load_torque))
        return Completed(theta, positions, [float(c.other_rate), float(c.coupler_joint_rate)],  # type: ignore[arg-type]
                         float(c.theta_rate), None if c.load_torque is None else float(c.load_torque))


class CompletedBlock(NamedTuple):
    """Measurements completed on arrays (NaN where a value is not published, see ``complete_block``)."""

    valid: npt.NDArray[np.bool_]  #: bool: finite and within the rocker's reach (published at all)
    theta: FloatArray  #: rad
    positions: FloatArray  #: (n, 2): other rocker, coupler joint, rad
    velocities: FloatArray  #: (n, 2) rad/s; NaN rows: no velocities published
    theta_rate: FloatArray  #: rad/s, NaN: not published
    load_torque: FloatArray  #: N m, NaN: not published


def complete_block(cfg: AntennaConfig, q: FloatArray, q_dot: FloatArray, effort: FloatArray,
                   rule: CompletionRule | None = None) -> CompletedBlock:
    """The block path of ``CompletionRule.one``: q (rad) with q_dot (rad/s) and effort (N m) NaN where the
    measurement had none. Where q is not finite or out of reach everything is NaN and ``valid`` False (the caller
    refuses measurements through ``measured`` before: NaN here means not measured)."""
    rule = rule or CompletionRule(cfg)
    q = np.asarray(q, dtype=np.float64)
    q_dot, effort = np.asarray(q_dot, dtype=np.float64), np.asarray(effort, dtype=np.float64)
    given_rate, given_effort = bool(np.isfinite(q_dot).any()), bool(np.isfinite(effort).any())
    c = complete(rule.link, q, rule.driven, rule.branch, q_rate=q_dot if given_rate else None,
                 effort=effort if given_effort else None, on_invalid='nan')
    theta = np.asarray(c.theta, dtype=np.float64)
    nan = np.full(q.shape, np.nan)
    if c.theta_rate is None:
        velocities, theta_rate = np.full((q.size, 2), np.nan), nan
    else:
        velocities = np.column_stack([c.other_rate, c.coupler_joint_rate]).astype(np.float64)  # type: ignore[list-item]
        velocities[~np.isfinite(velocities).all(axis=1)] = np.nan
        theta_rate = np.asarray(c.theta_rate, dtype=np.float64)
    load = nan if c.load_torque is None else np.asarray(c.load_torque, dtype=np.float64)
    positions = np.column_stack([c.other, c.coupler_joint]).astype(np.float64)
    reference = np.array(rule.reference)
    positions -= _TWO_PI * np.round((positions - reference) / _TWO_PI)  # the turn nearest the reference (one)
    return CompletedBlock(np.isfinite(theta), theta, positions, velocities, theta_rate, load)
