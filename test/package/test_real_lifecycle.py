"""fourbar_node across its controller's lifecycle, on the real ros2_control stack (the package's launch file, mock
hardware, one controller manager for the module): a command while the controller is inactive or not yet spawned,
one interrupted by a deactivation, by its hardware component's deactivation and by the controller manager's death
and respawn; each ends reached (or interrupted, as the parameter says), and the node's diagnostics say so. The
simulated actuator, playing a controller manager where controller_manager_msgs is installed, gives the same fates.

Runs where the ros2 command line, launch_ros and ros2_control are installed; skipped elsewhere with the reason.
"""

from __future__ import annotations

import itertools
import json
import math
import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from support.colcon_support import CliEnv, launch_missing, ros2, ros2_cli_missing
from support.paths import REPO
from support.ros2_control_support import ros2_control_missing

if (_why := ros2_cli_missing() or launch_missing()) is not None:
    pytest.skip(_why, allow_module_level=True)

from support.ros_cli_support import Background, fourbar_launch  # psutil: with ros2cli

from fourbar_ros.config.antenna_config import load_config

pytestmark = [pytest.mark.ros, pytest.mark.slow]

PROBE = REPO / 'test' / 'support' / 'lifecycle_probe.py'
NAMESPACE = 'life'
JTC = 'joint_trajectory_controller'
HARDWARE = 'fourbar_antenna_tilt'
#: The node's reached_tolerance (rad, the shipped default): a reached command's measured angle is within it.
REACHED_TOLERANCE = 1e-3
#: Random lifecycle sequences in `make test`; `make test-stress` runs FOURBAR_LIFECYCLE_SEQUENCES (default 100).
QUICK, STRESS = 3, int(os.environ.get('FOURBAR_LIFECYCLE_SEQUENCES', '100'))
FATES = ('reached', 'interrupted', 'superseded', 'dropped')


@pytest.fixture(scope='module')
def bringup(ros2_cli: CliEnv) -> Iterator[tuple[CliEnv, Background]]:
    """The package's ros2_control bringup in /life (trajectory mode, mock hardware), shared by the module."""
    if (why := ros2_control_missing(ros2_cli.env)) is not None:
        pytest.skip(why)
    with fourbar_launch(ros2_cli, NAMESPACE, ['use_ros2_control:=true', 'mode:=trajectory'],
                        f'Configured and activated {JTC}') as launch:
        yield ros2_cli, launch


def _probe(env: CliEnv, steps: list[dict[str, Any]], tmp_path: Path, namespace: str = NAMESPACE) -> dict[str, Any]:
    """Run the steps; every step must have done what it asked (the failure shows the log and the node's states)."""
    path, out = tmp_path / 'steps.json', tmp_path / 'out.json'
    path.write_text(json.dumps(steps), encoding='utf-8')
    done = subprocess.run([sys.executable, str(PROBE), f'/{namespace}', str(path), str(out)], env=env.env,
                          capture_output=True, text=True, timeout=120 + 40 * len(steps), check=False)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    result = dict(json.loads(out.read_text(encoding='utf-8')))
    bad = [e for e in result['log'] if isinstance(e['result'], str)
           or (isinstance(e['result'], dict) and (e['result'].get('seen') is False or e['result'].get('ok') is False
                                                   or e['result'].get('returncode', 0) != 0))]
    assert len(result['log']) == len(steps) and not bad, (
        f'steps done {len(result["log"])} of {len(steps)}; failed: {bad}\nthe node\'s controller state, command '
        f'fate and reason over time: {result["statuses"]}\nlast status: {result["status"]}')
    return result


def _until(timeout: float = 30.0, **values: object) -> dict[str, Any]:
    return {'until': values, 'timeout': timeout}


def _fate(fate: str, theta: float, timeout: float = 30.0, **values: object) -> dict[str, Any]:
    """Wait until the node's status shows command ``theta`` (rad) with ``fate`` (a status a period old shows the
    command before)."""
    return _until(timeout, command_theta_rad=repr(theta), command_fate=fate, **values)


def _reached(result: dict[str, Any], theta: float) -> None:
    status = result['status']
    assert status['command_fate'] == 'reached', status
    assert abs(float(status['measured_theta_rad']) - theta) <= REACHED_TOLERANCE, status


ACTIVE = _until(controller_state='active')


def test_a_command_while_the_controller_is_inactive_is_reached_once_it_is_active(
        bringup: tuple[CliEnv, Background], tmp_path: Path) -> None:
    result = _probe(bringup[0], [
        ACTIVE,
        {'switch': {'deactivate': [JTC]}}, _until(controller_state='inactive'),
        {'command': 0.04}, _fate('held', 0.04, command_fate_reason='controller inactive'),
        {'switch': {'activate': [JTC]}}, _fate('reached', 0.04),
    ], tmp_path)
    _reached(result, 0.04)
    print(f'from the activation to the motion: {_motion_after(result, "switch", -1):.3f} s')
    _no_jump(result)


