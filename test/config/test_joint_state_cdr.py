"""Block CDR encoding (fourbar_ros.interface.cdr) is byte for byte what rosbags' serializer writes."""

from __future__ import annotations

import math
import struct
from typing import Any

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from fourbar_ros.bags.storage import FLOAT64, JOINT_STATE, jazzy_typestore
from fourbar_ros.interface.cdr import (
    decode_float64s,
    decode_joint_states,
    encode_float64s,
    encode_joint_states,
    joint_state_layout,
)

STORE = jazzy_typestore()


def reference(stamp_ns: int, frame_id: str, names: tuple[str, ...], position: Any, velocity: Any | None,
              effort: Any) -> bytes:
    """rosbags' own serialization of one JointState."""
    t = STORE.types
    sec, nanosec = divmod(stamp_ns, 1_000_000_000)
    msg = t[JOINT_STATE](
        header=t['std_msgs/msg/Header'](stamp=t['builtin_interfaces/msg/Time'](sec=sec, nanosec=nanosec),
                                        frame_id=frame_id),
        name=list(names), position=np.array(position, dtype=np.float64),
        velocity=np.array([] if velocity is None else velocity, dtype=np.float64),
        effort=np.array(effort, dtype=np.float64))
    return bytes(STORE.serialize_cdr(msg, JOINT_STATE))


finite = st.floats(allow_nan=False, allow_infinity=True, width=64)
text = st.text(alphabet=st.characters(blacklist_characters='\x00', blacklist_categories=('Cs',)), max_size=9)


@given(frame_id=text, names=st.lists(text, min_size=0, max_size=3).map(tuple),
       rows=st.lists(st.tuples(st.integers(0, 2**31 * 10**9 - 1), st.booleans(), st.lists(finite, min_size=9,
                                                                                           max_size=9)),
                     min_size=1, max_size=6))
def test_joint_states_equal_rosbags_bytes(frame_id: str, names: tuple[str, ...],
                                          rows: list[tuple[int, bool, list[float]]]) -> None:
    """Any frame_id and name lengths (odd ones shift every later field's alignment), 0-3 joints, velocity
    present or empty per message, stamps up to the int32 limit: the same bytes as rosbags."""
    k = len(names)
    stamps = np.array([r[0] for r in rows], dtype=np.int64)
    has = np.array([r[1] for r in rows])
    vals = np.array([r[2] for r in rows]).reshape(len(rows), 3, 3)[:, :, :k]
    got = encode_joint_states(stamps, frame_id, names, vals[:, 0], vals[:, 2], vals[:, 1], has)
    assert len(got) == len(rows)
    for i, raw in enumerate(got):
        assert raw == reference(int(stamps[i]), frame_id, names, vals[i, 0], vals[i, 1] if has[i] else None,
                                vals[i, 2]), i


@pytest.mark.parametrize('frame_id', ['', 'a', 'ab', 'abc', 'fourbar_base', 'Ünïcode'])
@pytest.mark.parametrize('names', [('rocker_ab_joint', 'rocker_cd_joint'), ('a', 'bcd'), ('ab', 'c'), ('', '')])
def test_node_shapes_equal_rosbags_bytes(frame_id: str, names: tuple[str, str]) -> None:
    """The node's shape (two joints) with every alignment of the strings, velocity present and empty mixed,
    NaN/inf/-0.0 kept bit for bit."""
    n = 7
    stamps = np.array([0, 1, 999_999_999, 1_000_000_000, 1_700_000_000_123_456_789, 2**31 * 10**9 - 1, 5],
                      dtype=np.int64)
    rng = np.random.default_rng(7)
    pos = rng.normal(size=(n, 2))
    vel = rng.normal(size=(n, 2))
    eff = rng.normal(size=(n, 2))
    pos[1, 0], vel[2, 1], eff[3, 0] = math.nan, math.inf, -0.0
    has = np.array([False, True, True, False, True, False, True])
    got = encode_joint_states(stamps, frame_id, names, pos, eff, vel, has)
    for i in range(n):
        assert got[i] == reference(int(stamps[i]), frame_id, names, pos[i], vel[i] if has[i] else None, eff[i])
    for with_velocity in (True, False):
        assert joint_state_layout(frame_id, names, with_velocity).size == len(
            reference(0, frame_id, names, [0.0, 0.0], [0.0, 0.0] if with_velocity else None, [0.0, 0.0]))


