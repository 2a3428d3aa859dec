"""What the node does with one antenna angle command (rad): accept, clamp or reject it. No ROS here.

NaN and inf are always rejected. A finite command outside [theta_min, theta_max] is rejected or
clamped to the nearer limit, by policy; out-of-reach commands are a sub-case of out-of-limits
(the configured limits always lie inside the reach), told apart only for the message and counters.
Commands exactly at a limit are accepted unchanged.
"""

from __future__ import annotations

import enum
import math
from typing import NamedTuple

from fourbar_ros.antenna import Reach


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


def _fmt(theta: float) -> str:
    return f'{theta:.9g} rad ({math.degrees(theta):.6g} deg)'


def decide(command: float, theta_min: float, theta_max: float, policy: Policy, reach: Reach) -> Decision:
    """Apply the policy to one command (rad). ``reach`` only classifies out-of-limit commands."""
    if theta_min <= command <= theta_max:  # the common case first; NaN and inf fail here (finite limits)
        return Decision(command, Outcome.ACCEPTED, '')
    if not math.isfinite(command):
        return Decision(None, Outcome.REJECTED_NOT_FINITE, f'command {command} rad is not finite')
    limit = theta_min if command < theta_min else theta_max
    where = 'out of reach' if not reach.contains(command) else 'outside the limits'
    reason = (f'command {_fmt(command)} is {where} [{_fmt(theta_min)}, {_fmt(theta_max)}]')
    if policy is Policy.CLAMP:
        return Decision(limit, Outcome.CLAMPED, f'{reason}; clamped to {_fmt(limit)}')
    outcome = Outcome.REJECTED_OUT_OF_REACH if where == 'out of reach' else Outcome.REJECTED_OUT_OF_LIMITS
    return Decision(None, outcome, f'{reason}; rejected')
