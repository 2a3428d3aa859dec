"""The plant's step generator: a stepper driver's field following position goals (rad at the motor, s).

Each goal is where the field should be one command period after it arrived: the field moves at the goals' own rate
plus the gap to that moving point, within its speed and acceleration limits, so goals arriving unevenly move it
without a dead stop (docs/how-to/mujoco-plant.md)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

__all__ = ['ACCELERATION_FACTOR', 'FEED_PERIODS', 'LATE_PERIODS', 'TRACKING_PERIODS', 'StepGenerator']

#: The generator's acceleration limit over the motor's (the node plans within the motor's; the generator needs room
#: above it to take up the goals' uneven arrival).
ACCELERATION_FACTOR = 2.0
#: Command periods over which the gap to the latest goal is closed (the time constant of the correction).
TRACKING_PERIODS = 2.0
#: Command periods after a goal for which its rate still drives the field (then only the gap does).
FEED_PERIODS = 1.5
#: Command periods between two goals beyond which they are not taken for a stream: the rate is the step over the
#: time between them (a goal after a pause, or a slow writer), not over one period.
LATE_PERIODS = 2.0


@dataclass
class StepGenerator:
    """The field's position (rad at the motor) and speed (rad/s) following goals; ``step`` advances one timestep.

    ``resolution``: rad at the motor the goals are rounded to (a microstep; 0 for the servo): within half of it
    of the goal, with no rate to follow and a speed one timestep's change can end, the field stops on the goal."""

    position: float
    speed_limit: float  #: rad/s at the motor, > 0
    acceleration_limit: float  #: rad/s^2 at the motor, > 0
    period: float  #: s, the command period
    resolution: float = 0.0
    goal: float = math.nan  #: the latest goal (rad at the motor; NaN: the start position)
    speed: float = 0.0
    _rate: float = 0.0  #: rad/s: the goals' own rate
    _rate_until: float = -math.inf  #: s: when it stops driving the field
    _goal_at: float = -math.inf  #: s: when the latest goal arrived
    _snap: float = field(init=False)

    def __post_init__(self) -> None:
        if math.isnan(self.goal):
            self.goal = self.position
        self._snap = 0.5 * self.resolution if self.resolution > 0.0 else 1e-12 * max(1.0, abs(self.position))

    @property
    def at_rest(self) -> bool:
        """On the goal, at rest, no rate to follow: stepping changes nothing."""
        return self.speed == 0.0 and self.position == self.goal and self._rate == 0.0

    def set_goal(self, goal: float, now: float) -> None:
        """A new goal (rad at the motor) arriving at ``now`` s."""
        elapsed = now - self._goal_at
        rate = (goal - self.goal) / (self.period if elapsed <= LATE_PERIODS * self.period else elapsed)
        self._rate = max(-self.speed_limit, min(self.speed_limit, rate))
        self._rate_until = now + FEED_PERIODS * self.period
        self.goal, self._goal_at = goal, now

    def stop(self) -> None:
        """Stop where the field is: the goal becomes its position, nothing left to follow."""
        self.goal, self.speed, self._rate = self.position, 0.0, 0.0

    def step(self, now: float, dt: float) -> None:
        """Advance the field over the timestep of ``dt`` s that begins at ``now`` s."""
        if now >= self._rate_until:
            self._rate = 0.0
        # The goal is where the field should be one period after it arrived, moving there at the goals' rate: the
        # gap is to that moving point, so goals arriving evenly are followed at their rate with no gap at all.
        ahead = self._rate * max(0.0, self._goal_at + self.period - now)
        gap, change = self.goal - ahead - self.position, self.acceleration_limit * dt
        # The speed that closes the gap, never more than the one from which the field, slowing by `change` a step,
        # still stops on the goal (it covers v^2 / (2 a) + v dt / 2 from speed v).
        stop = math.sqrt(0.25 * change * change + 2.0 * self.acceleration_limit * abs(gap)) - 0.5 * change
        close = min(abs(gap) / (TRACKING_PERIODS * self.period), stop)
        want = max(-self.speed_limit, min(self.speed_limit, self._rate + math.copysign(close, gap)))
        before = self.speed
        self.speed += max(-change, min(change, want - before))
        self.position += self.speed * dt
        if self._rate == 0.0 and abs(self.goal - self.position) <= self._snap and abs(before) <= change:
            self.position, self.speed = self.goal, 0.0
