"""The fate of each served command across its controller's lifecycle (no ROS).

A command is held until its controller can run it, sent, then reached, interrupted, superseded or dropped.
``CommandFates`` is told the controller's ``readiness``, the sends, the measured antenna angle and the time; it says
when a held command is due (``due``). Each lifecycle event: docs/explanation/lifecycle.md."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from enum import Enum

from fourbar_ros.config.antenna_config import AntennaConfig
from fourbar_ros.interface.stamps import ns_to_seconds, seconds_to_ns


class Readiness(Enum):
    """What the node knows of the controller it feeds."""

    NOT_FOLLOWED = 'not followed'  # no controller manager followed (none seen yet, or following is off): send
    ACTIVE = 'active'
    INACTIVE = 'inactive'  # loaded, not active
    HARDWARE_INACTIVE = 'hardware inactive'  # active, a hardware component of the manager not: it runs on, unheard
    ABSENT = 'absent'  # the controller manager runs without this controller
    GONE = 'gone'  # the controller manager seen before has gone (stopped, or restarting)

    @property
    def sendable(self) -> bool:
        """Whether a command goes out now."""
        return self in (Readiness.NOT_FOLLOWED, Readiness.ACTIVE)


class Fate(Enum):
    """Where a served command stands; the last four are final, one per command."""

    HELD = 'held'
    SENT = 'sent'
    REACHED = 'reached'
    INTERRUPTED = 'interrupted'
    SUPERSEDED = 'superseded'
    DROPPED = 'dropped'

    @property
    def final(self) -> bool:
        """Whether nothing more happens to the command."""
        return self not in (Fate.HELD, Fate.SENT)


#: lifecycle_msgs/State label of an active controller or hardware component.
ACTIVE_LABEL = 'active'


def readiness(controllers: Iterable[tuple[str, str]], hardware: Iterable[tuple[str, str]], name: str) -> Readiness:
    """The readiness of controller ``name`` from a controller manager's (controller name, state label) and
    (hardware component name, state label) pairs: active only with every hardware component active too."""
    states = dict(controllers)
    if name not in states:
        return Readiness.ABSENT
    if states[name] != ACTIVE_LABEL:
        return Readiness.INACTIVE
    if any(label != ACTIVE_LABEL for _, label in hardware):
        return Readiness.HARDWARE_INACTIVE
    return Readiness.ACTIVE


@dataclass(frozen=True)
class FateSettings:
    """``hold_timeout`` s a command waits for its controller (from its arrival, or its interruption) before it is
    dropped; ``resume_interrupted``: an interrupted command is held again (else final); ``reached_tolerance`` rad
    of antenna angle; ``reach_timeout`` s after the motion's planned end before a sent command counts as not
    reached (interrupted)."""

    hold_timeout: float
    resume_interrupted: bool
    reached_tolerance: float
    reach_timeout: float

    @classmethod
    def of(cls, cfg: AntennaConfig) -> FateSettings:
        """The settings of a configuration (its command_hold_timeout, resume_interrupted, reached_tolerance,
        reach_timeout)."""
        return cls(cfg.command_hold_timeout, cfg.resume_interrupted, cfg.reached_tolerance, cfg.reach_timeout)


@dataclass
class Command:
    """A served command: antenna angle ``theta`` rad, its fate and why, and times in ns on the node clock."""

    theta: float
    received_ns: int
    fate: Fate = Fate.HELD
    reason: str = ''
    held_ns: int = 0  # since when it waits (arrival, or interruption)
    end_ns: int = 0  # the planned end of its motion, once sent
    interruptions: int = 0


@dataclass
class CommandFates:
    """The current command and the count of every fate reached (``counts``; a resumed command passes HELD and SENT
    again). ``readiness`` is the controller's; ``measured`` whether the drive's state is known (nothing is planned
    before)."""

    settings: FateSettings
    readiness: Readiness = Readiness.NOT_FOLLOWED
    measured: bool = False
    current: Command | None = None
    counts: dict[Fate, int] = field(default_factory=lambda: dict.fromkeys(Fate, 0))

    def _set(self, fate: Fate, reason: str = '') -> None:
        cmd = self.current
        assert cmd is not None
        cmd.fate, cmd.reason = fate, reason
        self.counts[fate] += 1

    def why_not(self) -> str:
        """Why a command cannot go out now ('' when it can)."""
        if self.readiness is Readiness.HARDWARE_INACTIVE:
            return 'a hardware component inactive'
        if not self.readiness.sendable:
            return f'controller {self.readiness.value}'
        return '' if self.measured else 'no measured driven joint yet'

    def receive(self, theta: float, now_ns: int) -> bool:
        """A new command (antenna angle rad) at ``now_ns``; the one before it, if not final, is superseded. True:
        send it now; else it is held (``current.reason`` says why)."""
        self.supersede('by a newer command')
        self.current = Command(theta, now_ns, held_ns=now_ns)
        why = self.why_not()
        if why:
            self._set(Fate.HELD, why)
        return not why

    def supersede(self, by: str) -> None:
        """The current command, if not final, is superseded (``by`` what)."""
        if self.current is not None and not self.current.fate.final:
            self._set(Fate.SUPERSEDED, by)

    def sent(self, end_ns: int) -> None:
        """The current command went out; its motion ends at ``end_ns``."""
        assert self.current is not None
        self.current.end_ns = end_ns
        self._set(Fate.SENT)

    def drop(self, reason: str) -> None:
        """The current command cannot be carried out (``reason``: one line)."""
        if self.current is not None and not self.current.fate.final:
            self._set(Fate.DROPPED, reason)

    def interrupt(self, reason: str, now_ns: int, resumable: bool = True) -> None:
        """The current command, if sent, was not carried through (``reason``); held again where the settings say
        so and ``resumable``."""
        cmd = self.current
        if cmd is None or cmd.fate is not Fate.SENT:
            return
        cmd.interruptions += 1
        if resumable and self.settings.resume_interrupted:
            cmd.held_ns = now_ns
            self._set(Fate.HELD, f'interrupted ({reason}); resumes when the controller is active')
        else:
            self._set(Fate.INTERRUPTED, reason)

    def controller(self, new: Readiness, now_ns: int) -> None:
        """The controller's readiness changed to ``new``: a sent command it no longer runs is interrupted (also
        when a controller manager first appears without the controller active: what went out reached none)."""
        old, self.readiness = self.readiness, new
        if old is new:
            return
        if not new.sendable:
            self.interrupt(f'controller {old.value} -> {new.value}', now_ns)
        cmd = self.current
        if cmd is not None and cmd.fate is Fate.HELD:
            cmd.reason = cmd.reason if cmd.interruptions else self.why_not()

    def unmeasured(self, reason: str, now_ns: int) -> None:
        """The drive's measurements stopped (``reason``): nothing is planned until the next one, and a sent command
        is interrupted (a manager killed, or its broadcaster, stops them before the node hears of it)."""
        self.measured = False
        self.interrupt(reason, now_ns)

    def due(self) -> bool:
        """Whether a held command can go out now."""
        return self.current is not None and self.current.fate is Fate.HELD and not self.why_not()

    def reached(self, theta: float, now_ns: int) -> None:
        """The measured antenna angle (rad) at ``now_ns``: the sent command is reached when its motion has ended
        and the angle is within the tolerance."""
        cmd = self.current
        if (cmd is not None and cmd.fate is Fate.SENT and now_ns >= cmd.end_ns
                and abs(theta - cmd.theta) <= self.settings.reached_tolerance):
            self._set(Fate.REACHED)

    def tick(self, now_ns: int, theta: float | None) -> None:
        """Time passes: a command held longer than ``hold_timeout`` is dropped; one sent and not reached
        ``reach_timeout`` after its motion's end is interrupted (not resumed: the drive did not follow)."""
        cmd, s = self.current, self.settings
        if cmd is None:
            return
        if cmd.fate is Fate.HELD and now_ns - cmd.held_ns > seconds_to_ns(s.hold_timeout):
            self._set(Fate.DROPPED, f'held {ns_to_seconds(now_ns - cmd.held_ns):.3g} s '
                                    f'(hold_timeout {s.hold_timeout:g} s): {cmd.reason or self.why_not()}')
        elif cmd.fate is Fate.SENT and now_ns - cmd.end_ns > seconds_to_ns(s.reach_timeout):
            where = 'no measured angle' if theta is None else f'measured {theta:.6g} rad, {theta - cmd.theta:+.3g} off'
            self.interrupt(f'not reached {s.reach_timeout:g} s after the motion\'s end ({where})', now_ns,
                           resumable=False)

    def values(self) -> list[tuple[str, str]]:
        """Diagnostic key/value pairs: the readiness, the current command's fate and why, the fate counters."""
        cmd = self.current
        out = [('controller_state', self.readiness.value)]
        if cmd is not None:
            out += [('command_theta_rad', repr(cmd.theta)), ('command_fate', cmd.fate.value),
                    ('command_fate_reason', cmd.reason)]
        return out + [(f'commands_{f.value}', str(n)) for f, n in self.counts.items()]