CFG = load_config(REPO / 'config' / 'antenna.yaml')
#: The driven joint's acceleration limit (rad/s^2) and the jerk of the node's plans there (rad/s^3: motor_jerk_limit
#: through reducer_ratio); one 100 Hz controller update of that jerk is PLANNED_STEP (rad/s^2).
ACCELERATION_LIMIT = CFG.motor_acceleration_limit / abs(CFG.reducer_ratio)
PLANNED_JERK = CFG.motor_jerk_limit / abs(CFG.reducer_ratio)
PLANNED_STEP = PLANNED_JERK * 0.01
#: A takeover may step the reference acceleration by this fraction of the limit beyond the plan's jerk.
TAKEOVER_ALLOWANCE = 0.05


def _no_jump(result: dict[str, Any]) -> None:
    """After every activation the controller's reference acceleration changes between two successive updates by no
    more than the plan's jerk over the time between the two samples plus TAKEOVER_ALLOWANCE of the limit, whoever's
    trajectory it follows. (The controller samples at its own accumulated time: a loaded manager that stalls an
    update samples the next one that much later, and a jerk-limited plan moves on by as much in between.)"""
    step, excess = _largest_step(result)
    print(f'after the activations, the controller\'s reference acceleration: the largest step in one update '
          f'{step:.1%} of the limit (the plan\'s jerk gives {PLANNED_STEP / ACCELERATION_LIMIT:.0%} per 10 ms), '
          f'{excess:+.1%} beyond the plan\'s jerk over the sampled time (bound {TAKEOVER_ALLOWANCE:.0%})')
    assert excess <= TAKEOVER_ALLOWANCE, (
        f'a step of {excess:.1%} of the acceleration limit beyond the plan\'s jerk in one update after an activation')


def _largest_step(result: dict[str, Any]) -> tuple[float, float]:
    """The largest change of joint_trajectory_controller's reference acceleration between two successive updates
    after an activation (of the controller or its hardware) and before the next event, and the largest by which it
    exceeds the plan's jerk times the time between the two samples, both as fractions of the driven joint's
    acceleration limit. A deactivation stops the reference at once; that stop is not a takeover."""
    events = [e for e in result['log'] if not {'pause', 'mark', 'until', 'moving'} & set(e['step'])]
    worst, excess = 0.0, -math.inf
    for event, after in zip(events, [*events[1:], None], strict=True):
        step = event['step']
        if not (step.get('switch', {}).get('activate') or step.get('hardware', [None, None])[1] == 'active'):
            continue
        end = after['at'] if after is not None else float('inf')
        window = [r for r in result['references'] if event['at'] <= r[0] < end]
        for (_, a0, s0, t0), (_, a1, s1, t1) in itertools.pairwise(window):
            if s1 - s0 < 0.015:  # successive updates (100 Hz; the controller's publisher drops one now and then)
                worst = max(worst, abs(a1 - a0))
                excess = max(excess, abs(a1 - a0) - PLANNED_JERK * max(t1 - t0, 0.0))
    return worst / ACCELERATION_LIMIT, excess / ACCELERATION_LIMIT


def _motion_after(result: dict[str, Any], kind: str, which: int) -> float:
    """Seconds from the start of the step of ``kind`` (the ``which``th) to the first measured driven joint
    1e-6 rad or more from where it was then (the probe samples it every 10 ms or so)."""
    at = [e['at'] for e in result['log'] if kind in e['step']][which]
    measured = [m for m in result['measured'] if m[0] >= at]
    moved = next(t for t, q in measured if abs(q - measured[0][1]) >= 1e-6)
    return float(moved - at)


def test_a_command_before_the_controller_is_spawned_is_reached_once_the_spawner_has_run(
        bringup: tuple[CliEnv, Background], tmp_path: Path) -> None:
    env = bringup[0]
    result = _probe(env, [
        ACTIVE,
        {'switch': {'deactivate': [JTC]}}, {'unload': JTC}, _until(controller_state='absent'),
        {'command': -0.03}, _fate('held', -0.03, command_fate_reason='controller absent'),
        {'run': [ros2(), 'run', 'controller_manager', 'spawner', JTC, '--controller-manager',
                 f'/{NAMESPACE}/controller_manager']},
        _fate('reached', -0.03),
    ], tmp_path)
    _reached(result, -0.03)


