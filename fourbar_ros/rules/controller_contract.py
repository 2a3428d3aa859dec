"""What ros2_control's controllers accept, written once: fourbar_node checks what it sends, sim_actuator refuses alike.

Jazzy's ``validate_trajectory_msg`` and forward_command_controller's size check, with the controllers YAML's
settings; no NaN check, as in the controllers (docs/how-to/ros2-control.md). No ROS: messages are read as attributes."""

from __future__ import annotations

import enum
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from fourbar_ros.config.controllers import ForwardControllerSettings, TrajectoryControllerSettings

__all__ = ['FLOAT_EPSILON', 'ContractRule', 'DurationLike', 'PointLike', 'Refusal', 'TrajectoryPointLike',
           'check_forward_command', 'check_trajectory', 'duration_ns']

#: The controller's bound on a last point's |velocity| (rad/s) when a trajectory must end at rest:
#: ``std::numeric_limits<float>::epsilon()``.
FLOAT_EPSILON = float(np.finfo(np.float32).eps)


class DurationLike(Protocol):
    """``builtin_interfaces/Duration`` or ``Time``."""

    @property
    def sec(self) -> int: ...
    @property
    def nanosec(self) -> int: ...


class PointLike(Protocol):
    """``trajectory_msgs/JointTrajectoryPoint``: its motion fields."""

    @property
    def positions(self) -> Sequence[float]: ...
    @property
    def velocities(self) -> Sequence[float]: ...
    @property
    def accelerations(self) -> Sequence[float]: ...
    @property
    def time_from_start(self) -> DurationLike: ...


class TrajectoryPointLike(PointLike, Protocol):
    """``trajectory_msgs/JointTrajectoryPoint``: every field the controller reads."""

    @property
    def effort(self) -> Sequence[float]: ...


class ContractRule(enum.Enum):
    """A check of validate_trajectory_msg, in the controller's order; the value names its counter."""

    PARTIAL_JOINTS = 'partial_joints'  #: fewer or more joints than the controller's, partial goals not allowed
    NO_JOINT_NAMES = 'no_joint_names'
    NO_POINTS = 'no_points'
    FOREIGN_JOINT = 'foreign_joint'  #: a joint the controller does not have
    END_MOVING = 'end_moving'  #: the last point's |velocity| above FLOAT_EPSILON, not allowed
    ENDS_IN_PAST = 'ends_in_past'  #: a non-zero stamp plus the last time_from_start before the controller's now
    TIME_NOT_INCREASING = 'time_not_increasing'
    FIELD_SIZE = 'field_size'  #: an array whose length is not the number of joint names (empty where allowed)
    EFFORT_FIELD = 'effort_field'  #: effort values without an effort command interface
    COMMAND_SIZE = 'command_size'  #: forward_command_controller: not one value per joint
    #: stricter than the controller, which takes it over: a point with accelerations but no velocities (no
    #: interpolation branch of its ``sample`` runs, and it commands 0 rad)
    ACCELERATIONS_WITHOUT_VELOCITIES = 'accelerations_without_velocities'
    #: stricter than the controller, which takes it over and mishandles it: a first point without positions
    #: (ros2_control_node crashes when it is due at the takeover)
    MISHANDLED = 'mishandled'


@dataclass(frozen=True)
class Refusal:
    """Why a controller refuses a message: the rule and one line naming the point or joint."""

    rule: ContractRule
    reason: str


def duration_ns(d: DurationLike) -> int:
    """A Duration or Time as integer nanoseconds (the controller compares them as rclcpp does, in ns)."""
    return int(d.sec) * 1_000_000_000 + int(d.nanosec)


def _field_size(joints: int, values: Sequence[float], name: str, i: int, allow_empty: bool) -> Refusal | None:
    if (allow_empty and len(values) == 0) or len(values) == joints:
        return None
    return Refusal(ContractRule.FIELD_SIZE, f'point {i}: {len(values)} {name} for {joints} joint names')


