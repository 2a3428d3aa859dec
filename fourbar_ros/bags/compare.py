"""Compare two bags of the node's outputs message by message, each float in ulps of its scale (no rclpy).

What is compared, each quantity's scale and why: docs/how-to/bags.md#compare-two-output-bags; read ``BLOCK`` messages at
a time from both bags, so memory does not grow with them."""

from __future__ import annotations

import math
import os
from collections.abc import Generator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from fourbar_ros.bags.storage import FLOAT64, JOINT_STATE, BagError, jazzy_typestore, open_bag
from fourbar_ros.config.antenna_config import AntennaConfig
from fourbar_ros.core.antenna import Driven
from fourbar_ros.core.errors import one_line
from fourbar_ros.interface.cdr import decode_float64s, decode_joint_states
from fourbar_ros.interface.topics import (
    ANTENNA_ANGLE,
    COMPARED_FIELDS,
    DEFAULT_ULPS,
    INPUT_TORQUE,
    JOINT_STATES,
    JOINT_TRAJECTORY,
    sibling_topic,
)
from fourbar_ros.rules.velocity import VelocityState, anchors

FloatArray = npt.NDArray[np.float64]
#: Messages per block and topic.
BLOCK = 65536


@dataclass
class TopicData:
    """One topic's messages as arrays: log times (ns) and, for JointState, header stamps, names, frame ids,
    positions/efforts (n, k), velocities (n, k; NaN rows where empty) and the velocity presence."""

    msgtype: str
    log_ns: npt.NDArray[np.int64]
    stamp_ns: npt.NDArray[np.int64] | None = None
    names: list[tuple[str, ...]] = field(default_factory=list)
    frame_ids: list[str] = field(default_factory=list)
    positions: FloatArray | None = None
    velocities: FloatArray | None = None
    has_velocity: npt.NDArray[np.bool_] | None = None
    efforts: FloatArray | None = None
    data: FloatArray | None = None
    messages: list[Any] = field(default_factory=list)  # JointTrajectory: the decoded messages

    def __len__(self) -> int:
        return int(self.log_ns.size)


def _rows(seqs: list[Any], width: int) -> FloatArray:
    out = np.full((len(seqs), width), np.nan)
    for i, s in enumerate(seqs):
        if len(s):
            out[i, :len(s)] = s
    return out


def topic_types_of(path: str | os.PathLike[str]) -> dict[str, str]:
    """Topic -> type of the JointState, Float64 and JointTrajectory topics of a bag. Raises BagError (one line)."""
    with open_bag(path) as bag:
        return {t: m for t, m in bag.types.items() if m in (JOINT_STATE, FLOAT64, JOINT_TRAJECTORY)}


def _decode(path: Path, topic: str, msgtype: str, logs: list[int], raws: list[bytes], start: int) -> TopicData:
    """One block of messages as arrays: the block decoders of interface.cdr, else rosbags message by message."""
    store = jazzy_typestore()

    def full(j: int, raw: bytes) -> Any:
        try:
            return store.deserialize_cdr(raw, msgtype)
        except Exception as exc:
            raise BagError(f'{path}: message {start + j} on {topic} is not a valid {msgtype} '
                           f'({one_line(exc)})') from exc

    td = TopicData(msgtype, np.array(logs, dtype=np.int64))
    if msgtype == FLOAT64:
        values = decode_float64s(raws)
        td.data = values if values is not None else np.array([full(j, r).data for j, r in enumerate(raws)],
                                                             dtype=np.float64)
        return td
    if msgtype == JOINT_TRAJECTORY:
        td.messages = [full(j, r) for j, r in enumerate(raws)]
        td.stamp_ns = np.array([m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec for m in td.messages],
                               dtype=np.int64)
        td.names = [tuple(m.joint_names) for m in td.messages]
        return td
    first = full(0, raws[0])
    fast = decode_joint_states(raws, first.header.frame_id, tuple(first.name))
    if fast is not None:
        td.stamp_ns, td.positions, td.efforts = fast.stamps_ns, fast.position, fast.effort
        td.velocities, td.has_velocity = fast.velocity, fast.has_velocity
        td.names = [fast.names] * len(raws)
        td.frame_ids = [fast.frame_id] * len(raws)
        return td
    msgs = [full(j, r) for j, r in enumerate(raws)]
    width = max((max(len(m.position), len(m.velocity), len(m.effort)) for m in msgs), default=0)
    td.stamp_ns = np.array([m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec for m in msgs],
                           dtype=np.int64)
    td.names = [tuple(m.name) for m in msgs]
    td.frame_ids = [m.header.frame_id for m in msgs]
    td.positions = _rows([m.position for m in msgs], width)
    td.efforts = _rows([m.effort for m in msgs], width)
    td.velocities = _rows([m.velocity for m in msgs], width)
    td.has_velocity = np.array([len(m.velocity) > 0 for m in msgs], dtype=np.bool_)
    return td


