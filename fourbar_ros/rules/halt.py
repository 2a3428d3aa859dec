"""The operator's halt of an actuator mode (no ROS): halted or not, why and since when, counted.

A halt ends the command in force (held: dropped; sent: interrupted, never resumed), brakes the drive to rest
(``rules.serve.serve_brake``) and drops every new command and antenna trajectory until ``resume``; resuming only
clears it (nothing moves until the next command). How to use it: docs/how-to/ros2-control.md#halt-the-drive."""

from __future__ import annotations

from dataclasses import dataclass

from fourbar_ros.interface.stamps import ns_to_seconds

#: What a command or an antenna trajectory dropped while halted is told (the end of its one-line warning).
HALTED_LINE = 'halted: call ~/resume'


@dataclass
class Halt:
    """``why`` the drive is halted ('' while it is not) and since when (``since_ns``, node clock); ``halts`` the
    halts taken, ``repeated`` those asked while already halted, ``resumes`` the halts cleared, ``dropped`` the
    commands and antenna trajectories dropped while halted."""

    why: str = ''
    since_ns: int = 0
    halts: int = 0
    repeated: int = 0
    resumes: int = 0
    dropped: int = 0

    def halt(self, why: str, now_ns: int) -> bool:
        """Halt (``why``: who asked, one line) at ``now_ns``; False (counted, nothing changed) if already halted."""
        if self.why:
            self.repeated += 1
            return False
        self.why, self.since_ns = why, now_ns
        self.halts += 1
        return True

    def resume(self) -> str:
        """Clear the halt; why it was halted ('' if it was not: nothing to clear, not counted)."""
        was, self.why = self.why, ''
        self.resumes += bool(was)
        return was

    def since(self, now_ns: int) -> str:
        """Why and for how long the drive has been halted at ``now_ns`` (one line; '' while not halted)."""
        if not self.why:
            return ''
        return f'{self.why}, {ns_to_seconds(now_ns - self.since_ns):.3f} s ago'

    def dropped_line(self, what: str) -> str:
        """The warning for ``what`` (a command or antenna trajectory, named) dropped while halted; counted."""
        self.dropped += 1
        return f'{what} dropped: {HALTED_LINE} (halted {self.why})'

    def values(self, now_ns: int) -> list[tuple[str, str]]:
        """Diagnostic key/value pairs: ``halted`` (no, or yes with why and since when) and the counters."""
        state = f'yes: {self.since(now_ns)}' if self.why else 'no'
        return [('halted', state), ('halts', str(self.halts)), ('halts_repeated', str(self.repeated)),
                ('halt_resumes', str(self.resumes)), ('halt_dropped', str(self.dropped))]
