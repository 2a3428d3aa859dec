"""`fourbar process` on a bag of measured joint states: the complete joint_states and the other outputs written in
the measured topic's namespace at the measurements' log times and stamps, through the completion rule's block path
(exactly its floats); bad measurements skipped and counted; the measured topics `--help` names taken, and one of
another type refused in one line naming its type; `fourbar compare` covering the new outputs (and ignoring them
when told). No ROS middleware (bags written with rosbags' serializer)."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from fourbar_ros.bags.storage import AtomicBagWriter, float64_cdr, jazzy_typestore, open_bag, read_messages
from fourbar_ros.commands import main
from fourbar_ros.config.antenna_config import default_config
from fourbar_ros.rules.completion import CompletionRule, complete_block

CFG = default_config()
RULE = CompletionRule(CFG)
DRIVEN = CFG.driven_joint
STORE = jazzy_typestore()
JS = 'sensor_msgs/msg/JointState'


def joint_state(names: list[str], position: list[float], velocity: list[float], effort: list[float],
                sec: int) -> bytes:
    t = STORE.types
    msg = t[JS](header=t['std_msgs/msg/Header'](stamp=t['builtin_interfaces/msg/Time'](sec=sec, nanosec=5),
                                                frame_id=''),
                name=names, position=np.array(position), velocity=np.array(velocity), effort=np.array(effort))
    return bytes(STORE.serialize_cdr(msg, JS))


GOOD = [(0.2 + 0.02 * i, [0.1 * i] if i % 3 else [], [0.01 * i] if i % 2 else []) for i in range(12)]


def measured_bag(path: Path, topic: str = '/measured_joint_states') -> Path:
    with AtomicBagWriter(path) as bag:
        conn = bag.add_topic(topic, JS)
        sec = 0
        for q, v, e in GOOD:
            sec += 1
            bag.write(conn, sec * 10**9, joint_state([DRIVEN], [q], v, e, sec))
        for names, p, v, e in ([['elbow'], [0.3], [], []],  # no driven joint
                               [RULE.names, [0.3, 0.4, 0.5], [], []],  # the node's own complete state
                               [[DRIVEN], [0.3], [0.1, 0.2], []],  # mismatched lengths
                               [[DRIVEN], [math.nan], [], []], [[DRIVEN], [0.3], [math.inf], []],  # not finite
                               [[DRIVEN], [3.0], [], []]):  # out of the rocker's range
            sec += 1
            bag.write(conn, sec * 10**9, joint_state(names, p, v, e, sec))
    return path


def test_a_measured_bag_is_completed_by_the_block_rule(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = measured_bag(tmp_path / 'measured')
    assert main(['process', str(src), str(tmp_path / 'out')]) == 0
    line = capsys.readouterr().err
    assert '18 measured joint states -> 12 completed (1 out of range, 2 not finite, 3 ignored, 0 malformed)' in line
    out = read_messages(tmp_path / 'out')
    q = np.array([g[0] for g in GOOD])
    q_dot = np.array([g[1][0] if g[1] else math.nan for g in GOOD])
    effort = np.array([g[2][0] if g[2] else math.nan for g in GOOD])
    block = complete_block(CFG, q, q_dot, effort)
    js = out['/joint_states']
    assert [log for log, _ in js] == [(i + 1) * 10**9 for i in range(12)]
    assert [(m.header.stamp.sec, m.header.stamp.nanosec) for _, m in js] == [(i + 1, 5) for i in range(12)]
    for k, (_, m) in enumerate(js):
        assert list(m.name) == RULE.names == [DRIVEN, CFG.delta_joint, CFG.coupler_joint]
        assert m.position.tolist() == block.positions[k].tolist() and m.position[0] == q[k]
        assert m.effort.tolist() == ([] if math.isnan(effort[k]) else [effort[k], 0.0, 0.0])
        assert m.velocity.tolist() == ([] if math.isnan(q_dot[k]) else block.velocities[k].tolist())
    assert [m.data for _, m in out['/antenna_angle']] == block.theta.tolist()
    assert [m.data for _, m in out['/antenna_rate']] == block.theta_rate[np.isfinite(q_dot)].tolist()
    assert [m.data for _, m in out['/load_torque']] == block.load_torque[np.isfinite(effort)].tolist()


def test_a_nan_velocity_or_effort_is_not_measured(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # joint_state_broadcaster's NaN for a missing state interface: completed without that value; inf refused.
    nan, inf = math.nan, math.inf
    sent = [(0.30, nan, 0.02), (0.31, 0.1, nan), (0.32, nan, nan), (0.33, 0.2, 0.03), (0.34, inf, 0.0),
            (0.35, 0.0, -inf)]
    with AtomicBagWriter(tmp_path / 'measured') as bag:
        conn = bag.add_topic('/joint_state_broadcaster/joint_states', JS)  # joint_state_broadcaster's local topic
        for k, (q, v, e) in enumerate(sent):
            bag.write(conn, (k + 1) * 10**9, joint_state([DRIVEN, 'other'], [q, 1.0], [v, 0.0], [e, 0.0], k + 1))
    assert main(['process', str(tmp_path / 'measured'), str(tmp_path / 'out')]) == 0
    assert '6 measured joint states -> 4 completed (0 out of range, 2 not finite, 0 ignored, 0 malformed)' in \
        capsys.readouterr().err
    out = read_messages(tmp_path / 'out')
    good = sent[:4]
    block = complete_block(CFG, np.array([g[0] for g in good]), np.array([g[1] for g in good]),
                           np.array([g[2] for g in good]))
    js = [m for _, m in out['/joint_states']]
    assert [m.header.stamp.sec for m in js] == [1, 2, 3, 4]
    for k, m in enumerate(js):
        assert m.position.tolist() == block.positions[k].tolist()
        assert m.velocity.tolist() == ([] if math.isnan(good[k][1]) else block.velocities[k].tolist())
    assert [m.data for _, m in out['/antenna_angle']] == block.theta.tolist()
    assert [log for log, _ in out['/antenna_rate']] == [2 * 10**9, 4 * 10**9]
    assert [m.data for _, m in out['/antenna_rate']] == block.theta_rate[[1, 3]].tolist()
    assert [log for log, _ in out['/load_torque']] == [1 * 10**9, 4 * 10**9]
    assert [m.data for _, m in out['/load_torque']] == block.load_torque[[0, 3]].tolist()


def test_compare_covers_the_completion_outputs(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = measured_bag(tmp_path / 'measured')
    assert main(['process', str(src), str(tmp_path / 'a')]) == 0
    assert main(['compare', str(tmp_path / 'a'), str(tmp_path / 'a')]) == 0
    # B: the same with one load torque off by 1e-6 N m.
    with AtomicBagWriter(tmp_path / 'b') as bag, open_bag(tmp_path / 'a') as reader:
        conns = {c.topic: bag.add_topic(c.topic, c.msgtype) for c in reader.connections}
        for c, log, data in reader.messages():
            raw = bytes(data)
            if c.topic == '/load_torque' and log == 4 * 10**9:
                raw = bytes(STORE.serialize_cdr(STORE.types['std_msgs/msg/Float64'](
                    data=STORE.deserialize_cdr(raw, c.msgtype).data + 1e-6), c.msgtype))
            bag.write(conns[c.topic], log, raw)
    capsys.readouterr()
    assert main(['compare', str(tmp_path / 'a'), str(tmp_path / 'b')]) == 1
    assert '/load_torque message 1: data' in capsys.readouterr().out
    assert main(['compare', str(tmp_path / 'a'), str(tmp_path / 'b'), '--ignore', 'load_torque']) == 0


def test_a_namespaced_measured_topic_and_a_bag_without_one(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = measured_bag(tmp_path / 'measured', '/robot/joint_state_broadcaster/joint_states')
    assert main(['process', str(src), str(tmp_path / 'out')]) == 0
    assert set(read_messages(tmp_path / 'out')) == {'/robot/joint_states', '/robot/antenna_angle',
                                                    '/robot/antenna_rate', '/robot/load_torque'}
    with AtomicBagWriter(tmp_path / 'other') as bag:
        bag.write(bag.add_topic('/elsewhere', JS), 1, joint_state([DRIVEN], [0.3], [], [], 1))
    capsys.readouterr()
    assert main(['process', str(tmp_path / 'other'), str(tmp_path / 'out2')]) == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1
    assert not (tmp_path / 'out2').exists()


def test_a_measured_topic_where_the_completed_states_go_is_refused(tmp_path: Path,
                                                                   capsys: pytest.CaptureFixture[str]) -> None:
    # A measured topic named joint_states would be overwritten by the complete ones: one line, nothing written.
    with AtomicBagWriter(tmp_path / 'measured') as bag:
        bag.write(bag.add_topic('/joint_states', JS), 1, joint_state([DRIVEN], [0.3], [], [], 1))
    assert main(['process', str(tmp_path / 'measured'), str(tmp_path / 'out'), '--topic', '/joint_states']) == 2
    assert 'measured_joint_states' in capsys.readouterr().err and not (tmp_path / 'out').exists()


def _help_defaults(capsys: pytest.CaptureFixture[str]) -> list[str]:
    """The JointState topics `fourbar process --help` names as --topic's defaults ('/name', and '*/name' as
    '/robot/name')."""
    with pytest.raises(SystemExit) as info:
        main(['process', '--help'])
    assert info.value.code == 0
    text = ' '.join(capsys.readouterr().out.split())
    defaults = re.finditer(r'default:? (/[\w/]+(?:, else /[\w/]+)*)(?:, else the one (\*/[\w/]+(?: or \*/[\w/]+)*))?',
                           text)
    named = [t for m in defaults for t in re.findall(r'\*?/[\w/]+', f'{m[1]} {m[2] or ""}')]
    return [t.replace('*', '/robot') for t in named if 'joint_states' in t]


def test_the_measured_topics_the_help_names_are_taken(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # The help and the choice of the measured topic come from the same constants: each name the help gives as a
    # default is processed.
    topics = _help_defaults(capsys)
    assert topics
    for i, topic in enumerate(topics):
        with AtomicBagWriter(tmp_path / f'in{i}') as bag:
            bag.write(bag.add_topic(topic, JS), 1, joint_state([DRIVEN], [0.3], [], [], 1))
        assert main(['process', str(tmp_path / f'in{i}'), str(tmp_path / f'out{i}')]) == 0, (
            topic, capsys.readouterr().err)
        ns = '/robot' if topic.startswith('/robot/') else ''
        assert f'{ns}/joint_states' in read_messages(tmp_path / f'out{i}')


@pytest.mark.parametrize(('topic', 'msgtype', 'given', 'message'), [
    ('/measured_joint_states', 'std_msgs/msg/Float64', False,
     f'the measured topic /measured_joint_states has type std_msgs/msg/Float64, expected {JS}'),
    ('/measured_joint_states', 'std_msgs/msg/Float64', True,
     f'the measured topic /measured_joint_states has type std_msgs/msg/Float64, expected {JS}'),
    ('/robot/joint_state_broadcaster/joint_states', 'std_msgs/msg/Float64', False,
     f'the measured topic /robot/joint_state_broadcaster/joint_states has type std_msgs/msg/Float64, expected {JS}'),
    ('/tilt', 'std_msgs/msg/Bool', True,
     f'topic /tilt has type std_msgs/msg/Bool, expected std_msgs/msg/Float64 or {JS} or '
     'trajectory_msgs/msg/JointTrajectory'),
])
def test_a_measured_topic_of_another_type_is_named_with_its_type(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                                  topic: str, msgtype: str, given: bool,
                                                                  message: str) -> None:
    store = jazzy_typestore()
    data = float64_cdr(0.3) if msgtype.endswith('Float64') else bytes(
        store.serialize_cdr(store.types[msgtype](data=True), msgtype))
    with AtomicBagWriter(tmp_path / 'measured') as bag:
        bag.write(bag.add_topic(topic, msgtype), 1, data)
    argv = ['process', str(tmp_path / 'measured'), str(tmp_path / 'out'), *(['--topic', topic] if given else [])]
    assert main(argv) == 2
    assert capsys.readouterr().err == f'fourbar process: error: {tmp_path / "measured"}: {message}\n'
    assert not (tmp_path / 'out').exists()


def test_malformed_payloads_are_counted_as_the_node_counts_them(tmp_path: Path,
                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    # The node's decoder and rules: a truncated payload and a big-endian one are counted and skipped, the
    # measurement after them completed (the node goes on the same way), instead of the whole bag refused.
    good = joint_state([DRIVEN], [0.3], [], [], 1)
    with AtomicBagWriter(tmp_path / 'measured') as bag:
        conn = bag.add_topic('/measured_joint_states', JS)
        bag.write(conn, 1, good[:20])
        bag.write(conn, 2, good[:1] + b'\x00' + good[2:])
        bag.write(conn, 3, good)
    assert main(['process', str(tmp_path / 'measured'), str(tmp_path / 'out')]) == 0
    assert '3 measured joint states -> 1 completed (0 out of range, 0 not finite, 0 ignored, 2 malformed)' in \
        capsys.readouterr().err
    assert len(read_messages(tmp_path / 'out')['/joint_states']) == 1