def test_all_with_or_all_without_velocity() -> None:
    stamps = np.arange(5, dtype=np.int64) * 10_000_000
    q = np.arange(10.0).reshape(5, 2)
    for has in (np.ones(5, dtype=bool), np.zeros(5, dtype=bool)):
        got = encode_joint_states(stamps, 'f', ('x', 'y'), q, -q, q * 3, has)
        assert got == [reference(int(stamps[i]), 'f', ('x', 'y'), q[i], q[i] * 3 if has[i] else None, -q[i])
                       for i in range(5)]


def test_stamp_beyond_int32_seconds_is_refused() -> None:
    with pytest.raises(ValueError, match='int32'):
        encode_joint_states(np.array([2**31 * 10**9], dtype=np.int64), '', ('a',), np.zeros((1, 1)),
                            np.zeros((1, 1)), np.zeros((1, 1)), np.zeros(1, dtype=bool))


def test_float64_roundtrip_equals_rosbags() -> None:
    values = np.array([0.0, -0.0, 1.5, -3.25e-300, math.nan, math.inf, -math.inf, 5e-324])
    got = encode_float64s(values)
    for v, raw in zip(values, got, strict=True):
        assert raw == bytes(STORE.serialize_cdr(STORE.types[FLOAT64](data=float(v)), FLOAT64))
    back = decode_float64s(got)
    assert back is not None
    assert np.array_equal(back.view(np.uint64), values.view(np.uint64))  # bit for bit, NaN payload included


def test_float64_decode_refuses_other_forms() -> None:
    good = encode_float64s(np.array([1.0]))[0]
    big_endian = b'\x00\x00\x00\x00' + struct.pack('>d', 1.0)
    assert decode_float64s([good, big_endian]) is None
    assert decode_float64s([good, good[:8]]) is None
    assert decode_float64s([good + b'\x00\x00\x00\x00']) is None
    assert decode_float64s([good[:8], good + b'\x00\x00\x00\x00']) is None  # right total, wrong parts


def test_joint_states_decode_back_or_refuse() -> None:
    """decode_joint_states inverts the encoder (rosbags-equal bytes, so any such message) and refuses any
    message of another form: other names or frame_id, another joint count, a truncated message."""
    stamps = np.array([5, 1_000_000_003, 7], dtype=np.int64)
    rng = np.random.default_rng(2)
    pos, eff, vel = rng.normal(size=(3, 2)), rng.normal(size=(3, 2)), rng.normal(size=(3, 2))
    has = np.array([True, False, True])
    raws = encode_joint_states(stamps, 'ab', ('x', 'yyy'), pos, eff, vel, has)
    got = decode_joint_states(raws, 'ab', ('x', 'yyy'))
    assert got is not None
    assert np.array_equal(got.stamps_ns, stamps) and np.array_equal(got.position, pos)
    assert np.array_equal(got.effort, eff) and np.array_equal(got.has_velocity, has)
    assert np.array_equal(got.velocity[has], vel[has]) and np.isnan(got.velocity[~has]).all()
    assert decode_joint_states(raws, 'ab', ('x', 'yyz')) is None
    assert decode_joint_states(raws, 'a', ('x', 'yyy')) is None
    other = reference(5, 'ab', ('x', 'yyy'), [1.0, 2.0, 3.0], None, [1.0, 2.0, 3.0])
    assert decode_joint_states([*raws, other], 'ab', ('x', 'yyy')) is None
    assert decode_joint_states([*raws, raws[0][:-8]], 'ab', ('x', 'yyy')) is None
