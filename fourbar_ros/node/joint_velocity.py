"""Joint velocities from successive published joint positions and their stamps. No ROS.

The rule (the node applies it per published JointState; an offline tool can apply it to recorded ones):

    velocities, anchor = velocity_step(anchor, sample, timeout)

``anchor`` is the sample velocities are measured from; start with ``None`` and feed back the returned one.

- No anchor yet: no velocity; the sample becomes the anchor.
- The stamp has not advanced (equal to the anchor's): no velocity, and the anchor stays. With sim time
  (``use_sim_time``, ``/clock`` at 40 Hz from ``ros2 bag play --clock``) commands at 100 Hz share a stamp;
  the time between them is unknown, so no velocity is computed over a zero interval. The anchor stays the
  *first* sample published at its stamp, so the next velocity spans from the first sample of one clock
  tick to the first of the next: over a constant-rate motion its mean is the true rate (replacing the anchor
  by the last sample of the old tick would divide one command interval by a whole tick: 100 Hz over 40 Hz
  gives 0.4x the true rate).
- The stamp went back (sim time restarted, a bag looped): no velocity; the sample becomes the anchor.
- The anchor is more than ``timeout`` s older: no velocity (a pause, not a motion); the sample becomes the anchor.
- Otherwise: velocity = (q - q_anchor) / (t - t_anchor) per joint, and the sample becomes the anchor.

With the wall clock every stamp differs, so this is the plain difference of successive samples.
"""

from __future__ import annotations

from typing import NamedTuple


class Sample(NamedTuple):
    """A published pose: stamp (ns since the clock's epoch) and joint positions (rad)."""

    stamp_ns: int
    positions: tuple[float, ...]


def velocity_step(anchor: Sample | None, current: Sample, timeout: float) -> tuple[list[float], Sample]:
    """Velocities (rad/s) of ``current`` against ``anchor`` ([] when not meaningful) and the next anchor.

    ``timeout`` in s. See the module docstring for each case.
    """
    if anchor is None:
        return [], current
    dt_ns = current.stamp_ns - anchor.stamp_ns
    if dt_ns == 0:
        return [], anchor
    dt = dt_ns * 1e-9
    if not 0.0 < dt <= timeout:
        return [], current
    prev = anchor.positions
    return [(q - prev[i]) / dt for i, q in enumerate(current.positions)], current