def topic_blocks(path: str | os.PathLike[str], topic: str, msgtype: str,
                 block: int = BLOCK) -> Generator[TopicData, None, None]:
    """The messages of one topic, ``block`` at a time, as arrays. Raises BagError (one line)."""
    with open_bag(path) as bag:
        logs: list[int] = []
        raws: list[bytes] = []
        for _, stamp, data in bag.messages([topic]):
            logs.append(int(stamp))
            raws.append(bytes(data))
            if len(raws) == block:
                yield _decode(bag.path, topic, msgtype, logs, raws, bag.count - block)
                logs, raws = [], []
        if raws:
            yield _decode(bag.path, topic, msgtype, logs, raws, bag.count - len(raws))


# --------------------------------------------------------------------------- scales

def position_scale(q: FloatArray) -> FloatArray:
    """|q| + pi (rad): see the module docstring."""
    return np.abs(q) + math.pi


def velocity_scale(stamps_ns: npt.NDArray[np.int64], positions: FloatArray, velocities: FloatArray,
                   state: VelocityState | None = None) -> FloatArray:
    """|v| + (|q| + |q_anchor| + 2 pi) / dt per element (the anchor as the velocity rule picks it); |v| where no
    interval is known. ``state`` carries the anchor from block to block (updated)."""
    if positions.shape[0] == 0:
        return np.abs(velocities)
    a = anchors(stamps_ns, positions, state if state is not None else VelocityState())
    with np.errstate(divide='ignore', invalid='ignore'):
        spread = (np.abs(a.positions) + np.abs(a.anchor_positions) + 2.0 * math.pi) / a.dt[:, None]
    spread[~(a.dt > 0.0)] = 0.0
    out: FloatArray = np.abs(velocities) + spread
    return out


def torque_condition(cfg: AntennaConfig, positions: FloatArray) -> FloatArray:
    """1 + pi (|cot s| + |cot r|) per row of [gamma, delta] positions (rad): see the module docstring."""
    gamma, delta = positions[:, 0], positions[:, 1]
    bx, by = cfg.rocker_ab_length * np.cos(gamma), cfg.rocker_ab_length * np.sin(gamma)
    cx, cy = cfg.frame_length - cfg.rocker_cd_length * np.cos(delta), cfg.rocker_cd_length * np.sin(delta)
    theta = np.arctan2(by - cy, cx - bx)  # C - B = h (cos theta, -sin theta)
    s = gamma + delta
    r = delta - theta if cfg.driven is Driven.GAMMA else gamma + theta
    with np.errstate(divide='ignore', invalid='ignore'):
        cond = 1.0 + math.pi * (np.abs(np.cos(s) / np.sin(s)) + np.abs(np.cos(r) / np.sin(r)))
    cond[np.isnan(cond)] = np.inf
    out: FloatArray = cond
    return out


# --------------------------------------------------------------------------- comparing

@dataclass(frozen=True)
class Difference:
    """One mismatch: where, what, both values and the allowed difference (None: must be equal)."""

    topic: str
    index: int
    what: str
    a: object
    b: object
    allowed: float | None = None

    def describe(self) -> str:
        """One line."""
        tol = '' if self.allowed is None else f' (|a - b| = {_absdiff(self.a, self.b):.3g} > {self.allowed:.3g})'
        return f'{self.topic} message {self.index}: {self.what}: A {self.a!r}, B {self.b!r}{tol}'


def _absdiff(a: object, b: object) -> float:
    try:
        return abs(float(a) - float(b))  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return math.nan


