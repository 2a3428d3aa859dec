"""A killed recording keeps what it had: periodic flushes, `fourbar reindex`, and a real SIGKILL of `fourbar record`.

Without ROS: a writer process that dies without any cleanup (os._exit) after a flush leaves exactly the flushed
messages in its hidden work directory; `fourbar reindex` turns them into a bag equal (topics, definitions, hashes,
QoS, every stamp and byte) to one written cleanly with those messages. With ROS: `fourbar record` is SIGKILLed while
a publisher streams; after reindex the bag is read by rosbags and by mcap or sqlite3, and holds every message that
was on disk (waited for with a deadline, one flush interval after it was published) before the kill.
"""

from __future__ import annotations

import os
import re
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml
from std_msgs.msg import Float64
from support.bag_support import Tool, read_with_mcap, read_with_sqlite, run_main, storage_file
from support.paths import REPO
from support.ros_support import TIMEOUT, RosSession, wait_for

from fourbar_ros.bags.storage import (
    FLOAT64,
    AtomicBagWriter,
    BagError,
    fingerprint,
    float64_cdr,
    jazzy_typestore,
    partial_dirs,
    read_messages,
    recorded_qos,
    reindex,
)
from fourbar_ros.interface.topics import Storage

# A writer that flushes after FLUSHED messages, writes UNFLUSHED more and dies without any cleanup.
KILLED_WRITER = '''
import os, sys
from fourbar_ros.bags.storage import AtomicBagWriter, FLOAT64, DIAGNOSTIC_ARRAY, Storage, float64_cdr, recorded_qos
out, storage, flushed, unflushed = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
bag = AtomicBagWriter(out, Storage(storage))
bag.open()
cmd = bag.add_topic('/antenna_angle_cmd', FLOAT64, [recorded_qos()])
bag.add_topic('/diagnostics', DIAGNOSTIC_ARRAY, [recorded_qos(transient_local=True)])
for i in range(flushed + unflushed):
    bag.write(cmd, 1_700_000_000_000_000_000 + 10_000_000 * i, float64_cdr(i * 0.001))
    if i + 1 == flushed:
        bag.flush()
os._exit(9)
'''


def _killed_writer(out: Path, storage: Storage, flushed: int, unflushed: int) -> None:
    proc = subprocess.run([sys.executable, '-c', KILLED_WRITER, str(out), storage.value, str(flushed), str(unflushed)],
                          check=False, cwd=REPO, capture_output=True, text=True, timeout=TIMEOUT)
    assert proc.returncode == 9, proc.stderr


def _clean_bag(out: Path, storage: Storage, n: int) -> Path:
    """What a clean recording of the first ``n`` messages would have written."""
    from fourbar_ros.bags.storage import DIAGNOSTIC_ARRAY

    with AtomicBagWriter(out, storage) as bag:
        cmd = bag.add_topic('/antenna_angle_cmd', FLOAT64, [recorded_qos()])
        bag.add_topic('/diagnostics', DIAGNOSTIC_ARRAY, [recorded_qos(transient_local=True)])
        for i in range(n):
            bag.write(cmd, 1_700_000_000_000_000_000 + 10_000_000 * i, float64_cdr(i * 0.001))
    return out


