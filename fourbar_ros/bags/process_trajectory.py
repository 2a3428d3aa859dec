"""The actuator trajectories fourbar_node publishes in trajectory mode, for a bag of antenna trajectories (no rclpy).

For every ``trajectory_msgs/JointTrajectory`` of the antenna trajectory topic (``/antenna_trajectory``, else the one
``*/antenna_trajectory``) in bag order, the node's rule (``fourbar_ros.rules.actuation.convert``): a refused
trajectory is counted by its problem (``problem_of``) and writes nothing; a converted one gives the driven joint's
JointTrajectory on ``<trajectory_controller>/joint_trajectory`` next to the input topic, at the input's log time,
with the input's header stamp (0: start on arrival), the log time standing for the node's clock at arrival. What
the controller's contract would refuse is counted and not written, as the node does. The output appears
atomically.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from fourbar_ros.bags.storage import (
    TRAJECTORIES,
    AtomicBagWriter,
    BagError,
    BagReader,
    Storage,
    jazzy_typestore,
    open_bag,
    recorded_qos,
)
from fourbar_ros.config.antenna_config import AntennaConfig
from fourbar_ros.config.controllers import TrajectoryControllerSettings
from fourbar_ros.core.errors import FourBarError
from fourbar_ros.interface.topics import JOINT_TRAJECTORY, sibling_topic, trajectory_topic
from fourbar_ros.rules.actuation import (
    ActuationCounters,
    PointFields,
    actuation_contract,
    outgoing_refusal,
    point_fields,
    problem_of,
    serve_antenna_trajectory,
)


@dataclass
class TrajectoryStats:
    """Counts of a run, named like the node's actuation counters."""

    counters: ActuationCounters = field(default_factory=ActuationCounters)
    seconds: float = 0.0

    def summary(self) -> str:
        """One line for the user."""
        c = self.counters
        refused = ', '.join(f'{n} {p.value}' for p, n in c.rejected.items() if n) or 'none'
        return (f'{c.trajectories_received} antenna trajectories -> {c.trajectories_sent} actuator trajectories '
                f'({c.trajectory_points_sent} points, {c.trajectory_points_inserted} inserted, '
                f'{c.trajectories_retimed} retimed; refused: {refused}) in {self.seconds:.2f} s')


def trajectory_cdr(store: Any, joint: str, points: list[PointFields], stamp_ns: int) -> bytes:
    """The serialized JointTrajectory of the node's points (``point_fields``) for ``joint``, stamped ``stamp_ns``."""
    t = store.types
    point_type, duration_type = t['trajectory_msgs/msg/JointTrajectoryPoint'], t['builtin_interfaces/msg/Duration']
    msg_points = [point_type(positions=np.array(p.positions, dtype=np.float64),
                             velocities=np.array(p.velocities, dtype=np.float64),
                             accelerations=np.array(p.accelerations, dtype=np.float64),
                             effort=np.array(p.effort, dtype=np.float64),
                             time_from_start=duration_type(sec=p.time_from_start.sec,
                                                           nanosec=p.time_from_start.nanosec))
                  for p in points]
    stamp = t['builtin_interfaces/msg/Time'](sec=stamp_ns // 1_000_000_000, nanosec=stamp_ns % 1_000_000_000)
    msg = t[JOINT_TRAJECTORY](header=t['std_msgs/msg/Header'](stamp=stamp, frame_id=''), joint_names=[joint],
                              points=msg_points)
    return bytes(store.serialize_cdr(msg, JOINT_TRAJECTORY))


def process_trajectory_bag(src: str | os.PathLike[str] | BagReader, dst: str | os.PathLike[str], cfg: AntennaConfig,
                           topic: str | None = None, storage: Storage | None = None) -> TrajectoryStats:
    """Write to ``dst`` what fourbar_node in trajectory mode publishes for the antenna trajectories of ``src``
    (see the module docstring). Raises BagError (one line) for bad input; ``dst`` then does not appear."""
    start = time.perf_counter()
    stats = TrajectoryStats()
    counters = stats.counters
    store = jazzy_typestore()
    contract = actuation_contract(cfg, 'trajectory')
    assert isinstance(contract, TrajectoryControllerSettings)
    with open_bag(src) as reader:
        chosen = reader.find(TRAJECTORIES, topic)
        with AtomicBagWriter(dst, storage or reader.storage) as bag:
            out = bag.add_topic(sibling_topic(chosen, trajectory_topic(cfg.trajectory_controller).name),
                                JOINT_TRAJECTORY, [recorded_qos()])
            with reader.guard():
                for _, log, data in reader.messages([chosen]):
                    counters.trajectories_received += 1
                    msg: Any = store.deserialize_cdr(bytes(data), JOINT_TRAJECTORY)
                    stamp_ns = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
                    try:
                        converted = serve_antenna_trajectory(
                            cfg, contract.allow_nonzero_velocity_at_trajectory_end, msg.joint_names, msg.points,
                            stamp_ns, int(log))
                    except FourBarError as exc:
                        counters.rejected[problem_of(exc)] += 1
                        continue
                    points = point_fields(converted.trajectory, cfg.effort_feedforward)
                    refusal = outgoing_refusal(contract, cfg.driven_joint, points, stamp_ns, int(log))
                    if refusal is not None:
                        counters.refused[refusal.rule] += 1
                        continue
                    bag.write(out, log, trajectory_cdr(store, cfg.driven_joint, points, stamp_ns))
                    counters.trajectories_sent += 1
                    counters.trajectory_points_sent += len(converted.trajectory)
                    counters.trajectory_points_inserted += converted.inserted
                    counters.trajectories_retimed += converted.retimed
            if counters.trajectories_received == 0:
                raise BagError(f'{reader.path}: topic {chosen} has no messages')
    stats.seconds = time.perf_counter() - start
    return stats
