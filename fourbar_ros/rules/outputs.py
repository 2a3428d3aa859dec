"""What fourbar_node publishes for a served antenna angle theta (rad): the pose, joint_states, input_torque. No ROS.

``JointStateRule`` per command (math module) and ``outputs_block`` on arrays (numpy) agree within a few ulps; an
output is added to both and to ``Block``. The outputs: docs/reference/topics.md."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fourbar_ros.config.antenna_config import AntennaConfig
from fourbar_ros.core.antenna import Driven
from fourbar_ros.core.completion import coupler_joint_position
from fourbar_ros.core.loads import Pose, poses
from fourbar_ros.core.numeric import FloatArray
from fourbar_ros.rules.velocity import BoolArray, IntArray, Sample, VelocityState, velocities, velocity_step

#: Joints of a JointState: gamma_joint, delta_joint, coupler_joint.
JOINTS = 3


def driven_index(cfg: AntennaConfig) -> int:
    """Column of the driven rocker's effort (0: gamma, 1: delta)."""
    return 0 if cfg.driven is Driven.GAMMA else 1


class JointStateRule:
    """The node's JointState for one served command: positions, velocities (the rule's anchor is kept here) and
    efforts."""

    def __init__(self, cfg: AntennaConfig) -> None:
        self._driven_first = cfg.driven is Driven.GAMMA
        self._timeout = cfg.velocity_timeout
        self._anchor: Sample | None = None

    def sample(self, theta: float, pose: Pose, stamp_ns: int) -> tuple[list[float], list[float], list[float]]:
        """(positions rad, velocities rad/s or [] when not meaningful, efforts N m) of the JointState stamped
        ``stamp_ns`` for angle ``theta`` (rad) at ``pose``; it is the next sample of the velocity rule."""
        positions = self.positions(theta, pose)
        velocity, self._anchor = velocity_step(self._anchor, Sample(stamp_ns, positions), self._timeout)
        return list(positions), velocity, self.effort(pose)

    def held(self, theta: float, pose: Pose) -> tuple[list[float], list[float], list[float]]:
        """The same pose held (republished): velocities 0.0, and not a sample of the velocity rule."""
        return list(self.positions(theta, pose)), [0.0] * JOINTS, self.effort(pose)

    def positions(self, theta: float, pose: Pose) -> tuple[float, float, float]:
        """[gamma, delta, coupler] (rad)."""
        return pose.gamma, pose.delta, coupler_joint_position(pose.gamma, theta)

    def effort(self, pose: Pose) -> list[float]:
        """The driven rocker's torque in its column (N m), 0.0 elsewhere."""
        torque = pose.input_torque
        return [torque, 0.0, 0.0] if self._driven_first else [0.0, torque, 0.0]


@dataclass(frozen=True)
class Block:
    """The outputs of the solvable served commands of a block, row by row: stamps (ns), JointState positions
    (rad), velocities (rad/s; rows without one where ``has_velocity`` is False) and efforts (N m), and the
    input torque (N m). ``not_solved``: served commands the core could not solve (nothing published)."""

    stamps_ns: IntArray
    positions: FloatArray
    velocities: FloatArray
    has_velocity: BoolArray
    efforts: FloatArray
    input_torque: FloatArray
    not_solved: int


def outputs_block(cfg: AntennaConfig, theta: FloatArray, stamps_ns: IntArray, anchor: VelocityState) -> Block:
    """The outputs for served angles ``theta`` (rad) stamped ``stamps_ns``, in order; ``anchor`` carries the
    velocity rule from block to block (updated)."""
    gamma, delta, torque = poses(cfg, theta)
    solved = np.isfinite(gamma) & np.isfinite(delta) & np.isfinite(torque)
    not_solved = int(solved.size - np.count_nonzero(solved))
    if not_solved:
        stamps_ns = stamps_ns[solved]
        theta, gamma, delta, torque = (x[solved] for x in (theta, gamma, delta, torque))
    positions = np.column_stack((gamma, delta, coupler_joint_position(gamma, theta)))
    efforts = np.zeros_like(positions)
    efforts[:, driven_index(cfg)] = torque
    vel, have = velocities(stamps_ns, positions, cfg.velocity_timeout, anchor)
    return Block(stamps_ns, positions, vel, have, efforts, torque, not_solved)