@dataclass
class Comparison:
    """Everything found: counts per topic, mismatches (the first ``limit`` kept), the worst ratio per field."""

    compared: dict[str, int] = field(default_factory=dict)
    differences: list[Difference] = field(default_factory=list)
    mismatches: int = 0
    worst: dict[str, float] = field(default_factory=dict)  # |a - b| / allowed, per topic.field
    limit: int = 10

    @property
    def equal(self) -> bool:
        """True when nothing differs beyond the tolerance."""
        return self.mismatches == 0

    def add(self, diff: Difference, count: int = 1) -> None:
        self.mismatches += count
        if len(self.differences) < self.limit:
            self.differences.append(diff)


class Comparer:
    """Compare topic data of A and B with one tolerance (``ulps`` of each scale, or ``atol``)."""

    def __init__(self, cfg: AntennaConfig, ulps: float = DEFAULT_ULPS, atol: float | None = None,
                 ignore: Sequence[str] = (), limit: int = 10) -> None:
        unknown = sorted(set(ignore) - set(COMPARED_FIELDS))
        if unknown:
            raise BagError(f'cannot ignore {", ".join(unknown)} (choose from {", ".join(COMPARED_FIELDS)})')
        if not (math.isfinite(ulps) and ulps >= 0) or (atol is not None and not (math.isfinite(atol) and atol >= 0)):
            raise BagError('tolerances must be finite and >= 0')
        self.cfg, self.ulps, self.atol, self.ignore = cfg, ulps, atol, frozenset(ignore)
        self.result = Comparison(limit=limit)

    def allowed(self, scale: FloatArray) -> FloatArray:
        """The allowed |a - b| for values of this scale."""
        if self.atol is not None:
            return np.full(scale.shape, self.atol)
        out: FloatArray = self.ulps * np.spacing(np.abs(scale))
        return out

    def floats(self, topic: str, what: str, a: FloatArray, b: FloatArray, scale: FloatArray,
               offset: int = 0) -> None:
        """Element-wise a vs b within allowed(scale); equal floats (NaN == NaN included) always pass."""
        same = (a == b) | (np.isnan(a) & np.isnan(b))
        allowed = self.allowed(scale)
        with np.errstate(invalid='ignore'):
            diff = np.abs(a - b)
            ok = same | (diff <= allowed)
            ratio = np.where(same, 0.0, diff / np.where(allowed > 0, allowed, np.inf))
        key = f'{topic} {what}'
        worst = float(np.nanmax(ratio)) if ratio.size else 0.0
        self.result.worst[key] = max(self.result.worst.get(key, 0.0), worst if math.isfinite(worst) else math.inf)
        bad = np.argwhere(~ok)
        for row in bad[: self.result.limit]:
            i = int(row[0])
            label = what if a.ndim == 1 else f'{what}[{int(row[1])}]'
            self.result.add(Difference(topic, offset + i, label, float(a[tuple(row)]), float(b[tuple(row)]),
                                       float(allowed[tuple(row)])))
        if len(bad) > self.result.limit:
            self.result.mismatches += len(bad) - self.result.limit

    def exact(self, topic: str, what: str, a: Sequence[Any] | npt.NDArray[Any],
              b: Sequence[Any] | npt.NDArray[Any], offset: int = 0) -> None:
        """Element-wise equality (stamps, names, frame ids, velocity presence)."""
        if isinstance(a, np.ndarray) and isinstance(b, np.ndarray):
            bad: list[int] = np.flatnonzero(a != b).tolist()
        else:
            bad = [i for i, (x, y) in enumerate(zip(a, b, strict=True)) if x != y]
        for i in bad[: self.result.limit]:
            x, y = a[i], b[i]
            self.result.add(Difference(topic, offset + i, what, x.item() if isinstance(x, np.generic) else x,
                                       y.item() if isinstance(y, np.generic) else y))
        if len(bad) > self.result.limit:
            self.result.mismatches += len(bad) - self.result.limit

    def joint_states(self, topic: str, a: TopicData, b: TopicData, offset: int, anchor: VelocityState) -> None:
        """One block of JointStates (message ``offset`` on)."""
        assert a.positions is not None and b.positions is not None and a.stamp_ns is not None
        assert a.efforts is not None and b.efforts is not None and a.velocities is not None
        assert b.velocities is not None and a.has_velocity is not None and b.has_velocity is not None
        assert b.stamp_ns is not None
        self.exact(topic, 'name', a.names, b.names, offset)
        self.exact(topic, 'frame_id', a.frame_ids, b.frame_ids, offset)
        if a.positions.shape != b.positions.shape:
            self.result.add(Difference(topic, offset, 'joint count', a.positions.shape[1], b.positions.shape[1]))
            return
        if 'stamps' not in self.ignore:
            self.exact(topic, 'header stamp (ns)', a.stamp_ns, b.stamp_ns, offset)
            self.exact(topic, 'log time (ns)', a.log_ns, b.log_ns, offset)
        if 'positions' not in self.ignore:
            self.floats(topic, 'position', a.positions, b.positions, position_scale(a.positions), offset)
        if 'velocities' not in self.ignore:
            self.exact(topic, 'velocity present', a.has_velocity, b.has_velocity, offset)
            both = a.has_velocity & b.has_velocity
            scale = velocity_scale(a.stamp_ns, a.positions, a.velocities, anchor)
            self.floats(topic, 'velocity', np.where(both[:, None], a.velocities, 0.0),
                        np.where(both[:, None], b.velocities, 0.0), scale, offset)
        if 'efforts' not in self.ignore:
            self.floats(topic, 'effort', a.efforts, b.efforts, self.effort_scale(a), offset)

    def rockers(self, a: TopicData) -> tuple[FloatArray, int] | None:
        """The [gamma, delta] positions (rad) of a JointState block, found by the configured joint names, and the
        driven joint's column; None when the block's messages do not all name both rockers (alike)."""
        if a.positions is None or not a.names or any(n != a.names[0] for n in a.names):
            return None
        names = list(a.names[0])
        cfg = self.cfg
        if cfg.gamma_joint not in names or cfg.delta_joint not in names:
            return None
        rows = a.positions[:, [names.index(cfg.gamma_joint), names.index(cfg.delta_joint)]]
        return rows, names.index(cfg.driven_joint)

    def effort_scale(self, a: TopicData) -> FloatArray:
        """Scale of each effort: the torque's condition at the driven rocker, |value| at the other joints."""
        assert a.efforts is not None and a.positions is not None
        scale = np.abs(a.efforts)
        found = self.rockers(a)
        if found is not None:
            rows, d = found
            scale[:, d] = scale[:, d] * torque_condition(self.cfg, rows)
        return scale

    def trajectories(self, topic: str, a: TopicData, b: TopicData, offset: int) -> None:
        """One block of JointTrajectories (message ``offset`` on): see the module docstring."""
        assert a.stamp_ns is not None and b.stamp_ns is not None
        self.exact(topic, 'joint_names', a.names, b.names, offset)
        if 'stamps' not in self.ignore:
            self.exact(topic, 'header stamp (ns)', a.stamp_ns, b.stamp_ns, offset)
            self.exact(topic, 'log time (ns)', a.log_ns, b.log_ns, offset)
        for i, (ma, mb) in enumerate(zip(a.messages, b.messages, strict=True)):
            k = offset + i
            layout_a, layout_b = _layout(ma.points), _layout(mb.points)
            if layout_a != layout_b:
                self.result.add(Difference(topic, k, 'points (count, field lengths)', layout_a, layout_b))
                continue
            if not ma.points:
                continue
            ns = [[p.time_from_start.sec * 1_000_000_000 + p.time_from_start.nanosec for p in m.points]
                  for m in (ma, mb)]
            if ns[0] != ns[1]:
                j = next(j for j, (x, y) in enumerate(zip(*ns, strict=True)) if x != y)
                self.result.add(Difference(topic, k, f'time_from_start (ns)[{j}]', ns[0][j], ns[1][j]))
            for what, attr, ignored in (('position', 'positions', 'positions'),
                                        ('velocity', 'velocities', 'velocities'),
                                        ('acceleration', 'accelerations', 'velocities'),
                                        ('effort', 'effort', 'efforts')):
                if ignored in self.ignore or not len(getattr(ma.points[0], attr)):
                    continue
                va = np.concatenate([getattr(p, attr) for p in ma.points]).astype(np.float64)[None, :]
                vb = np.concatenate([getattr(p, attr) for p in mb.points]).astype(np.float64)[None, :]
                scale = position_scale(va) if attr == 'positions' else np.abs(va)
                self.floats(topic, f'point {what}', va, vb, scale, k)

    def float64s(self, topic: str, a: TopicData, b: TopicData, joints: TopicData | None, offset: int) -> None:
        """One block of Float64s; ``joints``: A's joint_states of the same messages (the torque's condition)."""
        assert a.data is not None and b.data is not None
        if 'stamps' not in self.ignore:
            self.exact(topic, 'log time (ns)', a.log_ns, b.log_ns, offset)
        if topic.rsplit('/', 1)[-1] in self.ignore:  # input_torque, antenna_angle, antenna_rate, load_torque
            return
        scale = position_scale(a.data) if topic.rsplit('/', 1)[-1] == ANTENNA_ANGLE.name else np.abs(a.data)
        found = self.rockers(joints) if joints is not None and len(joints) == len(a) else None
        if found is not None:
            scale = scale * torque_condition(self.cfg, found[0])
        self.floats(topic, 'data', a.data, b.data, scale, offset)


