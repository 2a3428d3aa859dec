"""Whether the drive follows the motion its controller was sent (no ROS).

The measured driven joint is compared with the reference the controller follows at the same time; a drive that
stays farther from it than ``follow_tolerance`` (rad) for ``follow_timeout`` s does not follow. Its likely causes
are in ``LIKELY_CAUSES``."""

from __future__ import annotations

from dataclasses import dataclass

from fourbar_ros.interface.stamps import ns_to_seconds, seconds_to_ns

#: What keeps an active controller's drive from moving, most likely first (the line diagnostics give).
LIKELY_CAUSES = ('the hardware plugin does not write to the drive, the drive has no power or its brake on, the '
                 'joint is blocked, or the controller held the drive on a tolerance')


@dataclass
class FollowCheck:
    """``tolerance`` rad of driven joint; ``timeout`` s (0: no check). ``off_since_ns``: since when (node clock)
    the drive has been off the reference, None while it follows."""

    tolerance: float
    timeout: float
    off_since_ns: int | None = None

    def update(self, reference: float, position: float, at_ns: int) -> str:
        """The reference and the measured position (rad) at ``at_ns``: one line when the drive has now been off
        the reference for ``timeout`` s (the check starts afresh after it), else ''."""
        if self.timeout <= 0.0 or abs(position - reference) <= self.tolerance:
            self.off_since_ns = None
            return ''
        if self.off_since_ns is None:
            self.off_since_ns = at_ns
            return ''
        off = ns_to_seconds(at_ns - self.off_since_ns)
        if at_ns - self.off_since_ns < seconds_to_ns(self.timeout):
            return ''
        self.off_since_ns = None
        return (f'the drive does not follow: measured {position:.6g} rad, {position - reference:+.3g} rad off the '
                f'reference for {off:.3g} s (follow_tolerance {self.tolerance:g} rad)')

    def reset(self) -> None:
        """A new motion, or none: nothing is off yet."""
        self.off_since_ns = None
