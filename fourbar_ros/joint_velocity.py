"""Joint velocities from successive published joint positions. No ROS.

velocity = (q_k - q_{k-1}) / (t_k - t_{k-1}) with t the JointState stamps (ns), computed only when the
previous published sample exists, is newer than ``timeout`` seconds and older than this one;
otherwise there is no meaningful velocity and JointState.velocity stays empty.
"""

from __future__ import annotations

from typing import NamedTuple


class Sample(NamedTuple):
    """A published pose: stamp (ns since the clock's epoch) and joint positions (rad)."""

    stamp_ns: int
    positions: tuple[float, ...]


def finite_difference(previous: Sample | None, current: Sample, timeout: float) -> list[float]:
    """Velocities (rad/s) between two samples, or [] when not meaningful (first, stale or same stamp)."""
    if previous is None:
        return []
    dt = (current.stamp_ns - previous.stamp_ns) * 1e-9
    if not 0.0 < dt <= timeout:
        return []
    prev = previous.positions
    return [(q - prev[i]) / dt for i, q in enumerate(current.positions)]
