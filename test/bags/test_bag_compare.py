"""`fourbar compare A B`: equal bags pass, any changed value, stamp, count or shape is caught (exit 1), bad input
is one line (exit 2); and a bag recorded from the live node equals `fourbar process` of the same commands."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from support.bag_support import BAG_DIR, CONFIG, Tool, run_main, run_tool, served
from support.ros_support import ONE_JOINT_STATE_PER_COMMAND, NodeProcess, RosSession

from fourbar_ros.bags.compare import compare_bags
from fourbar_ros.bags.process import process_bag
from fourbar_ros.bags.storage import AtomicBagWriter, jazzy_typestore, open_bag, read_commands
from fourbar_ros.config.antenna_config import AntennaConfig, config_from_values, load_config
from fourbar_ros.interface.topics import Storage

STORE = jazzy_typestore()


@pytest.fixture(scope='module')
def cfg() -> AntennaConfig:
    return load_config(CONFIG)


@pytest.fixture(scope='module')
def processed(cfg: AntennaConfig, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp('compare') / 'processed'
    process_bag(BAG_DIR / 'jitter_mcap', out, cfg)
    return out


def rewrite(src: Path, dst: Path, change: Callable[[str, int, Any], Any | None]) -> None:
    """Copy a bag, passing each decoded message to ``change(topic, index, msg)``: a message to write instead,
    the same message, or None to drop it. Untouched messages keep their bytes."""
    with open_bag(src) as reader, AtomicBagWriter(dst) as bag:
        conns = {c.id: bag.add_topic(c.topic, c.msgtype) for c in reader.connections}
        index: dict[str, int] = {}
        for conn, stamp, data in reader.messages():
            i = index[conn.topic] = index.get(conn.topic, -1) + 1
            msg = STORE.deserialize_cdr(bytes(data), conn.msgtype)
            new = change(conn.topic, i, msg)
            if new is None:
                continue
            raw = bytes(data) if new is msg else bytes(STORE.serialize_cdr(new, conn.msgtype))
            bag.write(conns[conn.id], stamp, raw)


def changed(topic: str, index: int, edit: Callable[[Any], None]) -> Callable[[str, int, Any], Any]:
    def change(t: str, i: int, msg: Any) -> Any:
        if t == topic and i == index:
            edit(msg)
            return STORE.deserialize_cdr(bytes(STORE.serialize_cdr(msg, STORE_TYPES[t])), STORE_TYPES[t])
        return msg
    return change


STORE_TYPES = {'/joint_states': 'sensor_msgs/msg/JointState', '/input_torque': 'std_msgs/msg/Float64'}


def test_a_bag_equals_itself_and_its_other_storage(processed: Path, cfg: AntennaConfig, tmp_path: Path) -> None:
    process_bag(BAG_DIR / 'jitter_mcap', tmp_path / 'sqlite', cfg, storage=Storage.SQLITE3)
    result = compare_bags(processed, tmp_path / 'sqlite', cfg)
    assert result.equal and result.compared == {'/joint_states': 300, '/input_torque': 300}
    rc, _, out = run_main(['compare', processed, processed, '--params', CONFIG])
    assert rc == 0 and 'equal' in out, out


def _set_position(msg: Any, value: float) -> None:
    msg.position = np.array([value, *msg.position[1:]])


CASES: dict[str, Callable[[str, int, Any], Any | None]] = {
    'position by 1e-12 rad': changed('/joint_states', 7, lambda m: _set_position(m, m.position[0] + 1e-12)),
    'velocity by 1e-9 rad/s': changed('/joint_states', 5, lambda m: setattr(
        m, 'velocity', np.array([m.velocity[0], m.velocity[1] + 1e-9]))),
    'velocity dropped': changed('/joint_states', 5, lambda m: setattr(m, 'velocity', np.array([], dtype=float))),
    'effort by 1e-12 N m': changed('/joint_states', 3, lambda m: setattr(
        m, 'effort', np.array([m.effort[0] + 1e-12, *m.effort[1:]]))),
    'input torque by 1e-12 N m': changed('/input_torque', 11, lambda m: setattr(m, 'data', m.data + 1e-12)),
    'header stamp by 1 ns': changed('/joint_states', 2, lambda m: setattr(m.header.stamp, 'nanosec',
                                                                          m.header.stamp.nanosec + 1)),
    'joint name': changed('/joint_states', 0, lambda m: setattr(m, 'name', ['rocker_ab_joint', 'x'])),
    'frame_id': changed('/joint_states', 0, lambda m: setattr(m.header, 'frame_id', 'base')),
    'a message missing': lambda t, i, m: None if (t, i) == ('/input_torque', 19) else m,
    'NaN for a value': changed('/input_torque', 4, lambda m: setattr(m, 'data', math.nan)),
}


@pytest.mark.parametrize('case', list(CASES))
def test_a_change_is_caught(case: str, processed: Path, cfg: AntennaConfig, tmp_path: Path) -> None:
    rewrite(processed, tmp_path / 'b', CASES[case])
    result = compare_bags(processed, tmp_path / 'b', cfg)
    assert not result.equal and result.differences, case
    rc, _, out = run_main(['compare', processed, tmp_path / 'b', '--params', CONFIG])
    assert rc == 1 and 'differences' in out.splitlines()[-1], out


def test_tolerance_in_ulps_of_the_scale(processed: Path, cfg: AntennaConfig, tmp_path: Path) -> None:
    """A position moved by k ulps of its scale |q| + pi (exact: that ulp is a multiple of q's own) passes
    --ulps N for k <= N and fails it for k > N; --atol likewise in rad."""
    def move(k: int) -> Callable[[str, int, Any], Any]:
        return changed('/joint_states', 7, lambda m: _set_position(
            m, m.position[0] + k * math.ulp(abs(m.position[0]) + math.pi)))
    rewrite(processed, tmp_path / 'b8', move(8))
    rewrite(processed, tmp_path / 'b32', move(32))
    assert compare_bags(processed, tmp_path / 'b8', cfg).equal  # default 16
    assert not compare_bags(processed, tmp_path / 'b8', cfg, ulps=7).equal
    assert not compare_bags(processed, tmp_path / 'b32', cfg).equal
    assert compare_bags(processed, tmp_path / 'b32', cfg, ulps=32).equal
    assert compare_bags(processed, tmp_path / 'b32', cfg, atol=1e-13).equal  # 32 ulps of ~5 rad: 2.8e-14 rad
    assert not compare_bags(processed, tmp_path / 'b32', cfg, atol=1e-14).equal


def test_blocks_change_nothing(processed: Path, cfg: AntennaConfig, tmp_path: Path) -> None:
    """Read in blocks of 7 (the velocity anchor and the torque's joint_states carried across blocks): the same
    verdicts, and a difference is reported at its index in the whole topic."""
    assert compare_bags(processed, processed, cfg, block=7).equal
    rewrite(processed, tmp_path / 'b', changed('/input_torque', 200, lambda m: setattr(m, 'data', m.data * 1.001)))
    for block in (7, 65536):
        result = compare_bags(processed, tmp_path / 'b', cfg, block=block)
        assert [(d.topic, d.index) for d in result.differences] == [('/input_torque', 200)], block
    rewrite(processed, tmp_path / 'short', lambda t, i, m: None if t == '/joint_states' and i >= 290 else m)
    for block in (7, 10, 65536):
        result = compare_bags(processed, tmp_path / 'short', cfg, block=block)
        assert [(d.index, d.what, d.a, d.b) for d in result.differences] == [(290, 'message count', 300, 290)]


def test_ignored_fields(processed: Path, cfg: AntennaConfig, tmp_path: Path) -> None:
    rewrite(processed, tmp_path / 'b', CASES['header stamp by 1 ns'])
    assert compare_bags(processed, tmp_path / 'b', cfg, ignore=['stamps']).equal
    rewrite(processed, tmp_path / 'c', CASES['velocity dropped'])
    assert compare_bags(processed, tmp_path / 'c', cfg, ignore=['velocities']).equal


def test_command_defaults_are_the_modules() -> None:
    from fourbar_ros.bags import compare as bag_compare
    from fourbar_ros.commands import compare

    assert compare.DEFAULT_ULPS == bag_compare.DEFAULT_ULPS


def test_bad_input_is_one_line(processed: Path, tmp_path: Path) -> None:
    for args in (['compare', processed, tmp_path / 'missing'],
                 ['compare', processed, processed, '--ignore', 'colour'],
                 ['compare', processed, processed, '--atol', 'nan']):
        rc, lines, out = run_main(args)
        assert rc == 2 and len(lines) == 1 and lines[0].startswith('fourbar compare: error: '), (args, lines, out)


# --------------------------------------------------------------------------- against the live node


@pytest.mark.ros
@pytest.mark.slow
@pytest.mark.parametrize('bag_name, policy', [('bad_values_mcap', 'reject'), ('bad_values_mcap', 'clamp'),
                                              ('sweep_sqlite3', 'reject')])
def test_live_node_recording_equals_processed_bag(bag_name: str, policy: str, ros: RosSession,
                                                  tmp_path: Path) -> None:
    """The node, `fourbar record` and lock-step `fourbar replay` as processes; `fourbar process` of the same
    bag with the same parameters; `fourbar compare` equal. "Equal" here: the same messages in the same order
    (names, frame_id, count: NaN and out-of-limit commands dropped or clamped alike), positions, efforts and
    input_torque within the default ulps of their scales. Not compared: the stamps (the node stamps with its
    own clock, the recorder logs its receive time; fourbar process uses the command's log time) and so the
    velocities, which divide by the node's clock intervals."""
    bag = BAG_DIR / bag_name
    params = tmp_path / 'params.yaml'
    params.write_text(CONFIG.read_text(encoding='utf-8').replace('out_of_limits: reject', f'out_of_limits: {policy}'),
                      encoding='utf-8')
    cfg = load_config(params)
    assert cfg.out_of_limits == policy
    stream = read_commands(bag)
    n = len(served(stream.values, cfg, policy))
    live = tmp_path / 'live'
    env = ros.env()
    # One JointState per command: idle republishing would add poses the processed bag does not have.
    with NodeProcess(['--ros-args', '--params-file', str(params), *ONE_JOINT_STATE_PER_COMMAND], env) as node, \
            Tool(['record', live, '--storage', stream.storage, '--stop-after', f'joint_states={n}',
                  '--stop-after', f'input_torque={n}'], env) as recorder:
        recorder.wait_line('recording')
        rc, lines, _ = run_tool(['replay', bag, '--no-progress', '--as-fast-as-node-keeps-up'], env)
        assert rc == 0, lines
        assert recorder.wait() == 0, recorder.lines
        assert node.running()
    rc, lines, _ = run_main(['process', bag, tmp_path / 'offline', '--params', params])
    assert rc == 0, lines
    rc, _, out = run_main(['compare', live, tmp_path / 'offline', '--params', params, '--ignore',
                           'stamps,velocities'])
    assert rc == 0, out
    assert f'/joint_states {n}' in out and f'/input_torque {n}' in out, out
    # The comparison has teeth on these very bags: a clamped or dropped command would change the count or
    # a position far beyond the tolerance.
    other = config_from_values({**cfg.as_values(), 'out_of_limits': 'clamp' if policy == 'reject' else 'reject'})
    process_bag(bag, tmp_path / 'other_policy', other)
    if n != len(served(stream.values, other)) or policy == 'clamp':
        assert not compare_bags(live, tmp_path / 'other_policy', cfg, ignore=['stamps', 'velocities']).equal


def _three_joint_bag(path: Path, cfg: AntennaConfig, theta: float, effort_change: float,
                     torque_change: float) -> Path:
    """The node's own 3-joint joint_states and input_torque at one pose, with the effort and torque moved."""
    from fourbar_ros.core.loads import pose

    store = jazzy_typestore()
    t = store.types
    p = pose(cfg, theta)
    tau = p.input_torque
    msg = t['sensor_msgs/msg/JointState'](
        header=t['std_msgs/msg/Header'](stamp=t['builtin_interfaces/msg/Time'](sec=1, nanosec=0), frame_id=''),
        name=list(cfg.joint_names), position=np.array([p.gamma, p.delta, p.gamma + theta]),
        velocity=np.array([], dtype=np.float64), effort=np.array([tau + effort_change, 0.0, 0.0]))
    with AtomicBagWriter(path) as bag:
        js = bag.add_topic('/joint_states', 'sensor_msgs/msg/JointState')
        it = bag.add_topic('/input_torque', 'std_msgs/msg/Float64')
        bag.write(js, 10**9, bytes(store.serialize_cdr(msg, 'sensor_msgs/msg/JointState')))
        bag.write(it, 10**9, bytes(store.serialize_cdr(t['std_msgs/msg/Float64'](data=tau + torque_change),
                                                      'std_msgs/msg/Float64')))
    return path


def test_the_torque_tolerance_follows_its_condition_in_the_nodes_own_bags(tmp_path: Path) -> None:
    # A poorly conditioned pose (near the driven rocker's dead point: |cot r| large, the torque ~1/sin r) in the
    # node's 3-joint JointState: a change of the effort and of input_torque just inside the condition-scaled
    # tolerance passes, just outside it is reported (by joint name, whatever the joint count).
    from fourbar_ros.bags.compare import DEFAULT_ULPS, torque_condition
    from fourbar_ros.core.loads import pose

    cfg = config_from_values({'theta_min': -0.1, 'theta_max': 0.335})  # the dead point: 0.337 rad
    theta = 0.335
    p = pose(cfg, theta)
    cond = float(torque_condition(cfg, np.array([[p.gamma, p.delta]]))[0])
    assert cond > 100.0  # poorly conditioned: the tolerance is far above 16 ulps of the torque itself
    allowed = DEFAULT_ULPS * float(np.spacing(abs(p.input_torque) * cond))
    a = _three_joint_bag(tmp_path / 'a', cfg, theta, 0.0, 0.0)
    inside = _three_joint_bag(tmp_path / 'in', cfg, theta, 0.9 * allowed, 0.9 * allowed)
    outside = _three_joint_bag(tmp_path / 'out', cfg, theta, 1.5 * allowed, 1.5 * allowed)
    assert compare_bags(a, inside, cfg).equal
    result = compare_bags(a, outside, cfg)
    whats = {d.what for d in result.differences}
    assert not result.equal and {'effort[0]', 'data'} <= whats, whats
