"""Joint velocities from successive published joint positions and their stamps. No ROS.

``velocity_step`` per sample (the node), ``velocities`` on a block (``fourbar process``), ``anchors`` the sample
each is measured from. The rule: docs/reference/topics.md; why a stamp's first sample: docs/explanation/node.md."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from fourbar_ros.core.numeric import FloatArray

IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]


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


@dataclass
class VelocityState:
    """The anchor (``velocity_step``'s) carried from block to block: stamp (ns) and positions (rad) of the sample
    velocities are measured from; None before the first sample."""

    stamp_ns: int | None = None
    positions: FloatArray = field(default_factory=lambda: np.zeros(0))


@dataclass(frozen=True)
class Anchored:
    """A block with its anchors: ``dt`` (s) from each sample's anchor (0.0 for the first ever), ``positions`` and
    ``anchor_positions`` (rad) row by row."""

    dt: FloatArray
    positions: FloatArray
    anchor_positions: FloatArray


def anchors(stamps_ns: IntArray, positions: FloatArray, state: VelocityState) -> Anchored:
    """Each sample's anchor under the rule, for a block of samples (rows of ``positions``, rad, at ``stamps_ns``);
    updates ``state`` to the anchor after the block.

    The anchor of a sample is the first sample of the run of equal stamps just before it (the rule keeps the anchor
    while the stamp does not advance and replaces it otherwise), so the whole block needs one running maximum.
    dt = (t - t_anchor) * 1e-9 s from the integer difference, as ``velocity_step`` computes it.
    """
    k = positions.shape[1]
    carried = state.stamp_ns is not None and state.positions.shape == (k,)
    if carried:  # the anchor goes first, as the sample before the block
        t = np.concatenate((np.array([state.stamp_ns], dtype=np.int64), stamps_ns))
        q = np.concatenate((state.positions.reshape(1, k), positions))
    else:
        t, q = stamps_ns, positions
    new_run = np.ones(t.size, dtype=np.bool_)
    new_run[1:] = t[1:] != t[:-1]
    run_start = np.maximum.accumulate(np.where(new_run, np.arange(t.size), 0))
    anchor = np.zeros(t.size, dtype=np.intp)
    anchor[1:] = run_start[:-1]
    dt = (t - t[anchor]).astype(np.float64) * 1e-9
    state.stamp_ns = int(t[run_start[-1]])
    state.positions = q[run_start[-1]].copy()
    first = 1 if carried else 0
    return Anchored(dt[first:], positions, q[anchor][first:])


def velocities(stamps_ns: IntArray, positions: FloatArray, timeout: float,
               state: VelocityState) -> tuple[FloatArray, BoolArray]:
    """``velocity_step`` over a block of published samples (rows of ``positions``, rad, at ``stamps_ns``):
    (velocities rad/s, which rows have one). Updates ``state`` to the next anchor. Same floats as the scalar
    rule: a velocity when 0 < dt <= timeout, (q - q_anchor) / dt."""
    if stamps_ns.size == 0:
        return np.zeros((0, positions.shape[1])), np.zeros(0, dtype=np.bool_)
    a = anchors(stamps_ns, positions, state)
    have = (a.dt > 0.0) & (a.dt <= timeout)  # the very first sample has dt 0: no velocity
    with np.errstate(divide='ignore', invalid='ignore'):
        vel: FloatArray = (a.positions - a.anchor_positions) / a.dt[:, None]
    return vel, have
