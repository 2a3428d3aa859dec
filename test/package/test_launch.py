"""``ros2 launch fourbar_ros fourbar.launch.py`` over a colcon-built install: the node in the given namespace
answers commands, arguments reach the node (one it does not declare is refused before anything starts),
robot_state_publisher / RViz start only where installed (else one log line), SIGINT ends everything with status 0;
and one launch_testing test (``launch_test``, on a domain of its own).

Runs where the ros2 command line and launch_ros are importable; skipped elsewhere with the reason.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

import pytest
from support.colcon_support import BIN, CliEnv, launch_missing, ros2, ros2_cli_missing
from support.isolation import isolated_env
from support.paths import REPO

if (_why := ros2_cli_missing() or launch_missing()) is not None:
    pytest.skip(_why, allow_module_level=True)

from support.ros_cli_support import (  # psutil: with ros2cli
    Background,
    echo_once,
    echoed_messages,
    publish_until_echoed,
    run,
    wait_node,
)

from fourbar_ros.config.antenna_config import load_config
from fourbar_ros.live.node_process import DomainLease

pytestmark = [pytest.mark.ros, pytest.mark.slow]

EPS = sys.float_info.epsilon


def installed(env: dict[str, str], package: str) -> bool:
    return run([ros2(), 'pkg', 'prefix', package], env).returncode == 0


@pytest.fixture
def install(ros2_cli: CliEnv) -> CliEnv:
    """The run's sourced install for the command line (conftest's ``ros2_cli``)."""
    return ros2_cli


def test_ros2_launch_in_a_namespace_serves_and_stops_on_sigint(install: CliEnv) -> None:
    launch = Background([ros2(), 'launch', 'fourbar_ros', 'fourbar.launch.py', 'namespace:=tilt_launch'],
                        install.env, cwd=install.cwd, terminal=False)  # started by a script: non-interactive
    try:
        nodes = wait_node(install.env, '/tilt_launch/fourbar_node')
        if installed(install.env, 'robot_state_publisher'):
            nodes = wait_node(install.env, '/tilt_launch/robot_state_publisher')
        else:
            launch.wait_output(lambda t: 'robot_state_publisher is not installed; not starting it' in t,
                               'the log line about robot_state_publisher')
        assert not [n for n in nodes if n.endswith('fourbar_node') and not n.startswith('/tilt_launch/')], nodes
        cfg = load_config(install.prefix / 'share' / 'fourbar_ros' / 'config' / 'antenna.yaml')
        echo = echo_once(install.env, '/tilt_launch/joint_states', 'sensor_msgs/msg/JointState')
        try:
            msg = publish_until_echoed(install.env, echo, '/tilt_launch/antenna_angle_cmd', -0.05)
        finally:
            echo.kill()
        gamma, delta = cfg.linkage.rocker_angles(-0.05, cfg.branch)
        # Same core solve in node and test; 4 ulps for a different operation order (condition ~1.5 here).
        assert abs(msg['position'][0] - gamma) <= 4 * EPS * abs(gamma)
        assert abs(msg['position'][1] - delta) <= 4 * EPS * abs(delta)
        children = launch.descendants()
        assert children
        status = launch.interrupt(group=False)  # `kill -INT` of ros2 launch: it stops its processes itself
        assert status == 0, launch.stdout[-2000:] + launch.stderr[-2000:]
        assert 'Traceback' not in launch.stdout + launch.stderr, launch.stdout[-3000:] + launch.stderr[-3000:]
        assert not launch.descendants(), 'a process outlived ros2 launch'
    finally:
        launch.kill()


def test_launch_arguments_reach_the_node_and_ctrl_c_ends_with_0(install: CliEnv, tmp_path: Path) -> None:
    params = tmp_path / 'mine.yaml'
    params.write_text((REPO / 'config' / 'antenna.yaml').read_text(encoding='utf-8')
                      .replace('load_torque: 3.5', 'load_torque: 1.25'), encoding='utf-8')
    launch = Background([ros2(), 'launch', 'fourbar_ros', 'fourbar.launch.py', 'namespace:=/tilt_args',
                         f'params_file:={params}', 'use_sim_time:=true', 'rviz:=true'], install.env, cwd=install.cwd)
    try:
        wait_node(install.env, '/tilt_args/fourbar_node')
        get = [ros2(), 'param', 'get', '--timeout', '30', '/tilt_args/fourbar_node']
        assert run([*get, 'use_sim_time'], install.env).stdout.strip() == 'Boolean value is: True'
        assert run([*get, 'load_torque'], install.env).stdout.strip() == 'Double value is: 1.25'
        if not installed(install.env, 'rviz2'):
            launch.wait_output(lambda t: 'rviz2 is not installed; not starting RViz' in t, 'the log line about rviz2')
        launch.descendants()
        status = launch.interrupt(group=True)  # Ctrl-C in a terminal: SIGINT to the whole foreground group
        assert status == 0, launch.stdout[-2000:] + launch.stderr[-2000:]
        assert 'Traceback' not in launch.stdout + launch.stderr, launch.stdout[-3000:] + launch.stderr[-3000:]
        assert not launch.descendants(), 'a process outlived ros2 launch'
    finally:
        launch.kill()


#: A line of a process launch started: its own output ("[fourbar_node-1] ...") or launch's note of its start.
PROCESS_LINE = re.compile(r'^\[[\w.]+-\d+\]|process started with pid', re.MULTILINE)


def test_an_undeclared_argument_is_refused_in_one_line_before_anything_starts(install: CliEnv) -> None:
    shown = run([ros2(), 'launch', 'fourbar_ros', 'fourbar.launch.py', '--show-args'], install.env, cwd=install.cwd)
    assert shown.returncode == 0, shown.stdout + shown.stderr
    declared = sorted(re.findall(r"^    '(\w+)':$", shown.stdout, re.MULTILINE))
    assert {'hardware', 'namespace', 'params_file', 'use_ros2_control'} <= set(declared), shown.stdout
    out = run([ros2(), 'launch', 'fourbar_ros', 'fourbar.launch.py', 'namespace:=tilt_refused',
               'use_ros2_control:=true', 'hardwre:=mujoco'], install.env, cwd=install.cwd)
    text = out.stdout + out.stderr
    refused = [line for line in text.splitlines() if 'hardwre' in line]
    want = f'fourbar.launch.py: unknown launch argument hardwre; it takes: {", ".join(declared)}'
    assert out.returncode == 1 and len(refused) == 1 and refused[0].endswith(want), (out.returncode, refused, text)
    assert not PROCESS_LINE.search(text) and 'Traceback' not in text, text  # nothing started


def test_sim_actuator_argument_starts_the_simulated_drive(install: CliEnv) -> None:
    launch = Background([ros2(), 'launch', 'fourbar_ros', 'fourbar.launch.py', 'namespace:=tilt_sim',
                         'sim_actuator:=true', 'robot_state_publisher:=false', 'mode:=trajectory'],
                        install.env, cwd=install.cwd)
    try:
        wait_node(install.env, '/tilt_sim/sim_actuator')
        wait_node(install.env, '/tilt_sim/fourbar_node')
        got = run([ros2(), 'param', 'get', '--timeout', '30', '/tilt_sim/fourbar_node', 'mode'],
                  install.env, timeout=60, cwd=install.cwd)
        assert 'trajectory' in got.stdout, got.stdout + got.stderr  # the mode argument reached the node
        echo = echo_once(install.env, '/tilt_sim/joint_states', 'sensor_msgs/msg/JointState')
        assert echo.wait_exit() == 0, echo.stderr  # the drive publishes by itself, at its rate
        echoed = echoed_messages(echo.stdout)
        assert echoed, f'no message in the echo\'s output:\n{echo.stdout}'
        doc = echoed[0]
        cfg = load_config(install.prefix / 'share' / 'fourbar_ros' / 'config' / 'antenna.yaml')
        # joint_states holds the node's complete state, one per measurement of the drive (trajectory mode): it
        # exists only because the drive publishes where the launch file remapped the node's measured_joint_states.
        other = cfg.delta_joint if cfg.driven_joint == cfg.gamma_joint else cfg.gamma_joint
        assert doc['name'] == [cfg.driven_joint, other, cfg.coupler_joint] and len(doc['effort']) == 3, doc
        status = launch.interrupt(group=True)
        assert status == 0, launch.stdout[-2000:] + launch.stderr[-2000:]
        assert 'Traceback' not in launch.stdout + launch.stderr, launch.stdout[-3000:] + launch.stderr[-3000:]
        assert not launch.descendants(), 'a process outlived ros2 launch'
    finally:
        launch.kill()


def test_launch_testing_test_passes(install: CliEnv, lease: DomainLease) -> None:
    # On a domain of its own: not the one of this module's ros2 daemon and command-line processes.
    launch_test = BIN / 'launch_test'
    exe = str(launch_test) if launch_test.exists() else 'launch_test'
    ready = REPO / 'test' / 'package' / 'launch_fourbar_ready.py'
    out = run([exe, str(ready)], isolated_env(install.env, lease.domain_id), timeout=180, cwd=install.cwd)
    text = out.stdout + out.stderr
    assert out.returncode == 0, text[-4000:]
    assert 'test_joint_states_answer_a_command' in text and 'test_exit_codes' in text, text[-4000:]