def test_a_command_interrupted_by_a_deactivation_resumes_and_is_reached(
        bringup: tuple[CliEnv, Background], tmp_path: Path) -> None:
    result = _probe(bringup[0], [
        ACTIVE, {'command': 0.0}, _fate('reached', 0.0),
        {'command': -0.09}, {'moving': True},
        {'switch': {'deactivate': [JTC]}}, _fate('held', -0.09, controller_state='inactive'),
        {'switch': {'activate': [JTC]}}, _fate('reached', -0.09),
    ], tmp_path)
    _reached(result, -0.09)
    assert any(s[2] == 'held' and s[3].startswith('interrupted (controller active -> inactive)')
               for s in result['statuses']), result['statuses']


def test_a_command_interrupted_ends_interrupted_where_the_parameter_says_so(
        bringup: tuple[CliEnv, Background], tmp_path: Path) -> None:
    env = bringup[0]
    node = f'/{NAMESPACE}/fourbar_node'
    param = [ros2(), 'param', 'set', node, 'resume_interrupted']
    result = _probe(env, [
        ACTIVE, {'command': 0.0}, _fate('reached', 0.0),
        {'run': [*param, 'false']},
        {'command': -0.09}, {'moving': True},
        {'switch': {'deactivate': [JTC]}}, _fate('interrupted', -0.09),
        {'switch': {'activate': [JTC]}}, ACTIVE,
        {'run': [*param, 'true']},
    ], tmp_path)
    assert result['status']['command_fate'] == 'interrupted', result['status']
    assert abs(float(result['status']['measured_theta_rad']) + 0.09) > REACHED_TOLERANCE, result['status']


def test_a_command_interrupted_by_its_hardware_component_resumes_and_is_reached(
        bringup: tuple[CliEnv, Background], tmp_path: Path) -> None:
    result = _probe(bringup[0], [
        ACTIVE, {'command': 0.0}, _fate('reached', 0.0),
        {'command': 0.08}, {'moving': True},
        {'hardware': [HARDWARE, 'inactive']}, _fate('held', 0.08, controller_state='hardware inactive'),
        {'hardware': [HARDWARE, 'active']}, _fate('reached', 0.08),
    ], tmp_path)
    _reached(result, 0.08)
    _no_jump(result)


def test_a_command_held_across_the_controller_managers_death_and_respawn_is_reached(
        bringup: tuple[CliEnv, Background], tmp_path: Path) -> None:
    # A manager killed (SIGKILL) stays in the graph until its participant's lease ends; the node hears of it first
    # by its broadcaster's silence (no measurement for measurement_timeout), then by its successor: the command is
    # held once (counted) and resumed once the respawned manager's spawners are done.
    result = _probe(bringup[0], [
        ACTIVE, {'command': 0.0}, _fate('reached', 0.0),
        {'command': -0.07}, {'moving': True},
        {'kill_manager': bringup[1].proc.pid}, _fate('reached', -0.07, timeout=60.0),
    ], tmp_path)
    _reached(result, -0.07)
    killed = next(e for e in result['log'] if 'kill_manager' in e['step'])
    assert killed['result']['killed'], killed
    held = int(result['status']['commands_held']) - int(killed['status']['commands_held'])
    assert held == 1, f'held {held} times after the kill; the node\'s states: {result["statuses"]}'


def _random_sequence(rng: np.random.Generator) -> list[dict[str, Any]]:
    """2-6 events at random times (0-0.8 s apart): commands in the tilt range, the controller and the hardware
    component switched off and on (the controller not activated while the hardware is inactive); then both active
    again. The whole spans well under the hold timeout (15 s)."""
    steps: list[dict[str, Any]] = []
    controller = hardware = True
    for _ in range(int(rng.integers(2, 7))):
        steps.append({'pause': round(float(rng.uniform(0.0, 0.8)), 3)})
        kind = rng.choice(['command', 'command', 'controller', 'hardware'])
        if kind == 'command':
            steps.append({'command': round(float(rng.uniform(-0.09, 0.09)), 4)})
        elif kind == 'controller' and (controller or hardware):
            # the manager refuses to activate it while its hardware component is inactive ("prepare command mode
            # switch was rejected")
            steps.append({'switch': {'deactivate' if controller else 'activate': [JTC]}})
            controller = not controller
        else:
            hardware = not hardware
            steps.append({'hardware': [HARDWARE, 'active' if hardware else 'inactive']})
    if not hardware:
        steps.append({'hardware': [HARDWARE, 'active']})
    if not controller:
        steps.append({'switch': {'activate': [JTC]}})
    return steps