def compare_bags(path_a: str | os.PathLike[str], path_b: str | os.PathLike[str], cfg: AntennaConfig,
                 ulps: float = DEFAULT_ULPS, atol: float | None = None, ignore: Sequence[str] = (),
                 limit: int = 10, block: int = BLOCK) -> Comparison:
    """Compare the JointState, Float64 and JointTrajectory topics of two bags (see the module docstring), ``block``
    messages at a time per topic (memory does not grow with the bags). BagError (one line) on bad input."""
    comparer = Comparer(cfg, ulps, atol, ignore, limit)
    result = comparer.result
    types_a, types_b = topic_types_of(path_a), topic_types_of(path_b)
    if not types_a and not types_b:
        raise BagError(f'{path_a}, {path_b}: no JointState, Float64 or JointTrajectory topic to compare')
    for topic in sorted(set(types_a) | set(types_b)):
        ta, tb = types_a.get(topic), types_b.get(topic)
        if ta is None or tb is None:
            result.add(Difference(topic, 0, 'topic', 'present' if ta else 'missing', 'present' if tb else 'missing'))
            continue
        if ta != tb:
            result.add(Difference(topic, 0, 'type', ta, tb))
            continue
        sibling = sibling_topic(topic, JOINT_STATES.name)
        pair_joints = (ta == FLOAT64 and sibling_topic(topic, INPUT_TORQUE.name) == topic
                       and types_a.get(sibling) == JOINT_STATE)
        joints_iter = topic_blocks(path_a, sibling, JOINT_STATE, block) if pair_joints else None
        blocks_b = topic_blocks(path_b, topic, tb, block)
        blocks_a = topic_blocks(path_a, topic, ta, block)
        anchor = VelocityState()
        count_a = count_b = 0
        for a in blocks_a:
            b = next(blocks_b, None)
            joints = next(joints_iter, None) if joints_iter is not None else None
            n = min(len(a), len(b)) if b is not None else 0
            if n:
                a_n, b_n = _head(a, n), _head(b, n)  # type: ignore[arg-type]
                if ta == JOINT_STATE:
                    comparer.joint_states(topic, a_n, b_n, count_a, anchor)
                elif ta == JOINT_TRAJECTORY:
                    comparer.trajectories(topic, a_n, b_n, count_a)
                else:
                    comparer.float64s(topic, a_n, b_n, None if joints is None else _head(joints, n), count_a)
            count_a += len(a)
            count_b += len(b) if b is not None else 0
            if b is None or len(b) != len(a):
                break
        count_a += sum(len(x) for x in blocks_a)  # what one bag has more: counted, not compared
        count_b += sum(len(x) for x in blocks_b)
        if joints_iter is not None:
            joints_iter.close()
        result.compared[topic] = min(count_a, count_b)
        if count_a != count_b:
            result.add(Difference(topic, min(count_a, count_b), 'message count', count_a, count_b))
    return result


def _head(td: TopicData, n: int) -> TopicData:
    """The first n messages."""
    def cut(x: Any) -> Any:
        return None if x is None else x[:n]
    return TopicData(td.msgtype, td.log_ns[:n], cut(td.stamp_ns), td.names[:n], td.frame_ids[:n],
                     cut(td.positions), cut(td.velocities), cut(td.has_velocity), cut(td.efforts), cut(td.data),
                     td.messages[:n])


def _layout(points: Sequence[Any]) -> list[tuple[int, int, int, int]]:
    """(positions, velocities, accelerations, effort) lengths per JointTrajectory point."""
    return [(len(p.positions), len(p.velocities), len(p.accelerations), len(p.effort)) for p in points]
