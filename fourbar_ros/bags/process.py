"""The bag fourbar_node would publish for a command bag, computed without the middleware (no rclpy).

For every command of the bag, in bag order and at its log time (the time the recorder received it,
which stands for the time the node would receive it), this applies the node's rules:

- the command policy (``command_policy.decide``): inside [theta_min, theta_max] served as is; NaN/inf
  rejected; outside the limits rejected or clamped to the nearer limit (``out_of_limits``);
- the published pose from the vectorized core (gamma, delta in rad, the driven rocker's torque in N m,
  the load as ``loads.pose`` computes it); an angle the core cannot solve publishes nothing, as in the node;
- the velocity rule of ``joint_velocity.velocity_step`` over the published samples (rad/s, empty when not
  meaningful), with the command's log time as the JointState stamp;

and writes ``joint_states`` (sensor_msgs/JointState: name = the joint names, position [gamma, delta],
velocity, effort with the torque at the driven rocker and 0.0 at the other, empty frame_id as the node
sends) and ``input_torque`` (std_msgs/Float64, N m) next to the command topic (``/antenna_angle_cmd`` ->
``/joint_states``, ``/input_torque``), both at the command's log time, joint_states first.
Blocks of ``BLOCK`` commands are read, solved, serialized (joint_state_cdr) and written at a time, so
memory does not grow with the bag; the output appears atomically (bag_io.AtomicBagWriter).
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from fourbar_ros.bags.joint_state_cdr import decode_float64s, encode_float64s, encode_joint_states
from fourbar_ros.bags.storage import (
    FLOAT64,
    JOINT_STATE,
    AtomicBagWriter,
    BagError,
    jazzy_typestore,
    open_bag,
    pick_command_topic,
    recorded_qos,
    storage_of,
    topic_types,
)
from fourbar_ros.config.antenna_config import AntennaConfig
from fourbar_ros.config.robot_model import coupler_joint_position
from fourbar_ros.core.antenna import Driven
from fourbar_ros.core.errors import one_line
from fourbar_ros.node.command_policy import Outcome, Policy, decide

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]

#: Commands per block: big enough that numpy's per-call cost vanishes, small enough for a few MB per block.
BLOCK = 65536


@dataclass
class ProcessStats:
    """Counts of a run, named like the node's diagnostics counters."""

    commands: int = 0
    accepted: int = 0
    clamped: int = 0
    rejected: dict[str, int] = field(default_factory=lambda: {o.value: 0 for o in Outcome if o.rejected})
    not_solved: int = 0
    published: int = 0
    with_velocity: int = 0
    seconds: float = 0.0
    topics: tuple[str, str] = ('', '')

    def summary(self) -> str:
        """One line for the user."""
        rejected = ', '.join(f'{v} {k.removeprefix("rejected_").replace("_", " ")}'
                             for k, v in self.rejected.items() if v)
        return (f'{self.commands} commands -> {self.published} joint_states and input_torque '
                f'({self.accepted} accepted, {self.clamped} clamped, {sum(self.rejected.values())} rejected'
                f'{": " + rejected if rejected else ""}'
                f'{f", {self.not_solved} not solvable" if self.not_solved else ""}) in {self.seconds:.2f} s')


def sibling_topic(command_topic: str, name: str) -> str:
    """``name`` in the command topic's namespace: /ns/antenna_angle_cmd -> /ns/NAME (the node's relative names)."""
    ns = command_topic.rsplit('/', 1)[0]
    return f'{ns}/{name}'


# --------------------------------------------------------------------------- the node's rules on arrays

@dataclass
class Served:
    """The commands of a block the node answers: index into the block, angle served (rad)."""

    index: npt.NDArray[np.intp]
    theta: FloatArray


def apply_policy(values: FloatArray, cfg: AntennaConfig, stats: ProcessStats) -> Served:
    """The node's decision for each command (rad): the common in-limits case on the array, every other
    command through ``command_policy.decide`` itself (identical outcomes by construction)."""
    inside = (cfg.theta_min <= values) & (values <= cfg.theta_max)  # NaN and inf fail here
    theta = values.copy()
    keep = inside.copy()
    outside = np.flatnonzero(~inside)
    stats.commands += values.size
    stats.accepted += values.size - outside.size
    if outside.size:
        policy, reach = Policy(cfg.out_of_limits), cfg.linkage.reach()
        for i in outside.tolist():
            d = decide(float(values[i]), cfg.theta_min, cfg.theta_max, policy, reach)
            if d.theta is None:
                stats.rejected[d.outcome.value] += 1
            else:
                stats.clamped += 1
                theta[i] = d.theta
                keep[i] = True
    index = np.flatnonzero(keep)
    return Served(index, theta[index])


