"""The ROS 2 command line a user types, over a colcon-built install of the package:
``ros2 run fourbar_ros fourbar_node --ros-args --params-file ... -r __ns:=...``, ``ros2 topic pub --once`` /
``ros2 topic echo --once``, ``ros2 param set`` (accepted and refused) and Ctrl-C.

Every process shares the module's leased ROS_DOMAIN_ID for the command line (conftest's ``ros2_cli``), discovery
limited to this host, and the ros2 daemon started once for the module.
Runs where the ros2 command line is importable (a sourced Jazzy install, or scripts/install_ros_cli.sh);
skipped elsewhere with the reason.
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest
from support.colcon_support import CliEnv, ros2, ros2_cli_missing

if (_why := ros2_cli_missing()) is not None:
    pytest.skip(_why, allow_module_level=True)

from support.ros_cli_support import (  # psutil: with ros2cli
    TIMEOUT,
    Background,
    echo_once,
    echoed_messages,
    publish_until_echoed,
    run,
)
from support.urdf_kinematics import link_poses

from fourbar_ros.config.antenna_config import load_config
from fourbar_ros.config.robot_model import robot_description

pytestmark = [pytest.mark.ros, pytest.mark.slow]

NAMESPACE = '/tilt_cli'
NODE = f'{NAMESPACE}/fourbar_node'
EPS = sys.float_info.epsilon


@dataclass
class Antenna:
    """The node started by ``ros2 run`` in NAMESPACE, and what the tests learnt from it."""

    env: dict[str, str]
    prefix: Path
    proc: Background
    params: Path
    joint_states: dict[str, Any] = field(default_factory=dict)


@pytest.fixture(scope='module')
def antenna(ros2_cli: CliEnv) -> Iterator[Antenna]:
    params = ros2_cli.prefix / 'share' / 'fourbar_ros' / 'config' / 'antenna.yaml'
    proc = Background([ros2(), 'run', 'fourbar_ros', 'fourbar_node', '--ros-args', '--params-file', str(params),
                       '-r', f'__ns:={NAMESPACE}'], ros2_cli.env, cwd=ros2_cli.cwd)
    try:
        yield Antenna(ros2_cli.env, ros2_cli.prefix, proc, params)
    finally:
        proc.kill()


def test_ros2_run_in_a_namespace_answers_topic_pub_on_topic_echo(antenna: Antenna) -> None:
    cfg = load_config(antenna.params)
    echo = echo_once(antenna.env, f'{NAMESPACE}/joint_states', 'sensor_msgs/msg/JointState')
    try:
        msg = publish_until_echoed(antenna.env, echo, f'{NAMESPACE}/antenna_angle_cmd', 0.05)
    finally:
        echo.kill()
    antenna.joint_states = msg
    names = list(msg['name'])
    assert names == list(cfg.joint_names)
    state = cfg.linkage.state(0.05, cfg.load_torque)
    # The node and this test call the same core solve; 4 ulps leave room for a different operation order in the
    # node's pose path (condition ~1.5 inside the tilt range). ros2 topic echo prints doubles round-trippably.
    for got, want in zip(msg['position'], (state.gamma, state.delta, state.gamma + 0.05), strict=True):
        assert abs(got - want) <= 4 * EPS * abs(want), (got, want)
    assert abs(msg['effort'][0] - state.input_torque) <= 16 * EPS * abs(state.input_torque)
    # Relative names: every topic of the node is inside the namespace (listed once discovery has seen them).
    deadline = time.monotonic() + TIMEOUT
    while True:
        topics = run([ros2(), 'topic', 'list'], antenna.env).stdout.split()
        if f'{NAMESPACE}/joint_states' in topics and f'{NAMESPACE}/antenna_angle_cmd' in topics:
            break
        assert time.monotonic() < deadline, f'namespaced topics not listed after {TIMEOUT} s: {topics}'
    assert not {'/joint_states', '/antenna_angle_cmd', '/input_torque', '/linkage_markers'} & set(topics), topics


def test_published_joint_states_close_the_urdf_loop(antenna: Antenna) -> None:
    """The node's own JointState, through the URDF's forward kinematics: both chains meet at C."""
    msg = antenna.joint_states
    if not msg:
        pytest.skip('no joint_states received (see the previous test)')
    cfg = load_config(antenna.params)
    assert msg['name'] == list(cfg.joint_names)  # every movable joint of the URDF, for robot_state_publisher
    positions = dict(zip(msg['name'], msg['position'], strict=True))
    poses = link_poses(robot_description(cfg), positions)
    gap = math.dist(poses['coupler_c'][:3, 3], poses['rocker_cd_c'][:3, 3])
    length_sum = cfg.frame_length + cfg.rocker_ab_length + cfg.coupler_length + cfg.rocker_cd_length
    assert gap <= 16 * EPS * length_sum  # the bound of test_urdf.py (angle errors of a few ulps, condition ~1)


def _param_get(antenna: Antenna, name: str) -> str:
    out = run([ros2(), 'param', 'get', '--timeout', '30', NODE, name], antenna.env)
    assert out.returncode == 0, out.stdout + out.stderr
    return out.stdout.strip()


def _param_set(antenna: Antenna, name: str, value: str) -> tuple[str, str]:
    out = run([ros2(), 'param', 'set', '--timeout', '30', NODE, name, value], antenna.env)
    assert out.returncode == 0, out.stdout + out.stderr  # ros2 param set exits 0 and says why on stderr
    return out.stdout.strip(), out.stderr.strip()


def test_ros2_param_set_accepted_and_refused(antenna: Antenna) -> None:
    theta_max = _param_get(antenna, 'theta_max')
    out, err = _param_set(antenna, 'load_torque', '2.0')
    assert out.startswith('Set parameter successful'), (out, err)
    assert _param_get(antenna, 'load_torque') == 'Double value is: 2.0'
    # One refusal of the node's own (every kind is checked in-process in test_node.py) and one of rclpy's.
    refusals = {
        'theta_max': '1.5',        # beyond the linkage's reach
        'marker_period': '0.2',    # read-only
    }
    for name, value in refusals.items():
        out, err = _param_set(antenna, name, value)
        assert out == '' and err.startswith('Setting parameter failed'), (name, out, err)
    assert _param_get(antenna, 'load_torque') == 'Double value is: 2.0'
    assert _param_get(antenna, 'theta_max') == theta_max
    assert antenna.proc.proc.poll() is None, antenna.proc.output()[-2000:]


def test_ctrl_c_stops_ros2_run_and_the_node_with_status_0(antenna: Antenna) -> None:
    children = antenna.proc.descendants()
    assert children, 'ros2 run started no node process'
    status = antenna.proc.interrupt(group=True)  # Ctrl-C in a terminal: SIGINT to the foreground group
    assert status == 0, antenna.proc.stderr[-3000:]
    assert 'Traceback' not in antenna.proc.stderr, antenna.proc.stderr[-3000:]
    assert not antenna.proc.descendants(), 'a process outlived ros2 run'


def test_echoed_messages_are_read_between_the_middlewares_log_lines() -> None:
    # Fast DDS logs to the echo's stdout (the line's start as one was captured; its end as Fast DDS formats it),
    # and ros2 topic echo notes messages lost before it matched: neither is part of a message.
    log = ('\x1b[37;1m2026-11-27 11:58:33.906 \x1b[31;1m[\x1b[37;1mRTPS_TRANSPORT_SHM\x1b[31;1m Error] '
           '\x1b[37mFailed init_port fastrtps_port7413: open_and_lock_file failed -> Function init_port\x1b[m')
    stdout = '\n'.join([log, 'header:', '  stamp:', '    sec: 1', "  frame_id: ''", 'name:', '- a_joint',
                         'position:', '- 0.5', 'velocity: []', '---', 'A message was lost!!!',
                         '\ttotal count change:1', '\ttotal count: 1', log, 'name: []', 'position: []', '---', ''])
    assert echoed_messages(stdout) == [
        {'header': {'stamp': {'sec': 1}, 'frame_id': ''}, 'name': ['a_joint'], 'position': [0.5], 'velocity': []},
        {'name': [], 'position': []}]
