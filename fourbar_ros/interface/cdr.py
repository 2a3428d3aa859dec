"""CDR bytes of the interface's messages (numpy and stdlib, no ROS): JointState and Float64, one or a block at a time.

The byte layout and why blocks need no per-message serializer: docs/how-to/bags.md."""

from __future__ import annotations

import itertools
import struct
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import numpy.typing as npt

from fourbar_ros.interface.stamps import join_ns, split_ns

ENCAPSULATION = b'\x00\x01\x00\x00'  #: CDR, little endian, no options
FloatArray = npt.NDArray[np.float64]


class MalformedCdrError(ValueError):
    """A payload that is not a little-endian CDR message of the expected type (truncated, inconsistent, big-endian)."""


_UINT32 = struct.Struct('<I')
_FLOAT64_LE = struct.Struct('<d')


def read_float64(raw: bytes) -> float:
    """The value of a little-endian CDR ``std_msgs/msg/Float64`` (the 4-byte encapsulation, then the double; any
    alignment padding after it is ignored). Raises MalformedCdrError for anything shorter or another encoding."""
    if len(raw) < 12 or raw[:4] != ENCAPSULATION:
        raise MalformedCdrError(f'{len(raw)} bytes starting {raw[:4].hex() or "(none)"}: not a little-endian CDR '
                                'Float64 (12 bytes, 00010000 first)')
    value: float = _FLOAT64_LE.unpack_from(raw, 4)[0]
    return value
_STAMP = struct.Struct('<iI')
_HEAD_LEN = len(ENCAPSULATION)


def _string(raw: bytes, at: int) -> tuple[str, int]:
    """The CDR string at ``at`` (its uint32 length aligned to 4) and the offset after it."""
    at += -(at - _HEAD_LEN) % 4
    end = at + 4
    if end > len(raw):
        raise MalformedCdrError(f'payload of {len(raw)} bytes ends inside a string length at byte {at}')
    size = _UINT32.unpack_from(raw, at)[0]
    stop = end + size
    if size == 0 or stop > len(raw) or raw[stop - 1] != 0:
        raise MalformedCdrError(f'string of {size} bytes at byte {at} is not NUL-terminated within the payload')
    try:
        return raw[end:stop - 1].decode('utf-8'), stop
    except UnicodeDecodeError as exc:
        raise MalformedCdrError(f'string at byte {at} is not UTF-8') from exc


def _float64s(raw: bytes, at: int) -> tuple[tuple[float, ...], int]:
    """The CDR float64 sequence at ``at`` (length aligned to 4, elements to 8 when any) and the offset after it."""
    at += -(at - _HEAD_LEN) % 4
    if at + 4 > len(raw):
        raise MalformedCdrError(f'payload of {len(raw)} bytes ends inside a sequence length at byte {at}')
    count = _UINT32.unpack_from(raw, at)[0]
    at += 4
    if count == 0:
        return (), at
    at += -(at - _HEAD_LEN) % 8
    end = at + 8 * count
    if end > len(raw):
        raise MalformedCdrError(f'{count} float64 at byte {at} run past the payload of {len(raw)} bytes')
    return struct.unpack_from(f'<{count}d', raw, at), end


def read_joint_state_head(raw: bytes) -> tuple[int, int, str, list[str], int]:
    """(stamp sec, stamp nanosec, frame_id, names, offset of the arrays) of a CDR ``sensor_msgs/msg/JointState``.

    Raises MalformedCdrError for anything but little-endian plain CDR with room for these fields; reads nothing past
    the payload. ``read_joint_state_arrays(raw, offset)`` then reads the floats.
    """
    if len(raw) < _HEAD_LEN + 8 or raw[0] != 0 or raw[1] != 1:
        raise MalformedCdrError(f'not a little-endian CDR message (encapsulation {bytes(raw[:2]).hex()}, '
                           f'{len(raw)} bytes)')
    sec, nanosec = _STAMP.unpack_from(raw, _HEAD_LEN)
    frame_id, at = _string(raw, _HEAD_LEN + 8)
    at += -(at - _HEAD_LEN) % 4
    if at + 4 > len(raw):
        raise MalformedCdrError(f'payload of {len(raw)} bytes ends inside the name count at byte {at}')
    count = _UINT32.unpack_from(raw, at)[0]
    at += 4
    if 5 * count > len(raw) - at:  # each name takes at least its length and its NUL
        raise MalformedCdrError(f'{count} names at byte {at} cannot fit the payload of {len(raw)} bytes')
    names = []
    for _ in range(count):
        name, at = _string(raw, at)
        names.append(name)
    return sec, nanosec, frame_id, names, at