def solve_poses(cfg: AntennaConfig, theta: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """gamma, delta (rad) and the driven rocker's torque (N m) at each angle: ``loads.pose`` on arrays.

    NaN where the core cannot solve (out of reach, a dead point).
    """
    link = cfg.linkage
    gamma, delta = link.rocker_angles(theta, cfg.branch, on_invalid='nan')
    load: float | FloatArray
    if cfg.has_gravity_load:  # loads.gravity_torque / com_height_rate, same operations
        rates = link.rates_at(theta, gamma, delta)
        along = 0.5 * cfg.coupler_length + cfg.com_offset_along
        rise = (cfg.rocker_ab_length * np.cos(gamma) * rates.dgamma_dtheta
                - along * np.cos(theta) - cfg.com_offset_normal * np.sin(theta))
        load = cfg.load_torque + cfg.antenna_mass * cfg.gravity * rise
    else:
        load = cfg.load_torque
    torque = np.asarray(link.torque_at(theta, gamma, delta, load, cfg.driven), dtype=np.float64)
    return np.asarray(gamma), np.asarray(delta), torque


@dataclass
class VelocityState:
    """The velocity anchor (``joint_velocity.velocity_step``'s): stamp (ns) and positions (rad) of the sample
    velocities are measured from, carried from block to block; None before the first published sample."""

    stamp_ns: int | None = None
    positions: FloatArray = field(default_factory=lambda: np.zeros(0))


def velocities(stamps_ns: IntArray, positions: FloatArray, timeout: float,
               state: VelocityState) -> tuple[FloatArray, BoolArray]:
    """``joint_velocity.velocity_step`` over a run of published samples (rows of ``positions``, rad, at
    ``stamps_ns``): (velocities rad/s, which rows have one). Updates ``state`` to the next anchor.

    The anchor of a sample is the first sample of the run of equal stamps just before it (the rule keeps
    the anchor while the stamp does not advance and replaces it otherwise), so the whole block needs one
    running maximum. Same floats as the scalar rule: dt = (t - t_anchor) * 1e-9 s from the integer
    difference, a velocity when 0 < dt <= timeout, (q - q_anchor) / dt.
    """
    n = stamps_ns.size
    k = positions.shape[1]
    if n == 0:
        return np.zeros((0, k)), np.zeros(0, dtype=np.bool_)
    carried = state.stamp_ns is not None
    if state.stamp_ns is not None:  # the anchor goes first, as the sample before the block
        t = np.concatenate((np.array([state.stamp_ns], dtype=np.int64), stamps_ns))
        q = np.concatenate((state.positions.reshape(1, k), positions))
    else:
        t, q = stamps_ns, positions
    idx = np.arange(t.size)
    new_run = np.ones(t.size, dtype=np.bool_)
    new_run[1:] = t[1:] != t[:-1]
    run_start = np.maximum.accumulate(np.where(new_run, idx, 0))
    anchor = np.empty(t.size, dtype=np.intp)
    anchor[0] = 0
    anchor[1:] = run_start[:-1]
    dt = (t - t[anchor]).astype(np.float64) * 1e-9
    have = (dt > 0.0) & (dt <= timeout)
    have[0] = False  # the very first sample has no anchor; a carried anchor is not output
    with np.errstate(divide='ignore', invalid='ignore'):
        vel = (q - q[anchor]) / dt[:, None]
    last = int(run_start[-1])
    state.stamp_ns = int(t[last])
    state.positions = q[last].copy()
    if carried:
        return vel[1:], have[1:]
    return vel, have


# --------------------------------------------------------------------------- reading and writing

def _command_blocks(reader: Any, conns: list[Any], path: Path, topic: str,
                    block: int) -> Iterator[tuple[IntArray, FloatArray]]:
    """(log times ns, values rad) of the commands, ``block`` at a time."""
    store = jazzy_typestore()
    stamps: list[int] = []
    raws: list[bytes] = []
    done = 0

    def flush() -> tuple[IntArray, FloatArray]:
        values = decode_float64s(raws)
        if values is None:  # not the plain little-endian form: the full deserializer, message by message
            out = np.empty(len(raws))
            for j, raw in enumerate(raws):
                try:
                    msg: Any = store.deserialize_cdr(raw, FLOAT64)
                    out[j] = float(msg.data)
                except Exception as exc:
                    raise BagError(f'{path}: message {done + j} on {topic} is not a valid {FLOAT64} '
                                   f'({one_line(exc)})') from exc
            values = out
        return np.array(stamps, dtype=np.int64), values

    try:
        for _, stamp, data in reader.messages(connections=conns):
            stamps.append(stamp)
            raws.append(bytes(data))
            if len(raws) == block:
                yield flush()
                done += len(raws)
                stamps.clear()
                raws.clear()
    except BagError:
        raise
    except Exception as exc:
        raise BagError(f'{path}: unreadable bag after {done + len(raws)} messages ({one_line(exc)})') from exc
    if raws:
        yield flush()


def process_bag(src: str | os.PathLike[str], dst: str | os.PathLike[str], cfg: AntennaConfig,
                topic: str | None = None, storage: str | None = None, block: int = BLOCK,
                on_block: Callable[[int], None] | None = None) -> ProcessStats:
    """Write to ``dst`` the joint_states and input_torque fourbar_node would publish for the commands of
    ``src`` (see the module docstring). ``topic``: the command topic (default: bag_io's choice of
    ``/antenna_angle_cmd``); ``storage``: 'mcap' or 'sqlite3' (default: the input's). ``on_block(n)`` is
    called with the number of commands done after each block. Raises BagError (one line) for bad input;
    ``dst`` then does not appear.
    """
    start = time.perf_counter()
    src_path = Path(src)
    stats = ProcessStats()
    names = cfg.joint_names
    driven = 0 if cfg.driven is Driven.GAMMA else 1
    vel_state = VelocityState()
    with open_bag(src_path) as reader:
        chosen = pick_command_topic(src_path, topic_types(reader), topic)
        conns = [c for c in reader.connections if c.topic == chosen]
        joint_topic, torque_topic = sibling_topic(chosen, 'joint_states'), sibling_topic(chosen, 'input_torque')
        stats.topics = (joint_topic, torque_topic)
        with AtomicBagWriter(dst, storage or storage_of(reader)) as bag:
            qos = [recorded_qos()]  # the node's publishers: reliable, volatile
            js_conn = bag.add_topic(joint_topic, JOINT_STATE, qos)
            tq_conn = bag.add_topic(torque_topic, FLOAT64, qos)
            write = bag.writer.write
            for stamps, values in _command_blocks(reader, conns, src_path, chosen, block):
                served = apply_policy(values, cfg, stats)
                t = stamps[served.index]
                gamma, delta, torque = solve_poses(cfg, served.theta)
                solved = np.isfinite(gamma) & np.isfinite(delta) & np.isfinite(torque)
                if not solved.all():
                    stats.not_solved += int(solved.size - np.count_nonzero(solved))
                    t, gamma, delta, torque = t[solved], gamma[solved], delta[solved], torque[solved]
                positions = np.column_stack((gamma, delta, coupler_joint_position(gamma, served.theta[solved])))
                effort = np.zeros_like(positions)
                effort[:, driven] = torque
                vel, have = velocities(t, positions, cfg.velocity_timeout, vel_state)
                try:
                    js = encode_joint_states(t, '', names, positions, effort, vel, have)
                except ValueError as exc:
                    raise BagError(f'{src_path}: {exc}') from None
                tq = encode_float64s(torque)
                for stamp, js_raw, tq_raw in zip(t.tolist(), js, tq, strict=True):
                    write(js_conn, stamp, js_raw)
                    write(tq_conn, stamp, tq_raw)
                stats.published += t.size
                stats.with_velocity += int(np.count_nonzero(have))
                if on_block is not None:
                    on_block(stats.commands)
            if stats.commands == 0:
                raise BagError(f'{src_path}: topic {chosen} has no messages')
            bag.counts[joint_topic] = bag.counts[torque_topic] = stats.published
    stats.seconds = time.perf_counter() - start
    return stats
