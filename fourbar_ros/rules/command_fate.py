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
    held_ns: int = 0  # since when it waits (its latest arrival, or interruption)
    end_ns: int = 0  # the planned end of its motion, once sent
    interruptions: int = 0
    repeats: int = 0  # the same command received again while it was in force (``CommandFates.repeat``)


@dataclass
class CommandFates:
    """The current command (the one in force) and the count of every fate reached (``counts``; a resumed command
    passes HELD and SENT again), of the commands that repeated the one in force (``repeats``). ``readiness`` is the
    controller's; ``measured`` whether the drive's state is known (nothing is planned before); ``unsettled`` why the
    drive's state cannot be planned from yet ('' when it can). A new command that can go is ``pending`` until it
    goes out (it becomes current, superseding the one before) or is refused (dropped; the current one stays)."""

    settings: FateSettings
    readiness: Readiness = Readiness.NOT_FOLLOWED
    measured: bool = False
    unsettled: str = ''
    current: Command | None = None
    pending: Command | None = None
    repeats: int = 0
    counts: dict[Fate, int] = field(default_factory=lambda: dict.fromkeys(Fate, 0))

    def _set(self, fate: Fate, reason: str = '', cmd: Command | None = None) -> None:
        cmd = cmd if cmd is not None else self.current
        assert cmd is not None
        cmd.fate, cmd.reason = fate, reason
        self.counts[fate] += 1

    def _replace(self, cmd: Command, by: str) -> None:
        """``cmd`` becomes the current command; the one before, if not final, is superseded (``by`` what)."""
        self.supersede(by)
        self.current = cmd

    def why_not(self) -> str:
        """Why a command cannot go out now ('' when it can)."""
        if self.readiness is Readiness.HARDWARE_INACTIVE:
            return 'a hardware component inactive'
        if not self.readiness.sendable:
            return f'controller {self.readiness.value}'
        return self.unsettled if self.measured else 'no measured driven joint yet'

    def repeat(self, theta: float, now_ns: int, measured_theta: float | None) -> bool:
        """Whether a command to ``theta`` (rad) at ``now_ns`` repeats the one in force (the same angle: a republished
        setpoint is the same float) and joins it, starting nothing new: one held (it waits from this arrival), one
        sent, or one reached where the drive is still measured there (within ``reached_tolerance`` of
        ``measured_theta``, rad). A different angle, however close, is a new command."""
        cmd, tol = self.current, self.settings.reached_tolerance
        if cmd is None or theta != cmd.theta:
            return False
        if cmd.fate is Fate.HELD:
            cmd.held_ns = now_ns
        elif not (cmd.fate is Fate.SENT or (cmd.fate is Fate.REACHED and measured_theta is not None
                                            and abs(measured_theta - cmd.theta) <= tol)):
            return False
        cmd.repeats += 1
        self.repeats += 1
        return True

    def receive(self, theta: float, now_ns: int) -> bool:
        """A new command (antenna angle rad) at ``now_ns``. True: plan and send it now (``pending`` until ``sent``
        or ``refused``); else it is held as the current command, superseding one held before (``current.reason``
        says why)."""
        cmd = Command(theta, now_ns, held_ns=now_ns)
        why = self.why_not()
        if why:
            self._replace(cmd, 'by a newer command')
            self._set(Fate.HELD, why)
        else:
            self.pending = cmd
        return not why

    def supersede(self, by: str) -> None:
        """The current command, if not final, is superseded (``by`` what)."""
        if self.current is not None and not self.current.fate.final:
            self._set(Fate.SUPERSEDED, by)

    def sent(self, end_ns: int) -> None:
        """The pending command (else the current one, resumed) went out; its motion ends at ``end_ns``. A pending
        one supersedes the one before."""
        if self.pending is not None:
            self._replace(self.pending, 'by a newer command')
            self.pending = None
        assert self.current is not None
        self.current.end_ns = end_ns
        self._set(Fate.SENT)

    def refused(self, reason: str) -> None:
        """The pending command (else the current one, resumed) cannot be carried out (``reason``: one line): it is
        dropped; the current one, if it was not the refused one, stays in force."""
        if self.pending is not None:
            self._set(Fate.DROPPED, reason, self.pending)
            self.pending = None
        else:
            self.drop(reason)

    def wait(self, reason: str) -> None:
        """The drive's state cannot be planned from yet (``reason``): the pending command is held as the current
        one (superseding one held before; one sent stays in force and the pending one is dropped: the node does not
        plan past a motion the drive is measured off), or the current one stays held, until the next measurement."""
        self.unsettled = reason
        cmd = self.current
        if self.pending is not None and cmd is not None and cmd.fate is Fate.SENT:
            self.refused(reason)
            return
        if self.pending is not None:
            self._replace(self.pending, 'by a newer command')
            self.pending = None
            self._set(Fate.HELD, reason)
        elif cmd is not None and cmd.fate is Fate.HELD:
            cmd.reason = reason

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
        self.measured, self.unsettled = False, ''
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
        return out + [(f'commands_{f.value}', str(n)) for f, n in self.counts.items()] + [
            ('commands_repeated', str(self.repeats))]