def check_trajectory(c: TrajectoryControllerSettings, joint_names: Sequence[str],
                     points: Sequence[TrajectoryPointLike], stamp_ns: int, now_ns: int) -> Refusal | None:
    """None if the controller ``c`` accepts a JointTrajectory (``joint_names``, ``points``, ``header.stamp`` as
    ns ``stamp_ns``) arriving at ``now_ns`` (its clock, ns); else the first rule it breaks, checked in the
    controller's order."""
    names = list(joint_names)
    if not c.allow_partial_joints_goal and len(names) != len(c.joints):
        return Refusal(ContractRule.PARTIAL_JOINTS, f'joint_names {names}: the controller {c.name} needs all of '
                                                    f'{list(c.joints)} (allow_partial_joints_goal is false)')
    if not names:
        return Refusal(ContractRule.NO_JOINT_NAMES, 'empty joint_names')
    if not points:
        return Refusal(ContractRule.NO_POINTS, 'no points')
    foreign = [n for n in names if n not in c.joints]
    if foreign:
        return Refusal(ContractRule.FOREIGN_JOINT, f'joint {foreign[0]!r} is not one of the controller {c.name}\'s '
                                                   f'joints {list(c.joints)}')
    last = points[-1]
    if not c.allow_nonzero_velocity_at_trajectory_end:
        moving = [abs(float(v)) > FLOAT_EPSILON for v in last.velocities]
        if any(moving):
            k = moving.index(True)
            return Refusal(ContractRule.END_MOVING, f'the last point\'s velocity {float(last.velocities[k])!r} rad/s '
                                                    'is not zero (allow_nonzero_velocity_at_trajectory_end is false)')
    if stamp_ns != 0:
        end_ns = stamp_ns + duration_ns(last.time_from_start)
        if end_ns < now_ns:
            return Refusal(ContractRule.ENDS_IN_PAST, f'stamped to start at {stamp_ns * 1e-9:.9f} s, it ends '
                                                      f'{(now_ns - end_ns) * 1e-9:.6g} s before now')
    joints = len(names)
    previous = 0
    for i, p in enumerate(points):
        t = duration_ns(p.time_from_start)
        if i > 0 and t <= previous:
            return Refusal(ContractRule.TIME_NOT_INCREASING,
                           f'time_from_start of point {i} ({t * 1e-9:.9f} s) is not after point {i - 1}\'s '
                           f'({previous * 1e-9:.9f} s)')
        previous = t
        if c.allow_integration_in_goal_trajectories:
            if not (len(p.positions) or len(p.velocities) or len(p.accelerations)):
                return Refusal(ContractRule.FIELD_SIZE, f'point {i}: no positions, velocities or accelerations')
            sized = [(p.positions, 'positions'), (p.velocities, 'velocities'), (p.accelerations, 'accelerations')]
            wrong = next((r for v, n in sized if (r := _field_size(joints, v, n, i, True))), None)
        else:
            wrong = (_field_size(joints, p.positions, 'positions', i, False)
                     or _field_size(joints, p.velocities, 'velocities', i, True)
                     or _field_size(joints, p.accelerations, 'accelerations', i, True))
        if wrong is not None:
            return wrong
        if len(p.effort) and not c.has_effort_command_interface:
            return Refusal(ContractRule.EFFORT_FIELD, f'point {i} carries effort, but the controller {c.name} has no '
                                                      f'effort command interface ({list(c.command_interfaces)})')
    return _mishandled(points)


def _mishandled(points: Sequence[TrajectoryPointLike]) -> Refusal | None:
    """What the controller takes over but does not follow (stricter than the controller), or None."""
    if not len(points[0].positions):
        return Refusal(ContractRule.MISHANDLED, 'point 0 has no positions: the controller crashes when such a first '
                                               'point is due as it takes the trajectory over')
    for i, p in enumerate(points):
        if len(p.accelerations) and not len(p.velocities):
            return Refusal(ContractRule.ACCELERATIONS_WITHOUT_VELOCITIES,
                           f'point {i} has accelerations but no velocities: the controller would take it over and '
                           'command 0 rad (no interpolation runs without velocities); give velocities too')
    return None


def check_forward_command(c: ForwardControllerSettings, data: Sequence[float]) -> Refusal | None:
    """None if the forward controller ``c`` writes a ``Float64MultiArray`` with ``data``; else why it refuses."""
    if len(data) != len(c.joints):
        return Refusal(ContractRule.COMMAND_SIZE, f'{len(data)} values for the controller {c.name}\'s '
                                                  f'{len(c.joints)} joints {list(c.joints)}')
    return None
