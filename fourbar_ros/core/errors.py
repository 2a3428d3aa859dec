"""Exception types of fourbar_ros. All are ValueError subclasses with one-line messages."""

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
