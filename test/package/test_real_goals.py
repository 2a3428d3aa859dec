"""fourbar_node with ``trajectory_interface: action`` on the real joint_trajectory_controller (the package's launch
file, mock hardware): a goal that completes, a goal the next command preempts, and a goal the controller aborts, each
as the node's diagnostics count it, with the controller's own error code and string.

Runs where the ros2 command line, launch_ros and ros2_control are installed; skipped elsewhere with the reason.
"""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any, NamedTuple

import pytest
import yaml
from support.colcon_support import CliEnv, launch_missing, ros2_cli_missing
from support.paths import REPO
from support.ros2_control_support import ros2_control_missing

if (_why := ros2_cli_missing() or launch_missing()) is not None:
    pytest.skip(_why, allow_module_level=True)

from support.ros_cli_support import Background, fourbar_launch  # psutil: with ros2cli

from fourbar_ros.config.antenna_config import load_config

pytestmark = [pytest.mark.ros, pytest.mark.slow]

PROBE = REPO / 'test' / 'support' / 'goal_probe.py'
CONTROLLERS = REPO / 'config' / 'controllers.yaml'
ANTENNA = REPO / 'config' / 'antenna.yaml'
#: joint_trajectory_controller's path tolerance (rad) in the aborting controllers file; see the test.
TIGHT_PATH_TOLERANCE = 1e-6
NAMESPACE = 'goals'


class Bringup(NamedTuple):
    """The command line's environment and the running launch (its output so far)."""

    cli: CliEnv
    launch: Background


def _bringup(env: CliEnv, namespace: str, *extra: str) -> Iterator[Bringup]:
    if (why := ros2_control_missing(env.env)) is not None:
        pytest.skip(why)
    arguments = ['use_ros2_control:=true', 'mode:=trajectory', 'trajectory_interface:=action', *extra]
    with fourbar_launch(env, namespace, arguments, 'Configured and activated joint_trajectory_controller') as launch:
        yield Bringup(env, launch)


def _held_back(tmp_path: Path) -> list[str]:
    """Launch arguments for a drive that does not move: the package's parameters with the mock hardware's
    ``disable_commands`` (its state stays where it started) and its controllers file with joint_trajectory_controller's
    path tolerance TIGHT_PATH_TOLERANCE (the node's replan_tolerance below it, as the node requires)."""
    settings = yaml.safe_load(CONTROLLERS.read_text(encoding='utf-8'))
    settings['/**/joint_trajectory_controller']['ros__parameters']['constraints']['rocker_ab_joint'][
        'trajectory'] = TIGHT_PATH_TOLERANCE
    controllers = tmp_path / 'tight_controllers.yaml'
    controllers.write_text(yaml.safe_dump(settings), encoding='utf-8')
    params = yaml.safe_load(ANTENNA.read_text(encoding='utf-8'))
    params['/**']['ros__parameters']['hardware_parameters'] = ['disable_commands=true']
    params['/**']['ros__parameters']['replan_tolerance'] = TIGHT_PATH_TOLERANCE / 2.0
    antenna = tmp_path / 'held_antenna.yaml'
    antenna.write_text(yaml.safe_dump(params), encoding='utf-8')
    return [f'controllers_file:={controllers}', f'params_file:={antenna}']


@pytest.fixture(scope='module')
def bringup(request: pytest.FixtureRequest, ros2_cli: CliEnv, tmp_path_factory: pytest.TempPathFactory,
            ) -> Iterator[Bringup]:
    """The package's ros2_control bringup in /goals, the node sending goals, as shipped ('package') or with the drive
    held back (``_held_back``: 'held'); one at a time (both would publish the same status name on /diagnostics),
    each shared by the tests that ask for it."""
    extra = [] if request.param == 'package' else _held_back(tmp_path_factory.mktemp('held'))
    yield from _bringup(ros2_cli, NAMESPACE, *extra)


def _probe(env: CliEnv, namespace: str, commands: list[tuple[float, float]], until: dict[str, int],
           tmp_path: Path, settle: float = 0.0) -> dict[str, Any]:
    steps, out = tmp_path / 'steps.json', tmp_path / 'out.json'
    steps.write_text(json.dumps({'commands': [{'command': c, 'after': a} for c, a in commands], 'until': until,
                                 'timeout': 30.0, 'settle': settle}), encoding='utf-8')
    done = subprocess.run([sys.executable, str(PROBE), f'/{namespace}', str(steps), str(out)], env=env.env,
                          capture_output=True, text=True, timeout=150, check=False)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    return dict(json.loads(out.read_text(encoding='utf-8')))


