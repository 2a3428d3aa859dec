"""Exception types of fourbar_ros (ValueError subclasses with one-line messages) and how a message is quoted."""

from __future__ import annotations


class FourBarError(ValueError):
    """Base class: an input the linkage cannot serve. The message is one line and names the value."""


class InvalidGeometryError(FourBarError):
    """Link lengths that are not finite and positive, or a linkage that can never assemble."""


class UnreachableError(FourBarError):
    """An angle (NaN, inf, or outside the reachable interval) the linkage cannot take."""


class SingularPositionError(FourBarError):
    """A pose where the answer is undetermined (a change point) or a derivative is unbounded."""


class DeadPointError(SingularPositionError):
    """A dead point: the driven rocker cannot move the antenna there, so the required torque is unbounded."""


def one_line(exc: BaseException) -> str:
    """An exception's message as one line for ours: its first line without a closing period (the class name
    when empty). Foreign errors (rcl, rosbags, sqlite3) may span lines; the first says what went wrong."""
    text = str(exc).strip() or type(exc).__name__
    return text.splitlines()[0].rstrip('.')