def read_joint_state_arrays(raw: bytes, at: int) -> tuple[tuple[float, ...], tuple[float, ...], tuple[float, ...]]:
    """(position, velocity, effort) of a CDR JointState whose arrays start at ``at`` (``read_joint_state_head``).

    Values bit for bit as sent. Raises MalformedCdrError when they do not fit the payload.
    """
    position, at = _float64s(raw, at)
    velocity, at = _float64s(raw, at)
    effort, _ = _float64s(raw, at)
    return position, velocity, effort


class _Buf:
    """A growing CDR body with the alignment rule; records where the variable fields sit."""

    def __init__(self) -> None:
        self.data = bytearray()

    def align(self, n: int) -> None:
        self.data += b'\x00' * (-len(self.data) % n)

    def uint32(self, value: int) -> int:
        self.align(4)
        at = len(self.data)
        self.data += int(value).to_bytes(4, 'little')
        return at

    def string(self, text: str) -> None:
        raw = text.encode('utf-8') + b'\x00'
        self.uint32(len(raw))
        self.data += raw

    def float64s(self, count: int) -> int:
        """A float64 sequence of ``count`` zeros; returns the offset of its first element (-1 if empty)."""
        self.uint32(count)
        if count == 0:
            return -1
        self.align(8)
        at = len(self.data)
        self.data += b'\x00' * (8 * count)
        return at


@dataclass(frozen=True)
class JointStateLayout:
    """One fixed byte layout: template bytes (encapsulation included) and a structured dtype over them."""

    size: int
    template: bytes
    dtype: np.dtype[np.void]
    with_velocity: bool


@lru_cache(maxsize=16)
def joint_state_layout(frame_id: str, names: tuple[str, ...], with_velocity: bool) -> JointStateLayout:
    """The layout of a JointState with this frame_id and these names, position and effort of ``len(names)``
    values each and velocity of ``len(names)`` values (``with_velocity``) or none."""
    if '\x00' in frame_id or any('\x00' in n for n in names):
        raise ValueError('frame_id and joint names must not contain NUL characters')
    k = len(names)
    body = _Buf()
    sec_at = body.uint32(0)
    nsec_at = body.uint32(0)
    body.string(frame_id)
    body.uint32(k)
    for name in names:
        body.string(name)
    pos_at = body.float64s(k)
    vel_at = body.float64s(k if with_velocity else 0)
    eff_at = body.float64s(k)
    head = len(ENCAPSULATION)
    fields: dict[str, tuple[npt.DTypeLike, int]] = {'sec': ('<i4', head + sec_at), 'nanosec': ('<u4', head + nsec_at)}
    if k:
        fields['position'] = (('<f8', (k,)), head + pos_at)
        fields['effort'] = (('<f8', (k,)), head + eff_at)
        if with_velocity:
            fields['velocity'] = (('<f8', (k,)), head + vel_at)
    size = head + len(body.data)
    dtype = np.dtype({'names': list(fields), 'formats': [f[0] for f in fields.values()],
                      'offsets': [f[1] for f in fields.values()], 'itemsize': size})
    return JointStateLayout(size, ENCAPSULATION + bytes(body.data), dtype, with_velocity)


def _rows(layout: JointStateLayout, count: int) -> npt.NDArray[np.void]:
    """``count`` copies of the template, as a writable structured array."""
    buf = np.frombuffer(layout.template * count, dtype=np.uint8).copy()
    return buf.view(layout.dtype)


def _split(blob: bytes, size: int) -> list[bytes]:
    return [blob[i:i + size] for i in range(0, len(blob), size)]


def encode_joint_states(stamps_ns: npt.NDArray[np.int64], frame_id: str, names: Sequence[str],
                        position: FloatArray, effort: FloatArray, velocity: FloatArray,
                        has_velocity: npt.NDArray[np.bool_]) -> list[bytes]:
    """The CDR bytes of ``len(stamps_ns)`` JointState messages, in order.

    ``position``, ``effort``, ``velocity``: shape (n, len(names)) (rad, N m, rad/s); message i carries
    ``velocity[i]`` when ``has_velocity[i]``, else an empty velocity (the row is then ignored).
    """
    names = tuple(names)
    n = len(stamps_ns)
    k = len(names)
    sec, nanosec = split_ns(stamps_ns)
    position = np.asarray(position, dtype=np.float64).reshape(n, k)
    effort = np.asarray(effort, dtype=np.float64).reshape(n, k)
    velocity = np.asarray(velocity, dtype=np.float64).reshape(n, k)
    has_velocity = np.asarray(has_velocity, dtype=np.bool_).reshape(n)
    parts: dict[bool, list[bytes]] = {}
    for with_velocity in (True, False):
        select = has_velocity if with_velocity else ~has_velocity
        count = int(np.count_nonzero(select))
        if count == 0:
            parts[with_velocity] = []
            continue
        layout = joint_state_layout(frame_id, names, with_velocity)
        rows = _rows(layout, count)
        every = count == n
        rows['sec'] = sec if every else sec[select]
        rows['nanosec'] = nanosec if every else nanosec[select]
        if k:
            rows['position'] = position if every else position[select]
            rows['effort'] = effort if every else effort[select]
            if with_velocity:
                rows['velocity'] = velocity if every else velocity[select]
        parts[with_velocity] = _split(rows.tobytes(), layout.size)
    if not parts[False]:
        return parts[True]
    if not parts[True]:
        return parts[False]
    # Interleave by runs of equal presence (few: a velocity is missing only after a gap or a stamp step).
    edges = [0, *(np.flatnonzero(has_velocity[1:] != has_velocity[:-1]) + 1).tolist(), n]
    out: list[bytes] = []
    taken = {True: 0, False: 0}
    for lo, hi in itertools.pairwise(edges):
        kind = bool(has_velocity[lo])
        start = taken[kind]
        out += parts[kind][start:start + hi - lo]
        taken[kind] = start + hi - lo
    return out


