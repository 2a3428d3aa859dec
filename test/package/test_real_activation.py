"""A drive's first minutes on the real ros2_control stack: the package's launch file with a hardware plugin that
talks over topics (``joint_state_topic_hardware_interface/JointStateTopicSystem``, its topics given as
``hardware_parameters``), the test standing in for the drive. Once for the module: the parameters reach the launched
robot model, the controller manager clamps a command outside the URDF's limits, the shipped trajectory controller
activates holding the measured position where the controller's default holds the hardware's last command, and the
stop commands of docs/how-to/ros2-control.md deactivate the controller and the hardware.

Runs where the ros2 command line, launch_ros and ros2_control are installed; skipped elsewhere with the reason.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, NamedTuple

import pytest
import yaml
from support.colcon_support import CliEnv, launch_missing, ros2, ros2_cli_missing
from support.paths import REPO
from support.ros2_control_support import ros2_control_missing

if (_why := ros2_cli_missing() or launch_missing()) is not None:
    pytest.skip(_why, allow_module_level=True)

from support.ros_cli_support import (  # psutil: with ros2cli
    PUB_ONCE,
    Background,
    echo_once,
    echoed_messages,
    run,
    wait_node,
)

from fourbar_ros.config.antenna_config import load_config
from fourbar_ros.config.robot_model import joint_limits
from fourbar_ros.rules.diagnostics import status_name

pytestmark = [pytest.mark.ros, pytest.mark.slow]

NAMESPACE = 'drive'
MANAGER = f'/{NAMESPACE}/controller_manager'
PLUGIN = 'joint_state_topic_hardware_interface/JointStateTopicSystem'
#: The plugin's topics (its hardware parameters ``joint_commands_topic`` and ``joint_states_topic``).
COMMANDS, STATES = '/fourbar_test_drive/joint_commands', '/fourbar_test_drive/joint_states'
#: Where the stand-in drive says the joint is (rad): inside the range, away from the level pose's 0.8632 rad.
MEASURED = 0.85
#: A trajectory controller as the shipped one but without set_last_command_interface_value_as_state_on_activation:
#: the controller's default (true), the negative control.
DEFAULT_JTC = 'jtc_default'
UPDATE_RATE = 100  # Hz, the shipped controller manager's
#: Command and position are doubles passed through unchanged; a clamp to the limit gives the limit's double.
#: Compared to 1e-12 rad: the velocity clamp adds and subtracts v * dt, which rounds at ~1e-16 rad.
EXACT = 1e-12


class Bringup(NamedTuple):
    cli: CliEnv
    launch: Background
    drive: Background  # the stand-in drive's measured joint, published at 50 Hz
    commands: Background  # an echo of every command the plugin sends to the drive


def _files(directory: Path) -> tuple[Path, Path]:
    """The shipped parameter file with the plugin's topics as hardware_parameters, and the shipped controllers file
    with DEFAULT_JTC added beside joint_trajectory_controller."""
    params = directory / 'antenna.yaml'
    params.write_text((REPO / 'config' / 'antenna.yaml').read_text(encoding='utf-8').replace(
        'hardware_parameters: []', f"hardware_parameters: ['joint_commands_topic={COMMANDS}', "
                                   f"'joint_states_topic={STATES}']", 1), encoding='utf-8')
    settings = yaml.safe_load((REPO / 'config' / 'controllers.yaml').read_text(encoding='utf-8'))
    manager = settings['/**/controller_manager']['ros__parameters']
    assert manager['enforce_command_limits'] is True and manager['update_rate'] == UPDATE_RATE
    manager[DEFAULT_JTC] = dict(manager['joint_trajectory_controller'])
    shipped = settings['/**/joint_trajectory_controller']['ros__parameters']
    assert shipped['set_last_command_interface_value_as_state_on_activation'] is False
    default = copy.deepcopy({k: v for k, v in shipped.items()
                             if k != 'set_last_command_interface_value_as_state_on_activation'})
    settings[f'/**/{DEFAULT_JTC}'] = {'ros__parameters': default}
    controllers = directory / 'controllers.yaml'
    controllers.write_text(yaml.safe_dump(settings), encoding='utf-8')
    return params, controllers


@pytest.fixture(scope='module')
def bringup(ros2_cli: CliEnv, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Bringup]:
    if (why := ros2_control_missing(ros2_cli.env)) is not None:
        pytest.skip(why)
    params, controllers = _files(tmp_path_factory.mktemp('drive'))
    env = ros2_cli.env
    drive = Background([ros2(), 'topic', 'pub', '-r', '50', STATES, 'sensor_msgs/msg/JointState',
                        f'{{name: [rocker_ab_joint], position: [{MEASURED!r}], velocity: [0.0], effort: [0.0]}}'],
                       env, cwd=ros2_cli.cwd)
    commands = Background([ros2(), 'topic', 'echo', COMMANDS, 'sensor_msgs/msg/JointState'], env, cwd=ros2_cli.cwd)
    launch = Background([ros2(), 'launch', 'fourbar_ros', 'fourbar.launch.py', f'namespace:={NAMESPACE}',
                         'use_ros2_control:=true', 'mode:=forward', 'rviz:=false', f'hardware_plugin:={PLUGIN}',
                         f'params_file:={params}', f'controllers_file:={controllers}'], env, cwd=ros2_cli.cwd)
    try:
        launch.wait_output(lambda t: 'Configured and activated forward_position_controller' in t,
                           'the forward controller active')
        wait_node(env, f'/{NAMESPACE}/fourbar_node')
        yield Bringup(ros2_cli, launch, drive, commands)
        assert launch.interrupt(group=True) == 0, launch.stdout[-2000:] + launch.stderr[-2000:]
        assert 'Traceback' not in launch.stdout + launch.stderr, launch.stdout[-3000:] + launch.stderr[-3000:]
    finally:
        for process in (launch, drive, commands):
            process.kill()


def _control(b: Bringup, *args: str) -> str:
    out = run([ros2(), 'control', *args, '-c', MANAGER], b.cli.env, cwd=b.cli.cwd)
    assert out.returncode == 0, f'ros2 control {" ".join(args)}: {out.stdout}{out.stderr}'
    return out.stdout


def _commanded(b: Bringup) -> list[float]:
    """Every position the plugin has sent to the drive so far (rad)."""
    return [float(m['position'][0]) for m in echoed_messages(b.commands.output()) if m.get('position')]


def _recent(text: str) -> list[float]:
    """The positions of the commands in the last few kB of the echo's output (it grows by 100 messages a second:
    a wait parses its tail only), from a message boundary on."""
    tail = text[-8000:]
    start = tail.find('\n---')
    return [float(m['position'][0]) for m in echoed_messages(tail[start:] if start >= 0 else '') if m.get('position')]


def _stamped(b: Bringup) -> list[tuple[float, float]]:
    """(stamp in s, position in rad) of every command the plugin has sent to the drive so far."""
    return [(m['header']['stamp']['sec'] + 1e-9 * m['header']['stamp']['nanosec'], float(m['position'][0]))
            for m in echoed_messages(b.commands.output()) if m.get('position')]


def _state(b: Bringup, controller: str) -> dict[str, Any]:
    echo = echo_once(b.cli.env, f'/{NAMESPACE}/{controller}/controller_state',
                     'control_msgs/msg/JointTrajectoryControllerState')
    try:
        assert echo.wait_exit() == 0, echo.stderr
    finally:
        echo.kill()
    (state, *_) = echoed_messages(echo.stdout)
    return state


def test_the_hardware_parameters_reach_the_launched_robot_description(bringup: Bringup) -> None:
    # robot_state_publisher's robot_description, which it publishes for the controller manager.
    out = run([ros2(), 'param', 'get', f'/{NAMESPACE}/robot_state_publisher', 'robot_description'], bringup.cli.env)
    assert out.returncode == 0, out.stdout + out.stderr
    urdf = out.stdout
    for name, value in (('joint_commands_topic', COMMANDS), ('joint_states_topic', STATES)):
        assert f'<param name="{name}">{value}</param>' in urdf, urdf
    # The controller manager took that model: the plugin runs, active, and sends on the topic it was given.
    listed = _control(bringup, 'list_hardware_components', '--verbose')
    ours = listed.split('name: fourbar_antenna_tilt', 1)[1]
    assert f'plugin name: {PLUGIN}' in ours and 'label=active' in ours, listed


def test_a_command_outside_the_limits_is_clamped_by_the_controller_manager(bringup: Bringup) -> None:
    # Straight to the forward controller's topic: 0.0 rad, far below the joint's lower limit. The controller writes
    # it; the controller manager (enforce_command_limits) clamps it to the URDF's position limits and to the last
    # command +- the velocity limit per update, so the drive sees a ramp from where the joint is down to the limit.
    cfg = load_config(REPO / 'config' / 'antenna.yaml')
    limit = joint_limits(cfg)[cfg.driven_joint]
    step = limit.velocity / UPDATE_RATE
    out = run([ros2(), *PUB_ONCE, f'/{NAMESPACE}/forward_position_controller/commands',
               'std_msgs/msg/Float64MultiArray', '{data: [0.0]}'], bringup.cli.env)
    assert out.returncode == 0, out.stdout + out.stderr
    bringup.commands.wait_output(lambda t: any(abs(q - limit.lower) <= EXACT for q in _recent(t)),
                                 f'the commands at the lower limit {limit.lower!r} rad', timeout=(
                                     (MEASURED - limit.lower) / limit.velocity + 30.0))
    sent = [(t, q) for t, q in _stamped(bringup) if not math.isnan(q)]
    assert min(q for _, q in sent) >= limit.lower - EXACT, f'below the lower limit {limit.lower!r} rad: {sent[-5:]}'
    # The ramp, from its first step to the limit, by the plugin's stamps: each update may step by the velocity limit
    # times its period, and the stamps are taken as the updates write, each within an update of its update's time
    # on a loaded machine: the distance is the limit times the stamped time within two steps. The echo may miss
    # messages, so single steps are not compared.
    ramp = [(t, q) for t, q in sent if q < sent[0][1] - EXACT]
    end = next(i for i, (_, q) in enumerate(ramp) if abs(q - limit.lower) <= EXACT)
    (t0, q0), (t1, q1) = ramp[0], ramp[end]
    assert abs((q0 - q1) - limit.velocity * (t1 - t0)) <= 2 * step, (
        f'the ramp ran {q0 - q1!r} rad ({q0!r} to {q1!r}) in {t1 - t0:.3f} s, {(q0 - q1) / (t1 - t0)!r} rad/s; the '
        f'velocity limit is {limit.velocity!r} rad/s ({step!r} rad per update)')


def test_activation_holds_the_measured_position_not_the_last_command(bringup: Bringup) -> None:
    # The last command (the clamped ramp's end, the lower limit) is far from the measured 0.85 rad. The controller's
    # default holds that command on activation; the shipped setting holds the measured position.
    last = _commanded(bringup)[-1]
    assert abs(last - MEASURED) > 0.1, last
    spawned = run([ros2(), 'run', 'controller_manager', 'spawner', DEFAULT_JTC, 'joint_trajectory_controller',
                   '--inactive', '-c', MANAGER], bringup.cli.env)
    assert spawned.returncode == 0, spawned.stdout + spawned.stderr
    _control(bringup, 'switch_controllers', '--deactivate', 'forward_position_controller', '--activate', DEFAULT_JTC)
    default = _state(bringup, DEFAULT_JTC)
    assert default['reference']['positions'] == [last] and default['feedback']['positions'] == [MEASURED], (
        f'the default holds {default["reference"]["positions"]}, last command {last!r}, measured {MEASURED!r}')
    _control(bringup, 'switch_controllers', '--deactivate', DEFAULT_JTC, '--activate', 'joint_trajectory_controller')
    shipped = _state(bringup, 'joint_trajectory_controller')
    assert shipped['reference']['positions'] == [MEASURED] and shipped['output']['positions'] == [MEASURED], (
        f'the shipped controller holds {shipped["reference"]["positions"]} (output {shipped["output"]["positions"]})'
        f', measured {MEASURED!r}, last command {last!r}')


def _statuses(text: str, key: str, value: Callable[[str], bool], node: str = 'fourbar_node') -> list[dict[str, Any]]:
    """The statuses of ``node`` (in NAMESPACE) whose ``key`` has a value for which ``value`` holds, in the last few
    kB of a /diagnostics echo (parsed from a message boundary on: the echo's YAML folds long strings over lines)."""
    tail = text[-30000:]
    chunks = tail.split('\n---')[1:]  # the first may have been cut
    # only the node's own messages: the controller manager's carry multi-line strings the echo parser skips
    ours = '\n---'.join(c for c in chunks if key in c)
    return [s for m in echoed_messages(ours) for s in m.get('status', [])
            if s.get('name', '') == status_name(f'/{NAMESPACE}/{node}')
            and any(kv['key'] == key and value(kv['value']) for kv in s.get('values', []))]


def _not_following(text: str) -> list[dict[str, Any]]:
    """The node's statuses saying the drive does not follow."""
    return _statuses(text, 'drive_follows', lambda v: v.startswith('no:'))


def test_a_drive_that_does_not_follow_is_an_error_and_its_command_is_not_resumed(bringup: Bringup) -> None:
    # The stand-in drive stays at MEASURED whatever the plugin sends it. With the forward controller active, a
    # command's setpoints move away from there and the measured joint does not: after follow_timeout the node says
    # ERROR naming the likely causes, and the command ends interrupted, not resumed.
    env, cwd = bringup.cli.env, bringup.cli.cwd
    _control(bringup, 'switch_controllers', '--deactivate', 'joint_trajectory_controller',
             '--activate', 'forward_position_controller')
    diagnostics = Background([ros2(), 'topic', 'echo', '/diagnostics', 'diagnostic_msgs/msg/DiagnosticArray'],
                             env, cwd=cwd)
    try:
        diagnostics.wait_output(lambda t: 'controller_state' in t and 'value: active' in t,
                                'the node following its active forward controller')
        out = run([ros2(), *PUB_ONCE, f'/{NAMESPACE}/antenna_angle_cmd',
                   'std_msgs/msg/Float64', '{data: 0.09}'], env, cwd=cwd)  # gamma 0.969 rad, 0.12 from MEASURED
        assert out.returncode == 0, out.stdout + out.stderr
        diagnostics.wait_output(lambda t: bool(_not_following(t)), 'the node saying the drive does not follow',
                                timeout=60.0)
        status = _not_following(diagnostics.output())[-1]
    finally:
        diagnostics.kill()
    values = {kv['key']: kv['value'] for kv in status['values']}
    assert values['drive_follows'].startswith('no: the drive does not follow: measured 0.85 rad'), values
    assert values['command_fate'] == 'interrupted' and values['commands_interrupted'] == '1', values
    assert status['message'].startswith('the drive does not follow') and 'likely: ' in status['message'], status
    assert status['level'] == '\x02', f'level {status["level"]!r} (ERROR is 2): {status}'
    _control(bringup, 'switch_controllers', '--deactivate', 'forward_position_controller',
             '--activate', 'joint_trajectory_controller')


def test_the_stop_commands_deactivate_the_controller_and_the_hardware(bringup: Bringup) -> None:
    # docs/how-to/ros2-control.md, "Stop": both at once, as typed there (with this namespace's manager).
    _control(bringup, 'switch_controllers', '--deactivate', 'joint_trajectory_controller')
    _control(bringup, 'set_hardware_component_state', 'fourbar_antenna_tilt', 'inactive')
    controllers = _control(bringup, 'list_controllers')
    line = next(x for x in controllers.splitlines() if x.startswith('joint_trajectory_controller'))
    assert 'inactive' in line, controllers
    hardware = _control(bringup, 'list_hardware_components')
    assert 'state: id=2 label=inactive' in hardware.split('name: fourbar_antenna_tilt', 1)[1], hardware


def test_a_drive_read_outside_the_range_deactivates_the_controller_and_the_node_says_why(bringup: Bringup) -> None:
    # After the stop: the hardware and the shipped trajectory controller activated again, and a second fourbar_node
    # in trajectory mode (its command topic remapped away: it sends nothing) following that controller. A second
    # stand-in drive reads the joint 0.1 rad below its lower limit, interleaved with the first one's MEASURED: the
    # controller manager (enforce_command_limits) fails the controller's update and deactivates it, saying why only
    # in its log; that node's status turns ERROR with the manager's lines. (The manager leaves the controller
    # unconfigured; here a configure and an activation after it failed too, so this test comes last.)
    env, cwd = bringup.cli.env, bringup.cli.cwd
    cfg = load_config(REPO / 'config' / 'antenna.yaml')
    outside = joint_limits(cfg)[cfg.driven_joint].lower - 0.1
    jtc, name = 'joint_trajectory_controller', 'fourbar_node_jtc'
    params = next(a for a in bringup.launch.cmd if a.startswith('params_file:=')).split(':=', 1)[1]
    _control(bringup, 'set_hardware_component_state', 'fourbar_antenna_tilt', 'active')
    _control(bringup, 'switch_controllers', '--activate', jtc)
    diagnostics = Background([ros2(), 'topic', 'echo', '--full-length', '/diagnostics',
                              'diagnostic_msgs/msg/DiagnosticArray'], env, cwd=cwd)  # strings past 128 characters
    node = Background([ros2(), 'run', 'fourbar_ros', 'fourbar_node', '--ros-args', '-r', f'__ns:=/{NAMESPACE}',
                       '-r', f'__node:={name}', '--params-file', params, '-p', 'mode:=trajectory',
                       '-r', 'antenna_angle_cmd:=unused_cmd',
                       '-r', 'measured_joint_states:=joint_state_broadcaster/joint_states'], env, cwd=cwd)
    fault = None
    try:
        diagnostics.wait_output(lambda t: node.proc.poll() is not None or bool(
            _statuses(t, 'controller_state', lambda v: v == 'active', name)),
            f'{name} following the active {jtc}', timeout=60.0)
        assert node.proc.poll() is None, node.output()[-3000:]
        fault = Background([ros2(), 'topic', 'pub', '-r', '50', STATES, 'sensor_msgs/msg/JointState',
                            f'{{name: [rocker_ab_joint], position: [{outside!r}], velocity: [0.0], effort: [0.0]}}'],
                           env, cwd=cwd)
        try:
            deactivated = diagnostics.wait_output(
                lambda t: bool(_statuses(t, 'controller_deactivated', lambda v: v != 'no', name)),
                'the node saying the controller manager deactivated the controller', timeout=60.0)
        except AssertionError:
            seen = [{kv['key']: kv['value'] for kv in s['values'] if kv['key'].startswith('controller')}
                    for s in _statuses(diagnostics.output(), 'controller_state', lambda v: True, name)[-2:]]
            manager = [x for x in bringup.launch.output().splitlines() if '.controller_manager]' in x]
            raise AssertionError(f'the node said {seen}; the controller manager logged {manager[-8:]}') from None
        status = _statuses(deactivated, 'controller_deactivated', lambda v: v != 'no', name)[-1]
        listed = _control(bringup, 'list_controllers')
        assert node.interrupt(group=True) == 0, node.output()[-3000:]
    finally:
        for process in (fault, node, diagnostics):
            if process is not None:
                process.kill()
    values = {kv['key']: kv['value'] for kv in status['values']}
    line = next(x for x in listed.splitlines() if x.startswith(jtc))
    assert line.split()[-1] in ('inactive', 'unconfigured'), listed
    assert values['controller_state'] == 'inactive', values
    reason = values['controller_deactivated']
    assert f"while updating controller '{jtc}'" in reason and 'out of bounds' in reason, reason
    assert status['message'].startswith(f'controller {jtc} deactivated by the controller manager: '), status
    assert status['level'] == '\x02', f'level {status["level"]!r} (ERROR is 2): {status}'
