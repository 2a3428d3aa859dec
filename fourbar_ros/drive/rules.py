"""What the drive bridge does with each command and each reading (pure: no ROS; times in s on one clock).

A command is written only after the first good reading, finite, in the driven range and within ``max_step`` rad of
the latest reading (clamped to it); anything else holds the drive. docs/how-to/drive-bridge.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from fourbar_ros.config.antenna_config import AntennaConfig
from fourbar_ros.drive.backend import Reading
from fourbar_ros.motion.limits import JointLimits, range_slack
from fourbar_ros.rules.motion_plan import driven_range

#: How many command periods of motion at the speed limit a target may lead the latest reading by: one for the
#: command's own period, one for the reading's age (readings and commands arrive at about the same rate).
STEP_PERIODS = 2.0
#: Default seconds without a command (or without a good reading) before a moving drive is held.
WATCHDOG_TIMEOUT_S = 0.5


@dataclass(frozen=True)
class DriveLimits:
    """What the bridge enforces: the driven range [lower, upper] rad (slack included), the largest distance rad
    a target may lie from the latest reading, and the watchdog timeout s."""

    lower: float
    upper: float
    max_step: float
    watchdog_timeout: float = WATCHDOG_TIMEOUT_S

    @classmethod
    def from_config(cls, cfg: AntennaConfig, watchdog_timeout: float = WATCHDOG_TIMEOUT_S) -> DriveLimits:
        """The configuration's driven range and speed limit (rad/s at the rocker) over STEP_PERIODS commands."""
        lower, upper = driven_range(cfg)
        slack = range_slack(lower, upper)
        speed = JointLimits.from_config(cfg).at_rocker(1)
        return cls(lower - slack, upper + slack, speed * STEP_PERIODS / cfg.control_rate, watchdog_timeout)

    def in_range(self, position: float) -> bool:
        """True for a finite position (rad) inside [lower, upper]."""
        return math.isfinite(position) and self.lower <= position <= self.upper


@dataclass(frozen=True)
class JointReport:
    """A reading as published: position rad, velocity rad/s (never NaN), effort N m or None."""

    position: float
    velocity: float
    effort: float | None


@dataclass
class DriveCounters:
    """What the bridge did, for diagnostics and tests."""

    readings: int = 0
    bad_readings: int = 0  #: non-finite positions: not published, not used
    commands: int = 0
    written: int = 0
    clamped: int = 0  #: written closer to the reading than commanded (the speed limit)
    held_before_reading: int = 0
    held_not_finite: int = 0  #: NaN, inf or no position for the joint
    held_out_of_range: int = 0
    held_far_outside: int = 0  #: the drive reads more than max_step outside the range
    watchdog_holds: int = 0
    stale_holds: int = 0  #: no good reading for watchdog_timeout while moving


@dataclass
class DriveRules:
    """The bridge's state between calls; each ``on_*`` returns the target (rad) to write, or None."""

    limits: DriveLimits
    counters: DriveCounters = field(default_factory=DriveCounters)
    report: JointReport | None = None  #: the latest good reading
    reading_time: float | None = None
    last_command_time: float | None = None  #: of the last command written
    moving: bool = False  #: a target was written since the last hold
    held: str = ''  #: why the drive is held ('' while it follows commands)

    @property
    def status(self) -> str:
        """One line: no reading yet, idle, following, or held and why."""
        if self.report is None:
            return 'no reading yet'
        if self.held:
            return f'held: {self.held}'
        return 'following commands' if self.moving else 'idle'

    def on_reading(self, now: float, reading: Reading) -> JointReport | None:
        """The report to publish for ``reading`` at ``now`` (None for a non-finite position); velocity from the
        backend when finite, else differenced from the previous good reading (0 for the first)."""
        position, velocity, effort = reading
        if not math.isfinite(position):
            self.counters.bad_readings += 1
            return None
        if velocity is None or not math.isfinite(velocity):
            velocity = 0.0
            if self.report is not None and self.reading_time is not None and now > self.reading_time:
                velocity = (position - self.report.position) / (now - self.reading_time)
            if not math.isfinite(velocity):
                velocity = 0.0
        if effort is not None and not math.isfinite(effort):
            effort = None
        self.counters.readings += 1
        self.report, self.reading_time = JointReport(position, velocity, effort), now
        return self.report

    def on_command(self, now: float, position: float | None) -> float | None:
        """The target to write for a commanded ``position`` rad (None: the joint had none), or a hold."""
        self.counters.commands += 1
        if self.report is None:
            self.counters.held_before_reading += 1
            return None
        if position is None or not math.isfinite(position):
            self.counters.held_not_finite += 1
            return self._hold('a command that is not a number')
        if not self.limits.in_range(position):
            self.counters.held_out_of_range += 1
            return self._hold(f'a command out of range ({position!r} rad)')
        if self._stale(now):
            self.counters.stale_holds += 1
            return self._hold('no good reading')
        here, step = self.report.position, self.limits.max_step
        target = min(max(position, here - step), here + step)
        if target != position:
            self.counters.clamped += 1
        target = min(max(target, self.limits.lower), self.limits.upper)
        if not here - step <= target <= here + step:
            self.counters.held_far_outside += 1
            return self._hold(f'the drive reads {here!r} rad, outside the range')
        self.counters.written += 1
        self.moving, self.held, self.last_command_time = True, '', now
        return target

    def on_tick(self, now: float) -> float | None:
        """The watchdog: a hold when a moving drive had no command, or no good reading, for the timeout."""
        if not self.moving:
            return None
        if self._stale(now):
            self.counters.stale_holds += 1
            return self._hold('no good reading')
        if self.last_command_time is not None and now - self.last_command_time > self.limits.watchdog_timeout:
            self.counters.watchdog_holds += 1
            return self._hold(f'no command for {self.limits.watchdog_timeout:g} s')
        return None

    def _stale(self, now: float) -> bool:
        return self.reading_time is None or now - self.reading_time > self.limits.watchdog_timeout

    def _hold(self, why: str) -> float | None:
        """Hold: the latest reading as the target once, if the drive was moving and reads inside the range."""
        self.held = why
        if not self.moving:
            return None
        self.moving = False
        assert self.report is not None  # moving implies a reading
        return self.report.position if self.limits.in_range(self.report.position) else None
