"""The completion fourbar_node publishes in its actuator modes, for a bag of measured joint states (no rclpy).

Each ``sensor_msgs/JointState`` of the measured topic (``storage.find_topic``), in bag order and blocks of ``BLOCK``,
goes through the node's decoder and rules (``fourbar_ros.rules.completion``); the completed ``joint_states``,
``antenna_angle``, ``antenna_rate`` and ``load_torque`` go to the measured topic's namespace at its log time.
docs/how-to/bags.md ("Process a bag without the middleware") explains what is skipped, refused and written.
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from fourbar_ros.bags.storage import (
    FLOAT64,
    JOINT_STATE,
    MEASURED,
    AtomicBagWriter,
    BagError,
    BagReader,
    Storage,
    jazzy_typestore,
    open_bag,
    recorded_qos,
)
from fourbar_ros.config.antenna_config import AntennaConfig
from fourbar_ros.interface.cdr import MalformedCdrError, read_joint_state_arrays, read_joint_state_head
from fourbar_ros.interface.topics import JOINT_STATES, PER_MEASUREMENT_OUTPUTS
from fourbar_ros.rules.completion import CompletionRule, Skipped, complete_block, driven_index, driven_measurement

#: Measurements per block.
BLOCK = 65536


@dataclass
class MeasuredStats:
    """Counts of a run, named like the node's completion counters."""

    measurements: int = 0
    completed: int = 0
    refused_not_finite: int = 0
    ignored: int = 0  # no driven joint, the node's own complete states, or mismatched lengths
    malformed: int = 0  # payloads that are not a little-endian CDR JointState, as the node counts them
    out_of_range: int = 0
    seconds: float = 0.0

    def skip(self, why: Skipped) -> None:
        """Count a measurement the node would not complete, under the node's classes."""
        if why is Skipped.NOT_FINITE:
            self.refused_not_finite += 1
        elif why is Skipped.MALFORMED:
            self.malformed += 1
        else:
            self.ignored += 1

    def summary(self) -> str:
        """One line for the user."""
        return (f'{self.measurements} measured joint states -> {self.completed} completed ({self.out_of_range} out '
                f'of range, {self.refused_not_finite} not finite, {self.ignored} ignored, {self.malformed} '
                f'malformed) in {self.seconds:.2f} s')


#: The names the measured joint states go by: the node's input, and joint_state_broadcaster's local topic.
MEASURED_NAMES = tuple(t.name for t in MEASURED.topics)


def output_namespace(topic: str) -> str:
    """The namespace the node's outputs go to for a measured ``topic`` ('' for the root): the topic without its
    measured name when it ends in one, else the topic's own namespace."""
    for name in MEASURED_NAMES:
        if topic.endswith(f'/{name}'):
            return topic[:-len(name) - 1]
    return topic.rsplit('/', 1)[0]


class _Block:
    """Measurements gathered for one block: log times, header stamps and (q, q_dot, effort) with NaN for absent."""

    def __init__(self) -> None:
        self.log: list[int] = []
        self.stamp: list[tuple[int, int]] = []
        self.values: list[tuple[float, float, float]] = []


