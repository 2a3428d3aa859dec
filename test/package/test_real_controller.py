"""The real ros2_control stack judges the package's model of joint_trajectory_controller and its simulated actuator:
the package's launch file brings up the controller manager (mock hardware, the package's robot model and
controllers file) once for the module; random trajectories of every kind and fourbar_node's own plans go to the real
controller, and its reference, update by update (``~/controller_state``), is compared with the motion model's and
the simulated follower's.

Runs where the ros2 command line, launch_ros and ros2_control are installed; skipped elsewhere with the reason.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
import yaml
from support.colcon_support import CliEnv, launch_missing, ros2, ros2_cli_missing
from support.paths import REPO
from support.real_controller import Judged, judged, message_points, random_steps
from support.ros2_control_support import ros2_control_missing

if (_why := ros2_cli_missing() or launch_missing()) is not None:
    pytest.skip(_why, allow_module_level=True)

from support.ros_cli_support import Background, wait_node  # psutil: with ros2cli

from fourbar_ros.config.antenna_config import load_config
from fourbar_ros.config.controllers import trajectory_controller
from fourbar_ros.rules.controller_contract import check_trajectory

pytestmark = [pytest.mark.ros, pytest.mark.slow]

NAMESPACE = 'judge'
JUDGE = REPO / 'test' / 'support' / 'jtc_judge.py'
#: The model and the controller evaluate the same polynomials at the same times in float64; they differ by the
#: rounding of a different operation order (about 1e-15 rad at these magnitudes). 1e-9 rad leaves room for that
#: and catches any difference of the motion itself (a wrong lead-in, degree or time is 1e-4 rad or more here).
BOUND_RAD = 1e-9
#: Random trajectories in `make test`; `make test-stress` sends FOURBAR_JUDGE_TRAJECTORIES (default 200).
QUICK, STRESS = 12, int(os.environ.get('FOURBAR_JUDGE_TRAJECTORIES', '200'))


@pytest.fixture(scope='module')
def bringup(ros2_cli: CliEnv) -> Iterator[CliEnv]:
    """The package's ros2_control bringup in /judge (trajectory mode, mock hardware), shared by the module."""
    if (why := ros2_control_missing(ros2_cli.env)) is not None:
        pytest.skip(why)
    launch = Background([ros2(), 'launch', 'fourbar_ros', 'fourbar.launch.py', f'namespace:={NAMESPACE}',
                         'use_ros2_control:=true', 'mode:=trajectory', 'rviz:=false'], ros2_cli.env, cwd=ros2_cli.cwd)
    try:
        wait_node(ros2_cli.env, f'/{NAMESPACE}/fourbar_node')
        launch.wait_output(lambda t: 'Configured and activated joint_trajectory_controller' in t,
                           'the trajectory controller active')
        yield ros2_cli
        assert launch.interrupt(group=True) == 0, launch.stdout[-2000:] + launch.stderr[-2000:]
    finally:
        launch.kill()


def _judge(env: CliEnv, steps: list[dict[str, object]], tmp_path: Path) -> dict[str, object]:
    cases, out = tmp_path / 'steps.json', tmp_path / 'recording.json'
    cases.write_text(json.dumps(steps), encoding='utf-8')
    done = subprocess.run([sys.executable, str(JUDGE), f'/{NAMESPACE}', str(cases), str(out)], env=env.env,
                          capture_output=True, text=True, timeout=120 + 3 * len(steps), check=False)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    return dict(json.loads(out.read_text(encoding='utf-8')))


def _report(results: list[Judged]) -> str:
    rows = {}
    for r in results:
        key = (r.kind, r.stamp)
        worst = rows.get(key, (0, 0.0, 0.0, 0))
        rows[key] = (worst[0] + 1, max(worst[1], r.model), max(worst[2], r.follower), worst[3] + r.updates)
    return '\n'.join(f'{kind:>3} {stamp:>6}: {n:3d} trajectories, {u:5d} updates, model {m:.2e} rad, '
                     f'simulated {f:.2e} rad' for (kind, stamp), (n, m, f, u) in sorted(rows.items()))


def _check(env: CliEnv, steps: list[dict[str, object]], tmp_path: Path) -> list[Judged]:
    cfg = load_config(env.prefix / 'share' / 'fourbar_ros' / 'config' / 'antenna.yaml')
    path = env.prefix / 'share' / 'fourbar_ros' / 'config' / 'controllers.yaml'
    settings = trajectory_controller(str(path), 'joint_trajectory_controller')
    rate = yaml.safe_load(path.read_text(encoding='utf-8'))['/**/controller_manager']['ros__parameters']['update_rate']
    recording = _judge(env, steps, tmp_path)
    results = judged(recording, settings, cfg.driven_joint, 1.0 / rate)
    report = _report(results)
    print(report)
    assert results, 'no trajectory was taken over'
    # What the package's contract accepts, the real controller took over, and what it refuses, the controller did not.
    verdicts = [check_trajectory(settings, [cfg.driven_joint], message_points(t['points']), t['stamp'], t['received'])
                for t in recording['trajectories']]
    taken = {r.index for r in results}
    refused = [f'{i}: {v.reason}' for i, v in enumerate(verdicts) if v is not None]
    print(f'{len(recording["trajectories"])} trajectories, {len(taken)} taken over; refused by the contract:', refused)
    disagree = [(i, v) for i, v in enumerate(verdicts) if (v is None) != (i in taken)]
    assert not disagree, f'the contract and the real controller disagree on {len(disagree)}: {disagree[:5]}'
    off = [r for r in results if r.model > BOUND_RAD or r.follower > BOUND_RAD]
    assert not off, f'{len(off)} trajectories off the real controller by more than {BOUND_RAD} rad:\n{report}'
    return results


def test_the_model_follows_the_real_controller_on_random_trajectories(bringup: CliEnv, tmp_path: Path) -> None:
    steps = random_steps(np.random.default_rng(2026), QUICK, 0.76, 0.96)
    _check(bringup, steps, tmp_path)


def test_the_model_follows_the_real_controller_on_the_nodes_plans(bringup: CliEnv, tmp_path: Path) -> None:
    commands = [0.05, -0.02, 0.06, 0.0]
    steps = [{'command': theta, 'after': 0.0 if i == 0 else 0.4} for i, theta in enumerate(commands)]
    results = _check(bringup, steps, tmp_path)
    assert len(results) >= len(commands), f'{len(commands)} commands, {len(results)} trajectories taken over'


@pytest.mark.stress
def test_the_model_follows_the_real_controller_on_many_random_trajectories(bringup: CliEnv, tmp_path: Path) -> None:
    steps = random_steps(np.random.default_rng(7), STRESS, 0.76, 0.96)
    _check(bringup, steps, tmp_path)
