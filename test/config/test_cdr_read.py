"""One JointState read from its CDR bytes (fourbar_ros.interface.cdr) gives back exactly what rclpy serialized, and
a payload that is not one (truncated, corrupted, big-endian) gives MalformedCdrError and nothing else."""

from __future__ import annotations

import contextlib
import struct
from collections.abc import Sequence

import pytest
from hypothesis import given
from hypothesis import strategies as st
from rclpy.serialization import serialize_message
from sensor_msgs.msg import JointState

from fourbar_ros.interface.cdr import (
    MalformedCdrError,
    joint_state_layout,
    read_joint_state_arrays,
    read_joint_state_head,
)

Read = tuple[int, int, str, list[str], tuple[float, ...], tuple[float, ...], tuple[float, ...]]


def read(raw: bytes) -> Read:
    """Every field of a CDR JointState, through both readers."""
    sec, nanosec, frame_id, names, at = read_joint_state_head(raw)
    return (sec, nanosec, frame_id, names, *read_joint_state_arrays(raw, at))


def joint_state(sec: int, nanosec: int, frame_id: str, names: list[str], position: Sequence[float],
                velocity: Sequence[float], effort: Sequence[float]) -> JointState:
    msg = JointState()
    msg.header.stamp.sec, msg.header.stamp.nanosec = sec, nanosec
    msg.header.frame_id = frame_id
    msg.name = names
    msg.position, msg.velocity, msg.effort = list(position), list(velocity), list(effort)
    return msg


def bits(values: Sequence[float]) -> bytes:
    """The IEEE 754 bits of the values (NaN payloads and signed zeros included)."""
    return struct.pack(f'<{len(values)}d', *values)


text = st.text(st.characters(blacklist_categories=('Cs',), blacklist_characters='\x00'), max_size=9)
floats = st.lists(st.floats(width=64), max_size=4)  # NaN and inf included; empty = absent
messages = st.builds(joint_state, st.integers(-2**31, 2**31 - 1), st.integers(0, 2**32 - 1), text,
                     st.lists(text, max_size=4), floats, floats, floats)


@given(messages)
def test_read_gives_back_every_field_bit_for_bit(msg: JointState) -> None:
    sec, nanosec, frame_id, names, position, velocity, effort = read(serialize_message(msg))
    assert (sec, nanosec, frame_id, names) == (msg.header.stamp.sec, msg.header.stamp.nanosec,
                                               msg.header.frame_id, list(msg.name))
    assert bits(position) == msg.position.tobytes()
    assert bits(velocity) == msg.velocity.tobytes()
    assert bits(effort) == msg.effort.tobytes()


@pytest.mark.parametrize('frame_len', range(10))  # every alignment of what follows the frame_id
def test_every_truncation_is_malformed(frame_len: int) -> None:
    names = ('gamma', 'a', '')
    msg = joint_state(-7, 999_999_999, 'f' * frame_len, list(names), [1.0, float('nan'), -0.0], [4.0, 5.0, 6.0],
                      [float('inf'), 2.0, 3.0])
    raw = serialize_message(msg)
    # rclpy may append bytes after the message (not part of it); its own length, from the block layout:
    whole = joint_state_layout('f' * frame_len, names, with_velocity=True).size
    assert read(raw[:whole])[3] == list(names)
    for size in range(whole):
        with pytest.raises(MalformedCdrError):
            read(raw[:size])


@given(messages, st.data())
def test_corrupted_bytes_read_or_raise_malformed_only(msg: JointState, data: st.DataObject) -> None:
    raw = bytearray(serialize_message(msg))
    for _ in range(data.draw(st.integers(1, 4))):
        raw[data.draw(st.integers(0, len(raw) - 1))] = data.draw(st.integers(0, 255))
    with contextlib.suppress(MalformedCdrError):  # any other exception fails the test
        read(bytes(raw))


def test_big_endian_and_invalid_utf8_are_malformed() -> None:
    raw = bytearray(serialize_message(joint_state(1, 2, 'ab', ['j'], [1.0], [], [])))
    big = bytes(raw[:1]) + b'\x00' + bytes(raw[2:])  # encapsulation CDR_BE
    with pytest.raises(MalformedCdrError, match='little-endian'):
        read_joint_state_head(big)
    raw[4 + 8 + 4] = 0xFF  # the frame_id's first byte
    with pytest.raises(MalformedCdrError, match='UTF-8'):
        read_joint_state_head(bytes(raw))
