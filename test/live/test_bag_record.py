"""`fourbar record` against the real node (separate processes, leased ROS_DOMAIN_ID): Ctrl-C and SIGTERM
leave a complete bag that rosbags and mcap read, with the graph's QoS and type hashes; SIGKILL leaves no
bag at OUT; no publisher is a one-line error with nothing written."""

from __future__ import annotations

import signal
from pathlib import Path

import pytest
import yaml
from diagnostic_msgs.msg import DiagnosticArray
from support.bag_support import CONFIG, Tool, read_with_mcap, read_with_sqlite, run_tool, storage_file
from support.ros_support import NodeProcess, RosSession, wait_for

from fourbar_ros.bags.storage import fingerprint, jazzy_typestore, read_messages
from fourbar_ros.interface.topics import Storage

pytestmark = [pytest.mark.ros, pytest.mark.slow]

# Diagnostics every 50 ms, so messages flow without commands.
NODE_ARGS = ['--ros-args', '--params-file', str(CONFIG), '-p', 'diagnostics_period:=0.05']


def _listing(root: Path) -> list[str]:
    return sorted(str(p.relative_to(root)) for p in root.rglob('*'))


def _record_until_signal(ros: RosSession, out: Path, storage: Storage, sig: int) -> tuple[int, list[str]]:
    diagnostics = ros.collect(DiagnosticArray, '/diagnostics', qos=100)
    try:
        with NodeProcess(NODE_ARGS, ros.env()), \
                Tool(['record', out, '--storage', storage], ros.env()) as recorder:
            recorder.wait_line('recording')
            start = len(diagnostics)
            diagnostics.wait_count(start + 5)  # the node keeps publishing after the recorder is ready
            assert not out.exists()  # nothing at OUT while recording
            recorder.signal(sig)
            return recorder.wait(), recorder.lines
    finally:
        ros.uncollect(diagnostics)


@pytest.mark.parametrize('storage, sig', [(Storage.MCAP, signal.SIGINT), (Storage.SQLITE3, signal.SIGINT),
                                          (Storage.MCAP, signal.SIGTERM)],
                         ids=['mcap-SIGINT', 'sqlite3-SIGINT', 'mcap-SIGTERM'])
def test_stop_by_signal_leaves_a_complete_bag(storage: Storage, sig: int, ros: RosSession, tmp_path: Path) -> None:
    out = tmp_path / 'rec'
    rc, lines = _record_until_signal(ros, out, storage, sig)
    assert rc == 0, lines
    assert lines[-1].startswith(f'fourbar record: wrote {out}: ')
    assert _listing(tmp_path) == sorted(['rec', 'rec/metadata.yaml', f'rec/{storage_file(out).name}'])
    recorded = read_messages(out)
    diag = recorded['/diagnostics']
    assert len(diag) >= 1 and all(m.status for _, m in diag)
    assert recorded['/joint_states'] == [] and recorded['/input_torque'] == []  # no commands were sent
    other = read_with_mcap(out) if storage is Storage.MCAP else read_with_sqlite(out)
    assert [t for t, _ in other['/diagnostics']] == [t for t, _ in diag]
    assert [m.status[0].message for _, m in other['/diagnostics']] == [m.status[0].message for _, m in diag]

    info = yaml.safe_load((out / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert info['version'] == 9 and info['storage_identifier'] == storage.value
    assert info['message_count'] == len(diag)
    topics = {t['topic_metadata']['name']: t for t in info['topics_with_message_count']}
    assert set(topics) == {'/joint_states', '/input_torque', '/diagnostics'}
    store = jazzy_typestore()
    for name, topic in topics.items():
        meta = topic['topic_metadata']
        assert meta['type_description_hash'] == store.hash_rihs01(meta['type']), name
        [qos] = meta['offered_qos_profiles']  # one publisher each, as the graph reported it
        assert qos['reliability'] == 'reliable' and qos['durability'] == 'volatile', name
        assert qos['history'] == 'unknown' and qos['deadline'] == {'sec': 9223372036, 'nsec': 854775807}, name
    assert fingerprint(out)['topics']['/diagnostics'][0] == 'diagnostic_msgs/msg/DiagnosticArray'


def test_recorded_hashes_match_the_live_graph(ros: RosSession, tmp_path: Path) -> None:
    """The stored type hash is the one the node's publishers announce (rclpy's TopicEndpointInfo)."""
    out = tmp_path / 'rec'
    with NodeProcess(NODE_ARGS, ros.env()), Tool(['record', out], ros.env()) as recorder:
        recorder.wait_line('recording')
        live = {}
        for topic in ('/joint_states', '/input_torque', '/diagnostics'):
            wait_for(lambda t=topic: bool(ros.node.get_publishers_info_by_topic(t)), what=f'publisher on {topic}')
            live[topic] = str(ros.node.get_publishers_info_by_topic(topic)[0].topic_type_hash)
        recorder.signal(signal.SIGINT)
        assert recorder.wait() == 0
    info = yaml.safe_load((out / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    stored = {t['topic_metadata']['name']: t['topic_metadata']['type_description_hash']
              for t in info['topics_with_message_count']}
    assert stored == live


def test_sigkill_leaves_no_bag_at_out(ros: RosSession, tmp_path: Path) -> None:
    out = tmp_path / 'rec'
    rc, _ = _record_until_signal(ros, out, Storage.MCAP, signal.SIGKILL)
    assert rc == -signal.SIGKILL
    assert not out.exists()
    # Only the hidden work directory remains; it never has the bag's name.
    assert all(name.startswith('.rec.') and name.split('/')[0].endswith('.partial') for name in _listing(tmp_path))


def test_duration_stops_by_itself(ros: RosSession, tmp_path: Path) -> None:
    out = tmp_path / 'rec'
    with NodeProcess(NODE_ARGS, ros.env()):
        rc, lines, _ = run_tool(['record', out, '--topics', '/diagnostics', '--duration', '0.5'], ros.env())
    assert rc == 0, lines
    assert list(read_messages(out)) == ['/diagnostics']


def test_no_publisher_is_a_one_line_error(ros: RosSession, tmp_path: Path) -> None:
    out = tmp_path / 'rec'
    rc, lines, stdout = run_tool(['record', out, '--topics', '/nobody_publishes_this', '--wait', '1'], ros.env())
    assert rc == 1 and stdout == ''
    assert lines == ['fourbar record: error: no publisher on /nobody_publishes_this within 1 s']
    assert _listing(tmp_path) == []