def _sequences(bringup: tuple[CliEnv, Background], tmp_path: Path, count: int, seed: int) -> None:
    """``count`` random sequences, each started from a reached command and ended with the controller active: the
    last command in force is reached, every command of the sequence has one final fate or joined the one in force
    (a repeat of the same angle), nothing was refused by the controller's contract and no callback failed;
    no jump after an activation (``_no_jump``)."""
    rng = np.random.default_rng(seed)
    steps: list[dict[str, Any]] = []
    in_force: float | None = None  # the target of the command in force (none here ends otherwise than reached)

    def served(theta: float) -> float:
        """The command in force after ``theta``: itself, or the one it repeats (the same angle, joined)."""
        nonlocal in_force
        if in_force is None or theta != in_force:
            in_force = theta
        return in_force

    for i in range(count):
        theta = round(float(rng.uniform(-0.09, 0.09)), 4)
        start = served(theta)
        sequence = _random_sequence(rng)
        end, last = start, theta
        for s in sequence:
            if 'command' in s:
                end, last = served(s['command']), s['command']
        # The status waited for shows the last command received, so it counts that command's fate or repeat too.
        steps += [{'mark': i}, ACTIVE, {'command': theta}, _fate('reached', start, last_command_rad=repr(theta)),
                  {'mark': 'start'}, *sequence, _fate('reached', end, last_command_rad=repr(last)), {'mark': 'end'}]
    result = _probe(bringup[0], steps, tmp_path)
    marks = [e for e in result['log'] if 'mark' in e['step']]
    for start, end in zip(marks[1::3], marks[2::3], strict=True):
        i = result['log'].index(start)
        sequence = result['log'][i:result['log'].index(end)]
        commands = sum('command' in e['step'] for e in sequence)
        before, after = start['status'], end['status']
        grown = {f: int(after[f'commands_{f}']) - int(before[f'commands_{f}']) for f in (*FATES, 'repeated')}
        assert sum(grown.values()) == commands, (
            f'{commands} commands, final fates {grown}: {[e["step"] for e in sequence]}')
        refused = {k: v for k, v in after.items() if k.startswith('contract_refused_') and v != before[k]}
        assert not refused and after['callback_errors'] == '0', (refused, after['callback_errors'])
    _no_jump(result)


def test_random_lifecycles_end_with_the_last_command_reached(bringup: tuple[CliEnv, Background],
                                                               tmp_path: Path) -> None:
    _sequences(bringup, tmp_path, QUICK, 2026)


@pytest.mark.stress
def test_many_random_lifecycles_end_with_the_last_command_reached(bringup: tuple[CliEnv, Background],
                                                                  tmp_path: Path) -> None:
    _sequences(bringup, tmp_path, STRESS, 7)


@pytest.fixture(scope='module')
def forward(ros2_cli: CliEnv) -> Iterator[tuple[CliEnv, Background]]:
    """The package's ros2_control bringup in forward mode, in /lifefwd."""
    if (why := ros2_control_missing(ros2_cli.env)) is not None:
        pytest.skip(why)
    with fourbar_launch(ros2_cli, 'lifefwd', ['use_ros2_control:=true', 'mode:=forward'],
                        'Configured and activated forward_position_controller') as launch:
        yield ros2_cli, launch


def test_forward_mode_holds_a_command_while_its_controller_is_inactive_and_resumes_an_interrupted_one(
        forward: tuple[CliEnv, Background], tmp_path: Path) -> None:
    fwd = 'forward_position_controller'
    result = _probe(forward[0], [
        ACTIVE,
        {'switch': {'deactivate': [fwd]}}, _until(controller_state='inactive'),
        {'command': 0.04}, _fate('held', 0.04, command_fate_reason='controller inactive'),
        {'switch': {'activate': [fwd]}}, _fate('reached', 0.04),
        {'command': -0.08}, {'moving': True},
        {'switch': {'deactivate': [fwd]}}, _fate('held', -0.08, controller_state='inactive'),
        {'switch': {'activate': [fwd]}}, _fate('reached', -0.08),
    ], tmp_path, namespace='lifefwd')
    _reached(result, -0.08)


@pytest.fixture(scope='module')
def simulated(ros2_cli: CliEnv) -> Iterator[tuple[CliEnv, Background]]:
    """The package's launch with the simulated actuator in /simlife, controller_manager_msgs on the paths."""
    if (why := ros2_control_missing(ros2_cli.env)) is not None:
        pytest.skip(why)
    arguments = ['sim_actuator:=true', 'mode:=trajectory', 'robot_state_publisher:=false']
    with fourbar_launch(ros2_cli, 'simlife', arguments) as launch:
        yield ros2_cli, launch


def test_the_simulated_actuator_inactive_gives_the_real_controllers_fates(simulated: tuple[CliEnv, Background],
                                                                           tmp_path: Path) -> None:
    param = [ros2(), 'param', 'set', '/simlife/sim_actuator', 'controller_active']
    result = _probe(simulated[0], [
        ACTIVE,
        {'run': [*param, 'false']}, _until(controller_state='inactive'),
        {'command': 0.04}, _fate('held', 0.04, command_fate_reason='controller inactive'),
        {'run': [*param, 'true']}, _fate('reached', 0.04),
    ], tmp_path, namespace='simlife')
    _reached(result, 0.04)
