"""What the node does with antenna angle commands (rad): accept, clamp or reject them. No ROS here.

``decide`` takes one command (the node), ``serve`` an array (a bag's block) and sends every command outside the
limits through ``decide``, so both give the same outcomes. The rule: docs/reference/topics.md."""

from __future__ import annotations

import enum
import math
from collections import Counter
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from fourbar_ros.core.antenna import Reach
from fourbar_ros.core.numeric import FloatArray


class Policy(enum.Enum):
    """Out-of-limits policy: REJECT drops the command, CLAMP moves it to the nearer limit."""

    REJECT = 'reject'
    CLAMP = 'clamp'


class Outcome(enum.Enum):
    """What happened to a command."""

    ACCEPTED = 'accepted'
    CLAMPED = 'clamped'
    REJECTED_NOT_FINITE = 'rejected_not_finite'
    REJECTED_OUT_OF_LIMITS = 'rejected_out_of_limits'
    REJECTED_OUT_OF_REACH = 'rejected_out_of_reach'

    @property
    def rejected(self) -> bool:
        """True when nothing may be published for the command."""
        return self.value.startswith('rejected')


class Decision(NamedTuple):
    """The angle to serve (rad; None when rejected), the outcome and a one-line reason ('' if accepted)."""

    theta: float | None
    outcome: Outcome
    reason: str


def angle_text(theta: float) -> str:
    """An angle for messages: the exact double in rad (repr: two different doubles never print alike), then
    degrees when they are finite (math.degrees overflows beyond ~3e306 rad)."""
    deg = math.degrees(theta)
    return f'{theta!r} rad ({deg:.6g} deg)' if math.isfinite(deg) else f'{theta!r} rad'


def in_reach(reach: Reach, theta: float) -> bool:
    """True if the linkage reaches the antenna angle ``theta`` (rad) as a number, not modulo 2 pi."""
    return abs(theta) <= math.pi and reach.contains(theta)


def out_of_reach_text(reach: Reach, theta: float) -> str:
    """'is out of reach ...' for a finite ``theta`` (rad) that ``in_reach`` refuses, saying when it is only so
    because angles are not wrapped (below 1e6 rad, where wrapping would still be accurate to ~1e-10 rad)."""
    wrapped = ' (angles are numbers here, not taken modulo 2 pi)' if abs(theta) < 1e6 and reach.contains(theta) else ''
    return f'is out of reach; reachable: {reach.describe()}{wrapped}'


def decide(command: float, theta_min: float, theta_max: float, policy: Policy, reach: Reach) -> Decision:
    """Apply the policy to one command (rad). ``reach`` only classifies out-of-limit commands (see ``in_reach``)."""
    if theta_min <= command <= theta_max:  # the common case first; NaN and inf fail here (finite limits)
        return Decision(command, Outcome.ACCEPTED, '')
    if not math.isfinite(command):
        return Decision(None, Outcome.REJECTED_NOT_FINITE, f'command {command} rad is not finite')
    below = command < theta_min
    limit = theta_min if below else theta_max
    if in_reach(reach, command):
        outcome = Outcome.REJECTED_OUT_OF_LIMITS
        side = 'below theta_min' if below else 'above theta_max'
        reason = (f'command {angle_text(command)} is outside the limits: {side} {angle_text(limit)} '
                  f'by {abs(command - limit):.3g} rad')
    else:
        outcome = Outcome.REJECTED_OUT_OF_REACH
        reason = f'command {angle_text(command)} {out_of_reach_text(reach, command)}'
    if policy is Policy.CLAMP:
        side = 'theta_min' if below else 'theta_max'
        return Decision(limit, Outcome.CLAMPED, f'{reason}; clamped to {side} {angle_text(limit)}')
    return Decision(None, outcome, f'{reason}; rejected')


@dataclass
class Served:
    """The commands of a block that are answered: ``index`` into the block, the angle served (rad), and how many
    commands had each outcome."""

    index: np.ndarray[tuple[int], np.dtype[np.intp]]
    theta: FloatArray
    outcomes: Counter[Outcome]


def serve(commands: FloatArray, theta_min: float, theta_max: float, policy: Policy, reach: Reach) -> Served:
    """``decide`` for each command of an array (rad): the common in-limits case on the array, every other command
    through ``decide`` itself."""
    inside = (theta_min <= commands) & (commands <= theta_max)  # NaN and inf fail here
    theta = commands.copy()
    keep = inside.copy()
    outside = np.flatnonzero(~inside)
    outcomes: Counter[Outcome] = Counter({Outcome.ACCEPTED: commands.size - outside.size})
    for i in outside.tolist():
        d = decide(float(commands[i]), theta_min, theta_max, policy, reach)
        outcomes[d.outcome] += 1
        if d.theta is not None:
            theta[i] = d.theta
            keep[i] = True
    index = np.flatnonzero(keep)
    return Served(index, theta[index], outcomes)