@pytest.mark.parametrize('storage', list(Storage))
def test_killed_writer_keeps_the_flushed_messages(storage: Storage, tmp_path: Path) -> None:
    out = tmp_path / 'rec'
    # 3000 unflushed messages (~120 KB) are still in the open mcap chunk or sqlite3 transaction when it dies.
    _killed_writer(out, storage, 500, 3000)
    assert not out.exists()
    [work] = partial_dirs(out)
    rc, lines, stdout = run_main(['reindex', out])
    assert rc == 0 and stdout == '', lines
    assert lines[0].startswith(f'fourbar reindex: wrote {out}: 500 messages (/antenna_angle_cmd: 500, /diagnostics: 0)')
    assert not work.exists() and partial_dirs(out) == []
    # Everything that defines the content equals a clean bag of the flushed messages; only custom data
    # (none here) cannot be recovered.
    assert fingerprint(out) == fingerprint(_clean_bag(tmp_path / 'clean', storage, 500))
    other = read_with_mcap(out) if storage is Storage.MCAP else read_with_sqlite(out)
    assert [m.data for _, m in other['/antenna_angle_cmd']] == [i * 0.001 for i in range(500)]
    info = yaml.safe_load((out / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert info['message_count'] == 500 and info['storage_identifier'] == storage.value


@pytest.mark.parametrize('storage', list(Storage))
def test_reindex_rebuilds_a_bag_directory_in_place(storage: Storage, tmp_path: Path) -> None:
    """A bag directory without metadata.yaml (e.g. moved out of the work directory by hand)."""
    out = tmp_path / 'rec'
    _killed_writer(out, storage, 40, 3)
    [work] = partial_dirs(out)
    moved = tmp_path / 'moved'
    (work / 'rec').rename(moved)
    assert not (moved / 'metadata.yaml').exists()
    result = reindex(moved)
    assert result.path == moved and result.messages == 40 and result.removed is None
    assert [m.data for _, m in read_messages(moved)['/antenna_angle_cmd']] == [i * 0.001 for i in range(40)]
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(['moved', work.name])  # nothing else left


@pytest.mark.parametrize('renames_before_the_stop', [1, 2])
def test_reindex_in_place_stopped_between_renames_leaves_one_bag(renames_before_the_stop: int, tmp_path: Path,
                                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    """A Ctrl-C right after the old bag is moved aside (1) or the new one moved in (2): one bag at the path, the old
    one or the rebuilt one, and nothing of the rebuild beside it."""
    out = tmp_path / 'rec'
    _killed_writer(out, Storage.MCAP, 40, 3)
    [work] = partial_dirs(out)
    moved = tmp_path / 'moved'
    (work / 'rec').rename(moved)
    before = sorted(p.name for p in moved.iterdir())
    real_rename, calls = os.rename, []

    def rename_then_interrupt(src: str | os.PathLike[str], dst: str | os.PathLike[str]) -> None:
        real_rename(src, dst)
        if moved in (Path(src), Path(dst)):  # the swap's renames, not the build's own
            calls.append(dst)
            if len(calls) == renames_before_the_stop:
                raise KeyboardInterrupt

    monkeypatch.setattr(os, 'rename', rename_then_interrupt)
    with pytest.raises(KeyboardInterrupt):
        reindex(moved)
    monkeypatch.undo()
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(['moved', work.name])
    if renames_before_the_stop == 1:
        assert sorted(p.name for p in moved.iterdir()) == before  # the old bag, as it was
    else:
        assert [m.data for _, m in read_messages(moved)['/antenna_angle_cmd']] == [i * 0.001 for i in range(40)]


def test_reindex_errors_are_one_line_and_change_nothing(tmp_path: Path) -> None:
    out = tmp_path / 'rec'
    rc, lines, _ = run_main(['reindex', out])
    assert rc == 2 and lines == [f'fourbar reindex: error: {out}: no such bag and no interrupted recording '
                                 '(.rec.*.partial) next to it']
    _killed_writer(out, Storage.MCAP, 5, 0)
    _killed_writer(out, Storage.MCAP, 6, 0)
    before = sorted(p.name for p in tmp_path.iterdir())
    with pytest.raises(BagError, match=r'2 interrupted recordings .*pass the one to recover'):
        reindex(out)
    assert sorted(p.name for p in tmp_path.iterdir()) == before
    result = reindex(tmp_path / before[1])  # naming the work directory picks it
    assert result.path == out and result.messages in (5, 6) and result.removed == tmp_path / before[1]
    [left] = partial_dirs(out)
    # OUT is now a complete bag: reindexing it again changes nothing and points at the other work directory.
    with pytest.raises(BagError, match=re.escape(f'a complete, readable bag already; nothing to do; to recover '
                                                 f'an interrupted recording, pass {left}')):
        reindex(out)
    # A work directory killed before any message was flushed has nothing to recover.
    empty = tmp_path / 'empty'
    _killed_writer(empty, Storage.MCAP, 0, 3)
    with pytest.raises(BagError, match='no complete topic to recover'):
        reindex(empty)
    assert not empty.exists() and len(partial_dirs(empty)) == 1


def test_reindex_recovers_from_a_truncated_mcap(tmp_path: Path) -> None:
    """A file cut anywhere keeps every chunk that ends before the cut (here: cut inside the last chunk)."""
    # Build a file of three flushed chunks, then cut it in the middle of the third.
    bag = AtomicBagWriter(tmp_path / 'src', Storage.MCAP)
    bag.open()
    conn = bag.add_topic('/antenna_angle_cmd', FLOAT64, [recorded_qos()])
    sizes = []
    for chunk in range(3):
        for i in range(100):
            bag.write(conn, 1_000 + chunk * 100 + i, float64_cdr(chunk * 100 + i))
        bag.flush()
        assert bag.work_dir is not None
        sizes.append(storage_file(bag.work_dir / 'src').stat().st_size)
    assert bag.work_dir is not None
    src = bag.work_dir / 'src'
    cut = (sizes[1] + sizes[2]) // 2
    storage_file(src).write_bytes(storage_file(src).read_bytes()[:cut])
    try:
        result = reindex(src)
        assert result.messages == 200 and result.kept_bytes == sizes[1]
        assert result.dropped is not None and result.dropped.startswith(f'{cut - sizes[1]} bytes after')
        assert [m.data for _, m in read_messages(src)['/antenna_angle_cmd']] == [float(i) for i in range(200)]
    finally:
        bag.abort()


# --------------------------------------------------------------------------- SIGKILL of `fourbar record`

def _on_disk(out: Path, storage: Storage) -> list[float]:
    """The stream values already in the recorder's work directory, read without changing anything."""
    dirs = partial_dirs(out)
    if not dirs:
        return []
    files = [p for p in (dirs[0] / out.name).iterdir() if p.suffix in ('.mcap', '.db3')]
    if not files:
        return []
    store = jazzy_typestore()
    values: list[float] = []
    if storage is Storage.MCAP:
        from mcap.records import Message
        from mcap.stream_reader import StreamReader

        with files[0].open('rb') as f:
            try:
                for record in StreamReader(f).records:
                    if isinstance(record, Message):
                        values.append(float(store.deserialize_cdr(bytes(record.data), FLOAT64).data))
            except Exception:  # the end of a file still being written
                pass
        return values
    try:
        con = sqlite3.connect(f'file:{files[0]}?mode=ro', uri=True, timeout=0.1)
        try:
            rows = con.execute('SELECT data FROM messages ORDER BY id').fetchall()
        finally:
            con.close()
    except sqlite3.Error:  # locked while the recorder commits: try again
        return []
    return [float(store.deserialize_cdr(bytes(d), FLOAT64).data) for (d,) in rows]


@pytest.mark.ros
@pytest.mark.slow
@pytest.mark.parametrize('storage', list(Storage))
def test_sigkill_while_streaming_keeps_all_but_the_last_interval(storage: Storage, ros: RosSession,
                                                                 tmp_path: Path) -> None:
    out = tmp_path / 'rec'
    interval = 0.5
    pub = ros.publisher(Float64, '/fourbar_reindex_stream', 1000)
    published: list[float] = []  # monotonic time of each message i (value float(i))

    def publish() -> None:
        pub.publish(Float64(data=float(len(published))))
        published.append(time.monotonic())

    with Tool(['record', out, '--storage', storage, '--topics', '/fourbar_reindex_stream',
               '--flush-interval', str(interval)], ros.env()) as recorder:
        recorder.wait_line('recording')
        ros.wait_subscribers(pub)  # both sides matched: message 0 is not sent before the recorder is reached
        timer = ros.node.create_timer(0.005, publish)  # ~200 messages/s while the recorder runs
        ros.executor.wake()
        try:
            wait_for(lambda: len(published) >= 100, what='100 published messages')
            marked = len(published)  # messages 0 .. marked-1 went out before this point
            # A flush interval later they are on disk: wait for it (deadline), streaming on meanwhile.
            wait_for(lambda: len(_on_disk(out, storage)) >= marked, poll=0.05,
                     what=f'messages 0..{marked - 1} flushed to the work directory')
            recorder.signal(signal.SIGKILL)
            killed_at = time.monotonic()
            assert recorder.wait() == -signal.SIGKILL
        finally:
            ros.destroy(timer)
    sent = len(published)
    assert not out.exists()
    rc, lines, _ = run_main(['reindex', out])
    assert rc == 0, lines
    values = [m.data for _, m in read_messages(out)['/fourbar_reindex_stream']]
    other = read_with_mcap(out) if storage is Storage.MCAP else read_with_sqlite(out)
    assert [m.data for _, m in other['/fourbar_reindex_stream']] == values
    kept = len(values)
    # Reliable QoS, in order: what is kept is a gap-free prefix of what was sent, and holds everything that
    # was on disk before the kill.
    assert values == [float(i) for i in range(kept)]
    assert marked <= kept <= sent
    older = sum(1 for t in published if t < killed_at - interval)
    print(f'{storage}: {sent} sent, kill {killed_at - published[0]:.2f} s after the first; kept {kept}; '
          f'{older} sent more than {interval} s before the kill; {lines}')