def process_measured_bag(src: str | os.PathLike[str] | BagReader, dst: str | os.PathLike[str], cfg: AntennaConfig,
                         topic: str | None = None, storage: Storage | None = None, block: int = BLOCK) -> MeasuredStats:
    """Write to ``dst`` what fourbar_node in an actuator mode publishes for the measured joint states of ``src``
    (a path or an open bag; see the module docstring). Raises BagError (one line) for bad input; ``dst`` then does
    not appear."""
    start = time.perf_counter()
    stats = MeasuredStats()
    rule = CompletionRule(cfg)
    with open_bag(src) as reader:
        chosen = reader.find(MEASURED, topic)
        ns = output_namespace(chosen)
        names = [f'{ns}/{t.name}' for t in PER_MEASUREMENT_OUTPUTS]
        if chosen in names:
            raise BagError(f'{reader.path}: the measured topic {chosen} is where the completed joint states go; '
                           'record the measured joint states on measured_joint_states')
        with AtomicBagWriter(dst, storage or reader.storage) as bag:
            qos = [recorded_qos()]
            outs = [bag.add_topic(name, JOINT_STATE if t is JOINT_STATES else FLOAT64, qos)
                    for name, t in zip(names, PER_MEASUREMENT_OUTPUTS, strict=True)]
            pending = _Block()
            for _, log, data in reader.messages([chosen]):
                taken = _measurement(rule, bytes(data))
                if isinstance(taken, Skipped):
                    stats.skip(taken)
                else:
                    stamp, values = taken
                    pending.log.append(log)
                    pending.stamp.append(stamp)
                    pending.values.append(values)
                if len(pending.log) == block:
                    _write(bag, outs, cfg, rule, pending, stats)
                    pending = _Block()
            stats.measurements = reader.count
            _write(bag, outs, cfg, rule, pending, stats)
            if stats.measurements == 0:
                raise BagError(f'{reader.path}: topic {chosen} has no messages')
    stats.seconds = time.perf_counter() - start
    return stats


def _measurement(rule: CompletionRule, raw: bytes) -> tuple[tuple[int, int], tuple[float, float, float]] | Skipped:
    """((stamp sec, nanosec), (q, q_dot, effort) NaN where not measured) of one recorded measurement, read with the
    node's decoder and accepted by the node's rules (``rules.completion``), or why the node would skip it."""
    try:
        sec, nanosec, _, names, at = read_joint_state_head(raw)
        i = driven_index(names, rule.names, rule.driven_joint)
        if isinstance(i, Skipped):
            return i
        position, velocity, effort = read_joint_state_arrays(raw, at)
    except MalformedCdrError:
        return Skipped.MALFORMED
    values = driven_measurement(i, len(names), position, velocity, effort)
    if isinstance(values, Skipped):
        return values
    q, q_dot, tau = values
    return (sec, nanosec), (q, math.nan if q_dot is None else q_dot, math.nan if tau is None else tau)


def _write(bag: AtomicBagWriter, outs: list[Any], cfg: AntennaConfig, rule: CompletionRule, pending: _Block,
           stats: MeasuredStats) -> None:
    """Complete one block and write its outputs."""
    if not pending.log:
        return
    q, q_dot, effort = (np.array(column, dtype=np.float64) for column in zip(*pending.values, strict=True))
    done = complete_block(cfg, q, q_dot, effort, rule)
    store = jazzy_typestore()
    js_type, f64_type = store.types[JOINT_STATE], store.types[FLOAT64]
    header_type, time_type = store.types['std_msgs/msg/Header'], store.types['builtin_interfaces/msg/Time']
    empty = np.empty(0, dtype=np.float64)
    js_conn, angle_conn, rate_conn, load_conn = outs
    write = bag.write
    for k in np.flatnonzero(done.valid).tolist():
        log = pending.log[k]
        sec, nanosec = pending.stamp[k]
        has_rate = bool(np.isfinite(done.velocities[k]).all())
        has_effort = bool(np.isfinite(done.efforts[k]).all())
        js = js_type(header=header_type(stamp=time_type(sec=sec, nanosec=nanosec), frame_id=''), name=rule.names,
                     position=done.positions[k].copy(), velocity=done.velocities[k].copy() if has_rate else empty,
                     effort=done.efforts[k].copy() if has_effort else empty)
        write(js_conn, log, bytes(store.serialize_cdr(js, JOINT_STATE)))
        write(angle_conn, log, bytes(store.serialize_cdr(f64_type(data=float(done.theta[k])), FLOAT64)))
        for conn, value in ((rate_conn, done.theta_rate[k]), (load_conn, done.load_torque[k])):
            if math.isfinite(value):
                write(conn, log, bytes(store.serialize_cdr(f64_type(data=float(value)), FLOAT64)))
        stats.completed += 1
    stats.out_of_range += int(np.count_nonzero(~done.valid))
