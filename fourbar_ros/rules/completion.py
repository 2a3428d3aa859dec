"""What fourbar_node publishes for a measured driven joint (the actuator modes), and ``fourbar process`` for a bag.

``CompletionRule.one`` per message (math module) and ``complete_block`` on arrays (numpy) agree within a few ulps.
The outputs: docs/reference/topics.md; the passive angles' fixed turn: docs/explanation/exactness.md. No ROS."""

from __future__ import annotations

import enum
import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from fourbar_ros.config.antenna_config import AntennaConfig
from fourbar_ros.core.antenna import Driven
from fourbar_ros.core.completion import complete
from fourbar_ros.core.errors import DeadPointError, SingularPositionError
from fourbar_ros.core.loads import pose
from fourbar_ros.core.numeric import FloatArray

__all__ = ['Completed', 'CompletedBlock', 'CompletionRule', 'Skipped', 'complete_block', 'completed_names',
           'driven_index', 'driven_measurement', 'joint_state_names', 'measured', 'turn_starts']

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


class Skipped(enum.Enum):
    """Why a JointState on the measured topic is not completed; the value names its counter
    (``measurements_<value>``)."""

    OWN = 'own_skipped'  #: the node's own complete JointState (the measured topic remapped onto joint_states)
    NO_DRIVEN_JOINT = 'ignored_no_driven_joint'
    MALFORMED = 'ignored_malformed'  #: not a little-endian CDR JointState
    MISMATCHED_LENGTHS = 'ignored_mismatched_lengths'
    NOT_FINITE = 'refused_not_finite'  #: a position NaN or inf, an infinite velocity or effort (``measured``)


def driven_index(names: list[str], own: list[str], driven_joint: str) -> int | Skipped:
    """Where the driven joint is among a JointState's ``names``, or why it is skipped: the node's own names
    (``own``, exactly), or no driven joint. Read before the arrays: nothing else is needed to decide."""
    if names == own:
        return Skipped.OWN
    try:
        return names.index(driven_joint)
    except ValueError:
        return Skipped.NO_DRIVEN_JOINT


def driven_measurement(i: int, n: int, position: Sequence[float], velocity: Sequence[float],
                       effort: Sequence[float]) -> tuple[float, float | None, float | None] | Skipped:
    """The driven joint's (position rad, velocity rad/s, effort N m; None: not measured) at index ``i`` of a JointState
    of ``n`` names, or why it is skipped: arrays of another length (velocity and effort may be empty), or refused by
    ``measured``."""
    if len(position) != n or len(velocity) not in (0, n) or len(effort) not in (0, n):
        return Skipped.MISMATCHED_LENGTHS
    values = measured(position[i], velocity[i] if velocity else None, effort[i] if effort else None)
    return Skipped.NOT_FINITE if values is None else values


class Completed(NamedTuple):
    """One measurement completed: what the node publishes (see the module docstring)."""

    theta: float  #: antenna angle, rad
    positions: list[float]  #: [driven, other rocker, coupler joint], rad
    velocities: list[float]  #: [driven, other rocker, coupler joint] rad/s, or empty
    efforts: list[float]  #: [driven (measured), 0.0, 0.0] N m, or empty
    theta_rate: float | None  #: rad/s
    load_torque: float | None  #: N m about theta


def joint_state_names(cfg: AntennaConfig) -> tuple[str, str, str]:
    """JointState names of a completed measurement: the driven rocker, the other rocker, the coupler joint."""
    return (cfg.driven_joint, *completed_names(cfg))


#: Samples of each interval of the driven rocker's reach for ``turn_starts``.
_TURN_SAMPLES = 4097


