"""Bag files without ROS: the committed bags match their generator, are valid rosbag2 (Jazzy, v9) for
rosbags and for independent readers, say what they claim; bad bags give one-line errors; writes are atomic."""

from __future__ import annotations

import itertools
import math
import os
import shutil
import sqlite3
import struct
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
import yaml
from support.bag_support import BAG_DIR, CONFIG, DEMO_BAG, committed_bags, read_with_mcap, storage_file
from support.paths import REPO

from fourbar_ros.bags.storage import (
    COMMAND_TOPIC,
    FLOAT64,
    AtomicBagWriter,
    BagError,
    fingerprint,
    float64_cdr,
    jazzy_typestore,
    read_commands,
    recorded_qos,
    sibling_topic,
    write_command_bag,
)
from fourbar_ros.commands import main as cli_main
from fourbar_ros.config.antenna_config import AntennaConfig, load_config
from fourbar_ros.interface.topics import Storage

BAGS = committed_bags()
KINDS = ('sweep', 'steps', 'fast_ramp', 'jitter', 'bad_values')


def _ids(paths: list[Path]) -> list[str]:
    return [p.name for p in paths]


def _same_float(a: float, b: float) -> bool:
    return struct.pack('<d', a) == struct.pack('<d', b)


# --------------------------------------------------------------------------- generator vs committed data

