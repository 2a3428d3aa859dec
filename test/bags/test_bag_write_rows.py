"""The package's bag writer (``AtomicBagWriter``: its mcap storage writer, ``McapChunkWriter``) makes the bag
rosbags' own Writer makes, writing message by message or many messages in one call (``write_rows``), across chunk
boundaries and flushes: the same metadata.yaml and the same mcap file byte for byte (the same sqlite3 rows: a
database file is not the same byte for byte from one write to the next); readable by the mcap reader."""

from __future__ import annotations

import sqlite3
from pathlib import Path

import numpy as np
import pytest
from rosbags.rosbag2 import Writer
from support.bag_support import read_with_mcap, storage_file

from fourbar_ros.bags.storage import FLOAT64, JOINT_STATE, AtomicBagWriter, BagError, jazzy_typestore, recorded_qos
from fourbar_ros.bags.storage.adapters import adapter
from fourbar_ros.interface.cdr import encode_float64s, encode_joint_states
from fourbar_ros.interface.topics import Storage

ROWS = 12_000  # about 2.9 MB of mcap: a chunk the flush closes, two closed at 1 MiB, the last
BLOCKS = (1, 2, 997, 6_000)  # then the rest: blocks that start and end anywhere in a chunk
T0_NS = 1_700_000_000_000_000_000


def _messages() -> tuple[list[int], list[bytes], list[bytes]]:
    """Stamps (ns, 10 ms apart) and the CDR of a JointState (with a velocity on every third, so sizes vary) and a
    Float64 per row."""
    k = np.arange(ROWS)
    stamps = T0_NS + k.astype(np.int64) * 10_000_000
    q = np.column_stack([np.sin(k * 1e-3), np.cos(k * 1e-3), k * 1e-6])
    js = encode_joint_states(stamps, '', ('crank', 'rocker', 'coupler'), q, -q, 2 * q, k % 3 == 0)
    return stamps.tolist(), js, encode_float64s(k * 1e-4)


def _write(path: Path, storage: Storage, how: str) -> Path:
    """The messages of ``_messages`` in a bag at ``path``, written ``how``: 'rosbags' (rosbags' Writer, message by
    message), 'one_by_one' (``AtomicBagWriter.write``) or 'rows' (``AtomicBagWriter.write_rows`` in ``BLOCKS``);
    flushed after the third block's rows either way."""
    stamps, js, tq = _messages()
    blocks, start = [], 0
    for size in (*BLOCKS, ROWS):
        blocks.append((start, min(start + size, ROWS)))
        start = blocks[-1][1]
    flush_after = blocks[2][1]
    if how == 'rosbags':
        path.parent.mkdir(exist_ok=True)
        with Writer(path, version=9, storage_plugin=adapter(storage).plugin) as writer:
            js_conn, tq_conn = (writer.add_connection(t, m, typestore=jazzy_typestore(),
                                                      offered_qos_profiles=[recorded_qos()])
                                for t, m in (('/joint_states', JOINT_STATE), ('/input_torque', FLOAT64)))
            for k, (stamp, a, b) in enumerate(zip(stamps, js, tq, strict=True)):
                writer.write(js_conn, stamp, a)
                writer.write(tq_conn, stamp, b)
                if k + 1 == flush_after:
                    adapter(storage).flush(writer)
        return path
    path.parent.mkdir(exist_ok=True)
    with AtomicBagWriter(path, storage) as bag:
        js_conn = bag.add_topic('/joint_states', JOINT_STATE, [recorded_qos()])
        tq_conn = bag.add_topic('/input_torque', FLOAT64, [recorded_qos()])
        for start, end in blocks:
            if how == 'rows':
                bag.write_rows(stamps[start:end], ((js_conn, js[start:end]), (tq_conn, tq[start:end])))
            else:
                for stamp, a, b in zip(stamps[start:end], js[start:end], tq[start:end], strict=True):
                    bag.write(js_conn, stamp, a)
                    bag.write(tq_conn, stamp, b)
            if end == flush_after:
                bag.flush()
        assert bag.counts == {'/joint_states': ROWS, '/input_torque': ROWS}
    return path


def _tables(bag: Path) -> dict[str, list[tuple[object, ...]]]:
    """Every row of a sqlite3 bag's tables, in id order."""
    con = sqlite3.connect(f'file:{storage_file(bag)}?mode=ro', uri=True)
    try:
        names = [n for (n,) in con.execute("SELECT name FROM sqlite_master WHERE type = 'table' ORDER BY name")]
        return {n: list(con.execute(f'SELECT * FROM {n} ORDER BY rowid')) for n in names}
    finally:
        con.close()


@pytest.mark.parametrize('how', ['one_by_one', 'rows'])
@pytest.mark.parametrize('storage', list(Storage))
def test_the_package_writes_the_bag_rosbags_writes(tmp_path: Path, storage: Storage, how: str) -> None:
    reference = _write(tmp_path / 'rosbags' / 'bag', storage, 'rosbags')
    ours = _write(tmp_path / how / 'bag', storage, how)
    assert (reference / 'metadata.yaml').read_text() == (ours / 'metadata.yaml').read_text()
    if storage is Storage.SQLITE3:
        assert _tables(reference) == _tables(ours)
        return
    a, b = storage_file(reference).read_bytes(), storage_file(ours).read_bytes()
    differ = next((i for i, (x, y) in enumerate(zip(a, b, strict=False)) if x != y), min(len(a), len(b)))
    assert a == b, f'rosbags {len(a)} bytes, {how} {len(b)} bytes, first difference at byte {differ}'


def test_rows_read_back_with_the_mcap_reader(tmp_path: Path) -> None:
    stamps = _messages()[0]
    got = read_with_mcap(_write(tmp_path / 'rows', Storage.MCAP, 'rows'))
    assert {topic: len(msgs) for topic, msgs in got.items()} == {'/joint_states': ROWS, '/input_torque': ROWS}
    assert [t for t, _ in got['/input_torque']] == stamps
    assert [m.data for _, m in got['/input_torque']] == (np.arange(ROWS) * 1e-4).tolist()


@pytest.mark.parametrize('storage', list(Storage))
def test_rows_of_unequal_length_are_refused(tmp_path: Path, storage: Storage) -> None:
    _, js, tq = _messages()
    with pytest.raises(BagError, match='3 stamps for 2 messages on /input_torque'), \
            AtomicBagWriter(tmp_path / 'out', storage) as bag:
        js_conn = bag.add_topic('/joint_states', JOINT_STATE, [recorded_qos()])
        tq_conn = bag.add_topic('/input_torque', FLOAT64, [recorded_qos()])
        bag.write_rows([1, 2, 3], ((js_conn, js[:3]), (tq_conn, tq[:2])))
    assert not (tmp_path / 'out').exists()