_FLOAT64 = np.dtype({'names': ['head', 'data'], 'formats': ['<u4', '<f8'], 'offsets': [0, 4], 'itemsize': 12})
_HEAD = int.from_bytes(ENCAPSULATION, 'little')


def encode_float64s(values: FloatArray) -> list[bytes]:
    """The CDR bytes of one ``std_msgs/msg/Float64`` per value (12 bytes each; NaN and inf kept bit for bit)."""
    values = np.asarray(values, dtype=np.float64).reshape(-1)
    recs = np.empty(values.size, dtype=_FLOAT64)
    recs['head'] = _HEAD
    recs['data'] = values
    return _split(recs.tobytes(), 12)


def decode_float64s(raws: Sequence[bytes]) -> FloatArray | None:
    """The values of little-endian CDR ``std_msgs/msg/Float64`` messages, or None when any message is not
    exactly that 12-byte form (the caller then decodes one by one with a full deserializer)."""
    if any(len(r) != 12 for r in raws):
        return None
    recs = np.frombuffer(b''.join(raws), dtype=_FLOAT64)
    if recs.size and not bool(np.all(recs['head'] == _HEAD)):
        return None
    return np.array(recs['data'], dtype=np.float64)


@dataclass(frozen=True)
class DecodedJointStates:
    """JointStates of one frame_id and one list of names as arrays (stamps ns; positions, efforts,
    velocities (n, k) with NaN rows where the velocity is empty; ``has_velocity``)."""

    frame_id: str
    names: tuple[str, ...]
    stamps_ns: npt.NDArray[np.int64]
    position: FloatArray
    effort: FloatArray
    velocity: FloatArray
    has_velocity: npt.NDArray[np.bool_]


def _constant_mask(layout: JointStateLayout) -> npt.NDArray[np.bool_]:
    """True at the bytes of a layout that are the same in every message (everything but stamp and floats)."""
    mask = np.ones(layout.size, dtype=np.bool_)
    fields = layout.dtype.fields
    assert fields is not None
    for name in layout.dtype.names or ():
        sub, offset = fields[name][0], fields[name][1]
        mask[offset:offset + sub.itemsize] = False
    return mask


def decode_joint_states(raws: Sequence[bytes], frame_id: str, names: tuple[str, ...]) -> DecodedJointStates | None:
    """Decode little-endian CDR JointStates that all have this frame_id and these names, position and effort of
    ``len(names)`` values and a velocity of ``len(names)`` or none: the inverse of ``encode_joint_states``.
    None when any message is in another form (the caller then uses a full deserializer)."""
    n, k = len(raws), len(names)
    layouts = {lay.size: lay for lay in (joint_state_layout(frame_id, names, True),
                                         joint_state_layout(frame_id, names, False))}
    if len(layouts) != 2:
        return None
    sizes = np.fromiter((len(r) for r in raws), dtype=np.int64, count=n)
    stamps = np.empty(n, dtype=np.int64)
    position, effort = np.empty((n, k)), np.empty((n, k))
    velocity = np.full((n, k), np.nan)
    has_velocity = np.zeros(n, dtype=np.bool_)
    done = 0
    for size, layout in layouts.items():
        select = np.flatnonzero(sizes == size)
        if select.size == 0:
            continue
        done += select.size
        rows = np.frombuffer(b''.join([raws[i] for i in select.tolist()]), dtype=np.uint8).reshape(-1, size)
        const = _constant_mask(layout)
        template = np.frombuffer(layout.template, dtype=np.uint8)
        if not bool(np.all(rows[:, const] == template[const])):
            return None
        recs = rows.reshape(-1).view(layout.dtype)
        stamps[select] = join_ns(recs['sec'], recs['nanosec'])
        if k:
            position[select] = recs['position']
            effort[select] = recs['effort']
            if layout.with_velocity:
                velocity[select] = recs['velocity']
        has_velocity[select] = layout.with_velocity
    if done != n:
        return None
    return DecodedJointStates(frame_id, names, stamps, position, effort, velocity, has_velocity)
