"""What leaves for the controller: a trajectory's points as sent, checked against the controller's contract.

``point_fields``, ``held_to_arrival``, ``outgoing_refusal``, ``actuation_contract`` (the controller each actuator
mode sends to) and ``check_replan_tolerance``. See docs/how-to/ros2-control.md."""

from __future__ import annotations

from collections.abc import Sequence

from fourbar_ros.config.antenna_config import AntennaConfig, ConfigError
from fourbar_ros.config.controllers import (
    ForwardControllerSettings,
    TrajectoryControllerSettings,
    forward_controller,
    trajectory_controller,
)
from fourbar_ros.interface.joint_trajectory import DurationFields, PointFields
from fourbar_ros.interface.stamps import from_ns, seconds_to_ns, to_ns
from fourbar_ros.motion.trajectory import DrivenTrajectory
from fourbar_ros.rules.controller_contract import Refusal, check_trajectory
from fourbar_ros.rules.controller_motion import motion_settings_problem


def point_fields(traj: DrivenTrajectory, effort: bool) -> list[PointFields]:
    """The points of the JointTrajectory sent for a driven-joint trajectory: one joint; velocities and accelerations
    where given, else empty; the static torque as effort only when ``effort`` (the feed-forward)."""
    vel, acc = traj.velocities, traj.accelerations
    efforts = traj.efforts.tolist()
    return [PointFields([p], [] if vel is None else [float(vel[i])], [] if acc is None else [float(acc[i])],
                        [efforts[i]] if effort else [], DurationFields(*from_ns(seconds_to_ns(t))))
            for i, (t, p) in enumerate(zip(traj.times.tolist(), traj.positions.tolist(), strict=True))]


#: The least time (s) from the node's now to a stamped trajectory's last point. The controller refuses a stamped
#: trajectory that arrives after its last point (it ends in the past) and goes on with the one before, which the node's
#: next plan no longer continues; delivery under load was seen to take 0.6 s. A motion that ends sooner at rest goes
#: out with one more point holding its end until then. The cost: the controller checks the goal tolerance up to this
#: long after the motion's end (its path tolerance holds meanwhile).
END_AHEAD_S = 1.0


def held_to_arrival(points: list[PointFields], stamp_ns: int, now_ns: int) -> list[PointFields]:
    """``points`` (stamped ``stamp_ns``, sent at ``now_ns``) with one more point holding the last one, at rest,
    ``END_AHEAD_S`` after now, where they end at rest before then; else as they are (a zero stamp starts on
    arrival, so it never ends before it)."""
    last = points[-1] if points else None
    if (last is None or stamp_ns == 0 or any(x != 0.0 for x in (*last.velocities, *last.accelerations))
            or stamp_ns + to_ns(last.time_from_start) >= now_ns + seconds_to_ns(END_AHEAD_S)):
        return points
    hold = DurationFields(*from_ns(now_ns + seconds_to_ns(END_AHEAD_S) - stamp_ns))
    return [*points, last._replace(time_from_start=hold)]


def outgoing_refusal(contract: TrajectoryControllerSettings, joint: str, points: Sequence[PointFields], stamp_ns: int,
                     now_ns: int) -> Refusal | None:
    """What the trajectory controller would refuse of a trajectory this package sends (``joint``, ``points``,
    header stamp ``stamp_ns``), arriving at ``now_ns``: None for nothing. A refused one is not sent."""
    return check_trajectory(contract, [joint], points, stamp_ns, now_ns)


def actuation_contract(cfg: AntennaConfig, mode: str | None = None, namespace: str = '/',
                       ) -> TrajectoryControllerSettings | ForwardControllerSettings:
    """The settings of the controller that ``mode`` (default: the configured one; trajectory or forward) sends to,
    from ``controllers_file`` as the controller manager in ``namespace`` reads it. Raises ConfigError (one line)
    when they cannot take what the node sends: the controller's joints not the one driven joint,
    ``effort_feedforward`` without an effort command interface, a setting that changes the motion in a way the
    node does not model (``rules.controller_motion.motion_settings_problem``), or ``check_replan_tolerance``."""
    if (mode or cfg.mode) == 'trajectory':
        contract: TrajectoryControllerSettings | ForwardControllerSettings = trajectory_controller(
            cfg.controllers_file, cfg.trajectory_controller, namespace)
    else:
        contract = forward_controller(cfg.controllers_file, cfg.forward_controller, namespace)
    if isinstance(contract, TrajectoryControllerSettings):
        problem = motion_settings_problem(contract)
        if problem is not None:
            raise ConfigError(f'controllers_file: {problem}', ('controllers_file',))
    if list(contract.joints) != [cfg.driven_joint]:
        raise ConfigError(f'controllers_file: the controller {contract.name} has joints {list(contract.joints)}; the '
                          f'node drives the one joint {cfg.driven_joint!r}', ('controllers_file',))
    check_replan_tolerance(cfg, contract)
    if (cfg.effort_feedforward and isinstance(contract, TrajectoryControllerSettings)
            and not contract.has_effort_command_interface):
        raise ConfigError(f'effort_feedforward: the controller {contract.name} has command_interfaces '
                          f'{list(contract.command_interfaces)}, and it refuses points with effort unless one is '
                          'effort: give it [position, effort]', ('effort_feedforward',))
    return contract


def check_replan_tolerance(cfg: AntennaConfig,
                           contract: TrajectoryControllerSettings | ForwardControllerSettings) -> None:
    """Raise ConfigError (one line) when ``replan_tolerance`` is not below the trajectory controller's path
    tolerance at the driven joint (where it checks one): a drive the controller holds on that tolerance would stay
    within the node's of the motion the controller dropped, and the node would go on planning from that motion."""
    if not isinstance(contract, TrajectoryControllerSettings):
        return
    path = contract.tolerance(cfg.driven_joint).trajectory
    if path > 0.0 and not cfg.replan_tolerance < path:
        raise ConfigError(f'replan_tolerance: {cfg.replan_tolerance!r} rad must be below the path tolerance '
                          f'{path!r} rad of {contract.name} at {cfg.driven_joint} (a drive it holds off the motion '
                          'would still count as on it)', ('replan_tolerance',))