@pytest.fixture(scope='module')
def regenerated(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp('regen') / 'bags'
    subprocess.run([sys.executable, str(REPO / 'scripts' / 'make_command_bags.py'), '--out', str(out)],
                   check=True, capture_output=True, cwd=REPO)
    return out


@pytest.mark.parametrize(('command_topic', 'expected'), [
    ('/antenna_angle_cmd', '/joint_states'),  # a bag's root namespace
    ('/robot/antenna_angle_cmd', '/robot/joint_states'),  # a namespaced node's recording
    ('/a/b/antenna_angle_cmd', '/a/b/joint_states'),
    ('antenna_angle_cmd', 'joint_states'),  # a relative name stays relative, as the node's names resolve
    ('robot/antenna_angle_cmd', 'robot/joint_states'),
])
def test_sibling_topic_is_in_the_command_topics_namespace(command_topic: str, expected: str) -> None:
    assert sibling_topic(command_topic, 'joint_states') == expected


def test_every_kind_is_committed_in_both_storages() -> None:
    names = {p.name for p in BAG_DIR.iterdir() if p.is_dir()}
    assert names == {f'{k}_{s}' for k in KINDS for s in map(str, Storage)}
    assert DEMO_BAG.is_dir()


def test_generator_writes_exactly_the_committed_bags(regenerated: Path) -> None:
    generated = {p.name for p in regenerated.iterdir()}
    assert generated == {p.name for p in BAGS}


@pytest.mark.parametrize('bag', BAGS, ids=_ids(BAGS))
def test_committed_bag_matches_generator(bag: Path, regenerated: Path) -> None:
    """Topics, types, hashes, definitions, QoS, every stamp and every CDR byte, custom data."""
    assert fingerprint(bag) == fingerprint(regenerated / bag.name)


def test_fingerprint_sees_a_one_bit_change(tmp_path: Path) -> None:
    a, b = tmp_path / 'a', tmp_path / 'b'
    write_command_bag(a, [1, 2], [0.0, 0.1])
    write_command_bag(b, [1, 2], [0.0, math.nextafter(0.1, 1.0)])
    assert fingerprint(a) != fingerprint(b)


# --------------------------------------------------------------------------- valid rosbag2 for Jazzy

@pytest.mark.parametrize('bag', BAGS, ids=_ids(BAGS))
def test_metadata_is_rosbag2_v9_with_real_qos(bag: Path) -> None:
    info = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert info['version'] == 9
    store = storage_file(bag)
    assert info['storage_identifier'] == {'.mcap': 'mcap', '.db3': 'sqlite3'}[store.suffix]
    assert info['relative_file_paths'] == [store.name]
    [topic] = info['topics_with_message_count']
    meta = topic['topic_metadata']
    assert meta['name'] == COMMAND_TOPIC and meta['type'] == FLOAT64
    assert meta['serialization_format'] == 'cdr'
    assert meta['type_description_hash'] == jazzy_typestore().hash_rihs01(FLOAT64)
    # v9 QoS: a list of mappings with rmw's string names (what rosbag2 Jazzy writes and parses).
    [qos] = meta['offered_qos_profiles']
    assert qos['reliability'] == 'reliable' and qos['durability'] == 'volatile'
    assert qos['history'] == 'unknown' and qos['depth'] == 0 and qos['liveliness'] == 'automatic'
    infinite = {'sec': 9223372036, 'nsec': 854775807}
    assert qos['deadline'] == qos['lifespan'] == qos['liveliness_lease_duration'] == infinite
    assert topic['message_count'] == info['message_count'] == len(read_commands(bag))


@pytest.mark.parametrize('bag', [b for b in BAGS if storage_file(b).suffix == '.mcap'],
                         ids=_ids([b for b in BAGS if storage_file(b).suffix == '.mcap']))
def test_mcap_bags_read_back_with_the_mcap_package(bag: Path) -> None:
    from mcap.reader import make_reader

    with storage_file(bag).open('rb') as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    [schema] = summary.schemas.values()
    assert (schema.name, schema.encoding, schema.data) == (FLOAT64, 'ros2msg', b'float64 data\n')
    [channel] = summary.channels.values()
    assert channel.topic == COMMAND_TOPIC and channel.message_encoding == 'cdr'
    offered = yaml.safe_load(channel.metadata['offered_qos_profiles'])
    assert offered[0]['reliability'] == 'reliable'
    decoded = read_with_mcap(bag)[COMMAND_TOPIC]
    stream = read_commands(bag)
    assert [t for t, _ in decoded] == list(stream.stamps_ns)
    assert all(_same_float(m.data, v) for (_, m), v in zip(decoded, stream.values, strict=True))


@pytest.mark.parametrize('bag', [b for b in BAGS if storage_file(b).suffix == '.db3'],
                         ids=_ids([b for b in BAGS if storage_file(b).suffix == '.db3']))
def test_sqlite_bags_read_back_with_sqlite3(bag: Path) -> None:
    con = sqlite3.connect(f'file:{storage_file(bag)}?mode=ro', uri=True)
    try:
        assert con.execute('SELECT schema_version FROM schema').fetchone()[0] == 4
        assert con.execute('SELECT metadata_version FROM metadata').fetchone()[0] == 9
        [(name, typ, fmt, qos)] = con.execute(
            'SELECT name, type, serialization_format, offered_qos_profiles FROM topics').fetchall()
        assert (name, typ, fmt) == (COMMAND_TOPIC, FLOAT64, 'cdr')
        assert yaml.safe_load(qos)[0]['durability'] == 'volatile'
        [(encoding, text)] = con.execute(
            'SELECT encoding, encoded_message_definition FROM message_definitions').fetchall()
        assert (encoding, text) == ('ros2msg', 'float64 data\n')
        rows = con.execute('SELECT timestamp, data FROM messages ORDER BY timestamp, id').fetchall()
    finally:
        con.close()
    stream = read_commands(bag)
    # CDR little endian: 4-byte encapsulation header 00 01 00 00, then the float64.
    assert all(bytes(d)[:4] == b'\x00\x01\x00\x00' for _, d in rows)
    assert [t for t, _ in rows] == list(stream.stamps_ns)
    assert all(_same_float(struct.unpack_from('<d', bytes(d), 4)[0], v)
               for (_, d), v in zip(rows, stream.values, strict=True))


# --------------------------------------------------------------------------- the bags are what they claim

@pytest.fixture(scope='module')
def cfg() -> AntennaConfig:
    return load_config(CONFIG)


def _values(kind: str) -> list[float]:
    return list(read_commands(BAG_DIR / f'{kind}_mcap').values)


def test_sweep_covers_the_tilt_range_slowly(cfg: AntennaConfig) -> None:
    stream = read_commands(BAG_DIR / 'sweep_mcap')
    v = list(stream.values)
    top = v.index(max(v))
    assert v[0] == v[-1] == cfg.theta_min and v[top] == cfg.theta_max  # exactly the limits
    assert all(b > a for a, b in itertools.pairwise(v[:top + 1]))
    assert all(b < a for a, b in itertools.pairwise(v[top:]))
    speeds = [abs(b - a) / ((tb - ta) * 1e-9) for a, b, ta, tb in
              zip(v, v[1:], stream.stamps_ns, stream.stamps_ns[1:], strict=False)]
    assert max(speeds) < math.radians(1.0)  # slower than 1 deg/s


def test_steps_hold_levels(cfg: AntennaConfig) -> None:
    v = _values('steps')
    repeats = sum(1 for a, b in itertools.pairwise(v) if a == b)
    jumps = [abs(b - a) for a, b in itertools.pairwise(v) if a != b]
    assert repeats >= len(v) // 2 and len(jumps) >= 5
    assert max(jumps) >= 0.9 * (cfg.theta_max - cfg.theta_min)
    assert all(cfg.theta_min <= x <= cfg.theta_max for x in v)


def test_fast_ramp_is_faster_than_an_actuator(cfg: AntennaConfig) -> None:
    stream = read_commands(BAG_DIR / 'fast_ramp_mcap')
    v, t = stream.values, stream.stamps_ns
    speed = max(abs(b - a) / ((tb - ta) * 1e-9) for a, b, ta, tb in zip(v, v[1:], t, t[1:], strict=False))
    assert speed > math.radians(50.0)
    assert min(v) == cfg.theta_min and max(v) == cfg.theta_max


def test_jitter_is_noisy_jittered_and_valid(cfg: AntennaConfig) -> None:
    stream = read_commands(BAG_DIR / 'jitter_mcap')
    gaps = [b - a for a, b in zip(stream.stamps_ns, stream.stamps_ns[1:], strict=False)]
    assert min(gaps) > 0 and len(set(gaps)) > len(gaps) // 2
    v = stream.values
    assert all(cfg.theta_min <= x <= cfg.theta_max for x in v)
    sign_changes = sum(1 for a, b, c in zip(v, v[1:], v[2:], strict=False) if (b - a) * (c - b) < 0)
    assert sign_changes > len(v) // 4  # noise, not a smooth curve


def test_bad_values_cover_every_kind_of_bad_command(cfg: AntennaConfig) -> None:
    v = _values('bad_values')
    reach = cfg.linkage.reach()

    def good(x: float) -> bool:
        return math.isfinite(x) and cfg.theta_min <= x <= cfg.theta_max
    assert any(math.isnan(x) and math.copysign(1.0, x) > 0 for x in v)
    assert any(math.isnan(x) and math.copysign(1.0, x) < 0 for x in v)
    assert math.inf in v and -math.inf in v
    assert math.nextafter(cfg.theta_max, math.inf) in v and math.nextafter(cfg.theta_min, -math.inf) in v
    assert cfg.theta_min in v and cfg.theta_max in v
    assert any(math.isfinite(x) and not reach.contains(x) for x in v)  # beyond the linkage's reach
    assert any(math.isfinite(x) and reach.contains(x) and not good(x) for x in v)  # reachable, outside limits
    assert good(v[-1])
    assert all(good(b) for a, b in itertools.pairwise(v) if not good(a))  # each bad one is followed by a good one


# --------------------------------------------------------------------------- bad bags: one line, status 2

def _copy(bag: str, dst: Path) -> Path:
    shutil.copytree(BAG_DIR / bag, dst)
    return dst


def _truncate(path: Path, keep: float) -> None:
    data = path.read_bytes()
    path.write_bytes(data[:int(len(data) * keep)])


def _bad_missing(tmp: Path) -> Path:
    return tmp / 'nope'


def _bad_no_metadata(tmp: Path) -> Path:
    bag = _copy('sweep_mcap', tmp / 'bag')
    (bag / 'metadata.yaml').unlink()
    return bag


def _bad_empty_dir(tmp: Path) -> Path:
    (tmp / 'bag').mkdir()
    return tmp / 'bag'


def _bad_truncated_mcap(tmp: Path) -> Path:
    bag = _copy('sweep_mcap', tmp / 'bag')
    _truncate(storage_file(bag), 0.5)
    return bag


def _bad_truncated_db3(tmp: Path) -> Path:
    bag = _copy('sweep_sqlite3', tmp / 'bag')
    _truncate(storage_file(bag), 0.3)
    return bag


def _bad_garbage_db3(tmp: Path) -> Path:
    bag = _copy('steps_sqlite3', tmp / 'bag')
    storage_file(bag).write_bytes(b'not a database at all ' * 100)
    return bag


def _bad_garbage_mcap(tmp: Path) -> Path:
    bag = _copy('steps_mcap', tmp / 'bag')
    storage_file(bag).write_bytes(bytes(range(256)) * 8)
    return bag


def _bad_metadata_yaml(tmp: Path) -> Path:
    bag = _copy('steps_mcap', tmp / 'bag')
    (bag / 'metadata.yaml').write_text('rosbag2_bagfile_information: [unclosed\n  : :')
    return bag


def _bad_metadata_keys(tmp: Path) -> Path:
    bag = _copy('steps_mcap', tmp / 'bag')
    (bag / 'metadata.yaml').write_text('rosbag2_bagfile_information:\n  version: 9\n')
    return bag


def _bad_missing_storage_file(tmp: Path) -> Path:
    bag = _copy('steps_sqlite3', tmp / 'bag')
    storage_file(bag).unlink()
    return bag


def _other_topic_bag(path: Path, topic: str, msgtype: str, data: bytes) -> Path:
    with AtomicBagWriter(path, Storage.MCAP) as bag:
        conn = bag.add_topic(topic, msgtype, [recorded_qos()])
        bag.write(conn, 1, data)
    return path


def _bad_no_command_topic(tmp: Path) -> Path:
    return _other_topic_bag(tmp / 'bag', '/other_cmd', FLOAT64, float64_cdr(0.0))


def _bad_wrong_type(tmp: Path) -> Path:
    store = jazzy_typestore()
    data = bytes(store.serialize_cdr(store.types['std_msgs/msg/String'](data='0.1'), 'std_msgs/msg/String'))
    return _other_topic_bag(tmp / 'bag', COMMAND_TOPIC, 'std_msgs/msg/String', data)


def _bad_empty_topic(tmp: Path) -> Path:
    with AtomicBagWriter(tmp / 'bag', Storage.SQLITE3) as bag:
        bag.add_topic(COMMAND_TOPIC, FLOAT64, [recorded_qos()])
    return tmp / 'bag'


def _bad_cdr(tmp: Path) -> Path:
    return _other_topic_bag(tmp / 'bag', COMMAND_TOPIC, FLOAT64, b'\x00\x01\x00\x00\x01\x02')


BAD_BAGS = {
    'missing': (_bad_missing, 'no such bag'),
    'empty_dir': (_bad_empty_dir, 'no metadata.yaml'),
    'no_metadata': (_bad_no_metadata, 'no metadata.yaml'),
    'truncated_mcap': (_bad_truncated_mcap, 'unreadable bag'),
    'truncated_db3': (_bad_truncated_db3, 'unreadable bag'),
    'garbage_db3': (_bad_garbage_db3, 'unreadable bag'),
    'garbage_mcap': (_bad_garbage_mcap, 'unreadable bag'),
    'metadata_not_yaml': (_bad_metadata_yaml, 'unreadable bag'),
    'metadata_keys_missing': (_bad_metadata_keys, 'unreadable bag'),
    'storage_file_missing': (_bad_missing_storage_file, 'unreadable bag'),
    'no_command_topic': (_bad_no_command_topic, 'no command topic /antenna_angle_cmd (topics: /other_cmd'),
    'wrong_type': (_bad_wrong_type, 'has type std_msgs/msg/String, expected std_msgs/msg/Float64'),
    'empty_topic': (_bad_empty_topic, 'has no messages'),
    'bad_cdr': (_bad_cdr, 'message 0 on /antenna_angle_cmd is not a valid std_msgs/msg/Float64'),
}


def _listing(root: Path) -> list[str]:
    return sorted(str(p.relative_to(root)) for p in root.rglob('*'))


@pytest.mark.parametrize('case', list(BAD_BAGS))
def test_bad_bag_is_one_line_error(case: str, tmp_path: Path) -> None:
    make, words = BAD_BAGS[case]
    bag = make(tmp_path)
    with pytest.raises(BagError) as err:
        read_commands(bag)
    message = str(err.value)
    assert words in message and '\n' not in message and str(bag) in message


@pytest.mark.parametrize('case', list(BAD_BAGS))
def test_replay_cli_rejects_bad_bag(case: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    make, words = BAD_BAGS[case]
    bag = make(tmp_path)
    before = _listing(tmp_path)
    assert cli_main(['replay', str(bag), '--as-fast-as-node-keeps-up']) == 2
    out, err = capsys.readouterr()
    assert out == ''
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith('fourbar replay: error: ') and words in lines[0]
    assert _listing(tmp_path) == before  # nothing written, nothing changed


def test_replay_console_script_exit_status(tmp_path: Path) -> None:
    """The installed console script, as a user runs it: status 2 and one line."""
    script = Path(sys.executable).parent / 'fourbar'
    result = subprocess.run([str(script), 'replay', str(tmp_path / 'missing')], capture_output=True, text=True,
                            timeout=60, check=False)
    assert result.returncode == 2
    assert result.stderr.splitlines() == [f'fourbar replay: error: {tmp_path / "missing"}: no such bag']


def test_bare_storage_files_are_accepted() -> None:
    """rosbags (like ros2 bag) also opens a single .mcap or .db3 file."""
    for name in ('steps_mcap', 'steps_sqlite3'):
        assert read_commands(storage_file(BAG_DIR / name)).values == read_commands(BAG_DIR / name).values


# --------------------------------------------------------------------------- atomic writes

def test_atomic_writer_leaves_nothing_on_error(tmp_path: Path) -> None:
    out = tmp_path / 'out'
    with pytest.raises(RuntimeError), AtomicBagWriter(out, Storage.MCAP) as bag:
        conn = bag.add_topic(COMMAND_TOPIC, FLOAT64, [recorded_qos()])
        bag.write(conn, 1, float64_cdr(0.0))
        raise RuntimeError('boom')
    assert _listing(tmp_path) == []


@pytest.mark.parametrize('storage', list(Storage))
def test_atomic_writer_leaves_nothing_on_ctrl_c(tmp_path: Path, storage: str) -> None:
    out = tmp_path / 'out'
    with pytest.raises(KeyboardInterrupt), AtomicBagWriter(out, storage) as bag:
        conn = bag.add_topic(COMMAND_TOPIC, FLOAT64, [recorded_qos()])
        for i in range(100):
            bag.write(conn, i, float64_cdr(i * 1e-3))
        assert _listing(tmp_path) != []  # being written, under a hidden name
        assert not out.exists()
        raise KeyboardInterrupt
    assert _listing(tmp_path) == []


@pytest.mark.parametrize('call', ['mkdir', 'rename'])
def test_atomic_writer_leaves_nothing_on_ctrl_c_just_after(call: str, tmp_path: Path,
                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    """A stop raised the moment the hidden directory exists (where a signal sent on seeing it lands), or the moment
    the finished bag is renamed into place: nothing is left, as for a stop anywhere else."""
    real = getattr(os, call)

    def call_then_interrupt(*args: Any, **kw: Any) -> None:
        real(*args, **kw)
        raise KeyboardInterrupt

    writer = AtomicBagWriter(tmp_path / 'out', Storage.MCAP)
    monkeypatch.setattr(os, call, call_then_interrupt)
    with pytest.raises(KeyboardInterrupt), writer:
        pass
    monkeypatch.undo()
    assert _listing(tmp_path) == []


def test_atomic_writer_publishes_only_complete_bags(tmp_path: Path) -> None:
    out = tmp_path / 'out'
    path = write_command_bag(out, [10, 20, 30], [0.0, math.nan, -0.05], Storage.SQLITE3)
    assert path == out and _listing(tmp_path) == sorted(['out', 'out/metadata.yaml', 'out/out.db3'])
    stream = read_commands(out)
    assert stream.stamps_ns == (10, 20, 30) and math.isnan(stream.values[1])


def test_atomic_writer_refuses_bad_targets(tmp_path: Path) -> None:
    (tmp_path / 'exists').mkdir()
    with pytest.raises(BagError, match='exists already'):
        AtomicBagWriter(tmp_path / 'exists')
    with pytest.raises(BagError, match='does not exist'):
        AtomicBagWriter(tmp_path / 'no' / 'parent')
    with pytest.raises(BagError, match='stamps must not decrease'):
        write_command_bag(tmp_path / 'y', [2, 1], [0.0, 0.0])
    assert _listing(tmp_path) == ['exists']


@pytest.mark.parametrize('args, words', [
    (['EXISTS'], 'exists already, not overwriting'),
    (['MISSING/out'], 'does not exist'),
    (['NEW', '--stop-after', 'joint_states'], '--stop-after wants TOPIC=N'),
    (['NEW', '--stop-after', 'joint_states=0'], '--stop-after wants TOPIC=N'),
    (['NEW', '--wait', '0'], 'must be positive'),
    (['NEW', '--flush-interval', '0'], '--flush-interval must be a positive number of seconds'),
    (['NEW', '--flush-interval', 'nan'], '--flush-interval must be a positive number of seconds'),
])
def test_record_cli_bad_input(args: list[str], words: str, tmp_path: Path,
                              capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / 'EXISTS').mkdir()
    (tmp_path / 'EXISTS' / 'keep').write_text('untouched')
    before = _listing(tmp_path)
    argv = ['record', *[str(tmp_path / a) if a.isupper() or '/' in a else a for a in args]]
    assert cli_main(argv) == 2
    out, err = capsys.readouterr()
    lines = err.splitlines()
    assert out == '' and len(lines) == 1 and lines[0].startswith('fourbar record: error: ') and words in lines[0]
    assert _listing(tmp_path) == before
    assert (tmp_path / 'EXISTS' / 'keep').read_text() == 'untouched'


@pytest.mark.parametrize('args, words', [
    (['--clock', '--as-fast-as-node-keeps-up'], '--clock works with timed replay'),
    (['--clock', '0'], '--clock must be a positive rate in Hz, got 0.0'),
    (['--clock', 'inf'], '--clock must be a positive rate in Hz, got inf'),
])
def test_replay_cli_bad_clock(args: list[str], words: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert cli_main(['replay', str(BAG_DIR / 'sweep_mcap'), *args]) == 2
    out, err = capsys.readouterr()
    assert out == '' and len(err.splitlines()) == 1 and err.startswith('fourbar replay: error: ') and words in err


def test_progress_bar_draws_only_on_a_terminal() -> None:
    import io

    from fourbar_ros.live.progress import Progress

    quiet = io.StringIO()  # not a TTY: silent by default
    bar = Progress(10, 'replay', stream=quiet)
    bar.update(5, force=True)
    bar.end()
    assert quiet.getvalue() == ''
    shown = io.StringIO()
    bar = Progress(10, 'replay', stream=shown, enabled=True)
    bar.update(5, force=True)
    bar.update(10)  # throttled: not drawn yet
    bar.end()  # draws the last state and ends the line
    text = shown.getvalue()
    assert text.count('\r') == 2 and text.endswith('\n')
    assert 'replay [' + '#' * 15 + '.' * 15 + '] 5/10' in text and '10/10' in text.splitlines()[-1]
