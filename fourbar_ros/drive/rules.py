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
#: command's own period, one for the reading's age, one for the command's lateness (at 100 Hz on a loaded machine
#: commands arrive 4 to 16 ms apart).
STEP_PERIODS = 3.0
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


#: The lifecycle labels of a hardware component in the controller manager's activity (lifecycle_msgs/State).
INACTIVE, ACTIVE = 'inactive', 'active'
#: What the bridge's activation line starts with: the launch file starts the controllers' spawners on it.
ACTIVATED_MARK = 'hardware component active:'
#: Seconds without an answer after which an activation request counts as lost and is sent again: a respawned
#: manager reports the component before its service is up, and its dead predecessor's service, still in the graph
#: until its lease ends, makes the bridge's client look ready, so the first request can reach no one.
ANSWER_TIMEOUT_S = 1.0


def activated_line(component: str, joint: str, position: float) -> str:
    """The bridge's log line once the controller manager activated ``component`` at a reading of ``joint``."""
    return f'{ACTIVATED_MARK} {component!r} activated at the drive reading {joint} = {position!r} rad'


@dataclass
class Activation:
    """When the bridge asks the controller manager to activate its hardware component (pure: no ROS).

    The manager starts the component inactive (``hardware_components_initial_state.inactive``): its state
    interfaces read the plugin's topic, nothing is written and no controller may claim its command interfaces. The
    bridge asks for ``active`` once per manager (a new one: its activity's publication sequence restarts, or it is
    the first the bridge hears) while that manager reports the component inactive and never reported it active
    (a component someone deactivated is left alone), after a reading inside ``limits`` went out with the plugin
    subscribed to the readings and the manager's service at hand; a request unanswered for ``answer_timeout`` s
    counts as lost and is sent again on such a reading. The activation is confirmed (one line) by the manager's
    answer or by its report of the component active, whichever comes first (an answer can be lost). A reading
    outside the range is refused with one line.
    """

    limits: DriveLimits
    joint: str
    component: str
    manager_state: str = ''  #: the component's state as the manager last reported it ('' : not heard)
    armed: bool = False  #: a new manager reported the component inactive; no request sent for it yet
    pending: bool = False  #: a request is in flight
    refused: str = ''  #: the out-of-range line of this manager, once logged
    last_line: str = ''  #: the latest outcome (activated, refused, failed), for diagnostics
    activations: int = 0
    answer_timeout: float = ANSWER_TIMEOUT_S
    _sequence: int | None = None
    _requested: bool = False  #: activation was asked of the present manager
    _seen_active: bool = False  #: the present manager reported the component active (then it is left alone)
    _confirmed: bool = False  #: the present manager activated it on the bridge's request
    _position: float = math.nan  #: the reading (rad) the request was sent on
    _asked_at: float = 0.0  #: when (s) the request was sent
    _lost: bool = False  #: the request in flight went unanswered for answer_timeout: to be sent again
    _reported: str | None = None  #: the component's state in the present manager's latest report (None: absent)

    def on_activity(self, sequence: int | None, state: str | None) -> str | None:
        """The manager's activity (``sequence``: its publication sequence number, None where the middleware does
        not give one: every report counts as a new manager) with ``state``, the component's label (None: absent).
        The activation line when this report confirms the bridge's request, else None."""
        if self._sequence is None or sequence is None or sequence <= self._sequence:  # a new manager
            self._requested = self._seen_active = self._confirmed = self.pending = self._lost = False
            self.refused = self.manager_state = ''
        self._sequence, self._reported = sequence, state
        if state is None:  # the component is not (yet) the manager's: nothing to ask of it
            self.armed = False
            return None
        self.manager_state = state
        self._seen_active = self._seen_active or state == ACTIVE
        self.armed = state == INACTIVE and not self._seen_active and (self._lost or not self._requested)
        return self._confirm() if state == ACTIVE and self._requested else None

    def _confirm(self) -> str | None:
        if self._confirmed:
            return None
        self._confirmed, self.pending, self.manager_state = True, False, ACTIVE
        self.activations += 1
        self.last_line = activated_line(self.component, self.joint, self._position)
        return self.last_line

    def on_reading(self, position: float, ready: bool, now: float = 0.0) -> str | None:
        """After ``position`` rad was published at ``now`` s (``ready``: the plugin subscribed to the readings and
        the manager's service at hand): ACTIVE to request activation (again, once the request in flight is
        ``answer_timeout`` s old), a line to log for a refusal (once per manager), else None."""
        if self.pending and now - self._asked_at > self.answer_timeout:
            self.pending, self._lost = False, True
            self.armed = self._reported == INACTIVE and not self._seen_active
        if not self.armed or self.pending or not ready:
            return None
        if self.limits.in_range(position):
            self.armed, self.pending, self._requested, self._lost = False, True, True, False
            self._position, self._asked_at = position, now
            return ACTIVE
        if self.refused:
            return None
        self.refused = self.last_line = (
            f'not activating hardware component {self.component!r}: the drive reads {self.joint} = {position!r} '
            f'rad, outside the driven range [{self.limits.lower!r}, {self.limits.upper!r}] rad')
        return self.refused

    def on_response(self, ok: bool, state: str) -> str | None:
        """The manager's answer (``ok``, the component's state label): the line to log (None: already confirmed)."""
        if ok and state == ACTIVE:
            return self._confirm()
        self.pending = False
        self.last_line = f'the controller manager did not activate hardware component {self.component!r} ' \
                         f'(state {state!r})'
        return self.last_line