def turn_starts(cfg: AntennaConfig) -> tuple[float, float]:
    """Where the published turn of [other rocker, coupler joint] starts (rad): each published angle v is
    v - 2 pi floor((v - start) / 2 pi), in [start, start + 2 pi).

    The start is the middle of the widest arc of the circle that no reachable value of that joint enters (the
    driven rocker sampled over its whole reach, ``_TURN_SAMPLES`` angles per interval, the arc narrowed by the
    largest step between neighbouring samples), taken in the turn that holds the open-loop pose at mid-range. So
    a reachable pose's angle is never near a turn's edge, where one ulp could move it by 2 pi."""
    link, driven, branch = cfg.linkage, cfg.driven, cfg.measured_branch
    mid = pose(cfg, 0.5 * (cfg.theta_min + cfg.theta_max))
    anchor = ((mid.delta if driven is Driven.GAMMA else mid.gamma), mid.gamma + 0.5 * (cfg.theta_min + cfg.theta_max))
    reach = link.rocker_reach(driven)
    pieces = [np.linspace(reach.theta_gap, reach.theta_max, _TURN_SAMPLES)]
    if reach.theta_max < math.pi:  # two intervals, [gap, max] and [-max, -gap]
        pieces.append(-pieces[0])
    starts = []
    for j in range(2):
        values, step = [], 0.0
        for q in pieces:
            c = complete(link, q, driven, branch, on_invalid='nan')
            v = np.asarray(c.other if j == 0 else c.coupler_joint, dtype=np.float64)
            v = v[np.isfinite(v)]
            if v.size > 1:
                step = max(step, float(np.max(np.abs(np.diff(np.unwrap(v))))))
            values.append(np.mod(v, _TWO_PI))
        ring = np.sort(np.concatenate(values))
        gaps = np.diff(np.append(ring, ring[0] + _TWO_PI))
        k = int(np.argmax(gaps))
        if gaps[k] - 2.0 * step <= 0.0:  # the joint takes every angle: no edge can be kept away from it
            starts.append(anchor[j] - math.pi)
            continue
        edge = float(ring[k] + 0.5 * gaps[k])
        starts.append(anchor[j] - (anchor[j] - edge) % _TWO_PI)  # in (anchor - 2 pi, anchor]
    return starts[0], starts[1]


class CompletionRule:
    """The per-message path: ``one(q, q_dot, effort)`` for finite inputs within the rocker's reach."""

    def __init__(self, cfg: AntennaConfig) -> None:
        self.link = cfg.linkage
        self.driven = cfg.driven
        self.branch = cfg.measured_branch
        self.reach = cfg.linkage.rocker_reach(cfg.driven)
        self.driven_joint = cfg.driven_joint
        self.names = list(joint_state_names(cfg))
        #: [other rocker, coupler joint]: where each published turn starts (``turn_starts``)
        self.turn_starts = turn_starts(cfg)

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
        start_other, start_coupler = self.turn_starts
        other, coupler = float(c.other), float(c.coupler_joint)
        positions = [q, other - _TWO_PI * math.floor((other - start_other) / _TWO_PI),
                     coupler - _TWO_PI * math.floor((coupler - start_coupler) / _TWO_PI)]
        efforts = [] if effort is None else [effort, 0.0, 0.0]
        load = None if c.load_torque is None else float(c.load_torque)
        if c.theta_rate is None or q_dot is None:
            return Completed(theta, positions, [], efforts, None, load)
        return Completed(theta, positions, [q_dot, float(c.other_rate), float(c.coupler_joint_rate)],  # type: ignore[arg-type]
                         efforts, float(c.theta_rate), load)


class CompletedBlock(NamedTuple):
    """Measurements completed on arrays (NaN where a value is not published, see ``complete_block``)."""

    valid: npt.NDArray[np.bool_]  #: bool: finite and within the rocker's reach (published at all)
    theta: FloatArray  #: rad
    positions: FloatArray  #: (n, 3): driven, other rocker, coupler joint, rad
    velocities: FloatArray  #: (n, 3) rad/s; NaN rows: no velocities published
    efforts: FloatArray  #: (n, 3) N m: measured, 0, 0; NaN rows: no efforts published
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
        velocities, theta_rate = np.full((q.size, 3), np.nan), nan
    else:
        velocities = np.column_stack([q_dot, c.other_rate, c.coupler_joint_rate]).astype(np.float64)  # type: ignore[list-item]
        velocities[~np.isfinite(velocities).all(axis=1)] = np.nan
        theta_rate = np.asarray(c.theta_rate, dtype=np.float64)
    load = nan if c.load_torque is None else np.asarray(c.load_torque, dtype=np.float64)
    passive = np.column_stack([c.other, c.coupler_joint]).astype(np.float64)
    starts = np.array(rule.turn_starts)
    passive -= _TWO_PI * np.floor((passive - starts) / _TWO_PI)  # the published turn of each joint
    valid = np.isfinite(theta)
    zeros = np.zeros(q.size)
    efforts = np.column_stack([effort, zeros, zeros])
    efforts[~np.isfinite(effort) | ~valid] = np.nan
    positions = np.column_stack([q, passive])
    positions[~valid] = np.nan
    return CompletedBlock(valid, theta, positions, velocities, efforts, theta_rate, load)