def _grown(result: dict[str, Any], *keys: str) -> dict[str, int]:
    return {k: int(result['status'][k]) - int(result['before'][k]) for k in keys}


def _driven(theta: float) -> float:
    cfg = load_config(ANTENNA)
    return float(cfg.linkage.rocker_angles(theta, cfg.branch)[0])


KEYS = ('goals_sent', 'goals_accepted', 'goals_rejected', 'goals_succeeded', 'goals_aborted', 'goals_preempted',
        'goals_canceled', 'goals_lost', 'goals_not_sent_no_server')


@pytest.mark.parametrize('bringup', ['package'], indirect=True)
def test_a_goal_that_completes_is_counted_succeeded(bringup: Bringup, tmp_path: Path) -> None:
    result = _probe(bringup.cli, NAMESPACE, [(0.05, 0.0)], {'goals_succeeded': 1}, tmp_path, settle=0.3)
    assert _grown(result, *KEYS) == {**dict.fromkeys(KEYS, 0), 'goals_sent': 1, 'goals_accepted': 1,
                                     'goals_succeeded': 1}, result
    assert abs(result['measured'] - _driven(0.05)) < 1e-3, result  # the mock joint at the commanded angle
    assert int(result['status']['trajectories_sent']) >= 1


@pytest.mark.parametrize('bringup', ['package'], indirect=True)
def test_a_goal_the_next_command_supersedes_is_counted_preempted(bringup: Bringup, tmp_path: Path) -> None:
    # The second command arrives while the first goal's motion runs (a tilt to -0.06 rad from level or above takes
    # over a second at the default limits): the controller accepts the new goal and ends the running one as ABORTED
    # with INVALID_GOAL, "Current goal preempted by new incoming action."; the node counts that as preempted, and
    # the second succeeds.
    result = _probe(bringup.cli, NAMESPACE, [(-0.06, 0.0), (0.0, 0.4)], {'goals_succeeded': 1, 'goals_preempted': 1},
                    tmp_path, settle=0.3)
    assert _grown(result, *KEYS) == {**dict.fromkeys(KEYS, 0), 'goals_sent': 2, 'goals_accepted': 2,
                                     'goals_succeeded': 1, 'goals_preempted': 1}, result
    assert abs(result['measured'] - _driven(0.0)) < 1e-3, result


@pytest.mark.parametrize('bringup', ['held'], indirect=True)
def test_a_goal_the_controller_aborts_is_counted_with_its_reason(bringup: Bringup, tmp_path: Path) -> None:
    # Why it aborts: the held-back joint stays where it was, so the controller's reference leaves it as soon as the
    # motion starts; a path tolerance of 1e-6 rad is exceeded within a few updates: the controller aborts with
    # PATH_TOLERANCE_VIOLATED (-4) and holds. (A mock that follows its commands is no test of this: the controller
    # compares the measured position, its previous command, with the reference at its own clock, which a regular
    # 100 Hz loop keeps within speed * period jitter, often below 1e-6 rad: such a goal succeeded on a busy machine.)
    result = _probe(bringup.cli, NAMESPACE, [(0.05, 0.0)], {'goals_aborted': 1}, tmp_path, settle=1.5)
    assert _grown(result, *KEYS) == {**dict.fromkeys(KEYS, 0), 'goals_sent': 1, 'goals_accepted': 1,
                                     'goals_aborted': 1}, f'{result}\nlaunch log:\n{bringup.launch.output()[-4000:]}'
    status = result['status']
    assert status['last_goal_failure'] == 'aborted', status
    assert status['last_goal_error_code'] == '-4 (PATH_TOLERANCE_VIOLATED)', status
    assert status['last_goal_error_string'] == 'Aborted due to path tolerance violation', status
    # the command's fate, from the same callback: interrupted with the controller's reason, not resumed
    assert status['command_fate'] == 'interrupted', status
    assert 'PATH_TOLERANCE_VIOLATED' in status['command_fate_reason'], status
    assert abs(result['measured'] - _driven(0.05)) > 1e-3, result  # held short of the commanded angle
    bringup.launch.wait_output(lambda t: 'joint_trajectory_controller aborted a FollowJointTrajectory goal: error_code '
                               '-4 (PATH_TOLERANCE_VIOLATED): Aborted due to path tolerance violation' in t,
                               "the node's warning naming the controller's reason")
