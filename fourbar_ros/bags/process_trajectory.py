"""The actuator trajectories fourbar_node publishes in trajectory mode, for a bag of antenna trajectories (no rclpy).

Each goes through the node's ``rules.serve.serve_antenna_trajectory`` at its log time, with no measured drive; what
is written: docs/how-to/bags.md."""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field
from functools import partial
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
from fourbar_ros.interface.joint_trajectory import joint_trajectory
from fourbar_ros.interface.topics import JOINT_TRAJECTORY, sibling_topic, trajectory_topic
from fourbar_ros.rules.outgoing import actuation_contract
from fourbar_ros.rules.serve import ActuationCounters, Drive, Outgoing, serve_antenna_trajectory


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


def process_trajectory_bag(src: str | os.PathLike[str] | BagReader, dst: str | os.PathLike[str], cfg: AntennaConfig,
                           topic: str | None = None, storage: Storage | None = None) -> TrajectoryStats:
    """Write to ``dst`` what fourbar_node in trajectory mode publishes for the antenna trajectories of ``src``
    (see the module docstring). Raises BagError (one line) for bad input; ``dst`` then does not appear."""
    start = time.perf_counter()
    stats = TrajectoryStats()
    counters = stats.counters
    store = jazzy_typestore()
    contract = actuation_contract(cfg, 'trajectory')
    floats = partial(np.array, dtype=np.float64)  # rosbags serializes float64[] from numpy arrays
    with open_bag(src) as reader:
        chosen = reader.find(TRAJECTORIES, topic)
        with AtomicBagWriter(dst, storage or reader.storage) as bag:
            out = bag.add_topic(sibling_topic(chosen, trajectory_topic(cfg.trajectory_controller).name),
                                JOINT_TRAJECTORY, [recorded_qos()])
            with reader.guard():
                for _, log, data in reader.messages([chosen]):
                    counters.trajectories_received += 1
                    msg: Any = store.deserialize_cdr(bytes(data), JOINT_TRAJECTORY)
                    sent = serve_antenna_trajectory(cfg, contract, Drive(), msg, int(log), counters)
                    if isinstance(sent, Outgoing):
                        msg = joint_trajectory(store.types, cfg.driven_joint, sent.points, sent.stamp_ns, floats)
                        bag.write(out, log, bytes(store.serialize_cdr(msg, JOINT_TRAJECTORY)))
            if counters.trajectories_received == 0:
                raise BagError(f'{reader.path}: topic {chosen} has no messages')
    stats.seconds = time.perf_counter() - start
    return stats
