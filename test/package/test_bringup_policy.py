"""The package's ros2_control bringup started with ``enclaves:=true`` (trajectory mode, the action interface, mock
hardware) against its SROS2 policy (``config.security``): every process it starts carries its enclave, and every
node, as the ROS graph shows it, uses exactly what its profile allows, the options this bringup leaves off (sim time,
the antenna sensor) aside; the spawners, seen while they run, nothing it does not allow. That the middleware
enforces the policy is test/config/test_security_policy.py's (it needs DDS security plugins).

Runs where the ros2 command line, launch_ros and ros2_control are installed; skipped elsewhere with the reason.
"""

from __future__ import annotations

import json
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import NamedTuple

import pytest
from support.colcon_support import CliEnv, launch_missing, ros2_cli_missing
from support.paths import REPO
from support.policy_rules import as_graph, resolve, rules
from support.ros2_control_support import ros2_control_missing

if (_why := ros2_cli_missing() or launch_missing()) is not None:
    pytest.skip(_why, allow_module_level=True)

import psutil  # with ros2cli
from support.ros_cli_support import Background, fourbar_launch

from fourbar_ros.config.security import BRINGUP_ENCLAVES, DEFAULT_HARDWARE_ID, enclave, policy_xml
from fourbar_ros.interface.topics import ANTENNA_SENSOR_FLOAT64, NODE_NAME, Mode, trajectory_topic

pytestmark = [pytest.mark.ros, pytest.mark.slow]

NAMESPACE = 'secure'
PROBE = REPO / 'test' / 'support' / 'graph_probe.py'
#: The bringup's nodes that run throughout: (enclave, node).
LONG_LIVED = ((enclave(Mode.TRAJECTORY), NODE_NAME),
              (BRINGUP_ENCLAVES['robot_state_publisher'], 'robot_state_publisher'),
              (BRINGUP_ENCLAVES['controller_manager'], 'controller_manager'),
              (BRINGUP_ENCLAVES['controller_manager'], DEFAULT_HARDWARE_ID),
              (BRINGUP_ENCLAVES['controller_manager'], 'joint_state_broadcaster'),
              (BRINGUP_ENCLAVES['controller_manager'], 'joint_trajectory_controller'))
#: What the policy allows that this bringup does not turn on: /clock (use_sim_time) anywhere; fourbar_node's
#: antenna sensor and its trajectory topic (trajectory_interface: action sends goals instead).
OFF = {'/clock'}
NODE_OFF = {ANTENNA_SENSOR_FLOAT64.name, trajectory_topic('joint_trajectory_controller').name}
#: The enclave each executable starts in.
EXECUTABLE_ENCLAVE = {'fourbar_node': enclave(Mode.TRAJECTORY),
                      'robot_state_publisher': BRINGUP_ENCLAVES['robot_state_publisher'],
                      'ros2_control_node': BRINGUP_ENCLAVES['controller_manager'],
                      'spawner': BRINGUP_ENCLAVES['spawner']}
DEADLINE_S = 120.0


class Observed(NamedTuple):
    """The policy's profiles (resolved for the namespace), the graph the probe saw per node, and the command lines
    of the launch's processes running once it was done."""

    allowed: dict[tuple[str, str], dict[str, set[str]]]
    graph: dict[str, dict[str, list[str]]]
    processes: list[list[str]]


def _fqn(node: str) -> str:
    return f'/{NAMESPACE}/{node}'


def _expected(allowed: dict[tuple[str, str], dict[str, set[str]]], key: tuple[str, str]) -> dict[str, set[str]]:
    off = {resolve(name, f'/{NAMESPACE}', key[1]) for name in (OFF | NODE_OFF if key[1] == NODE_NAME else OFF)}
    return {kind: names - off for kind, names in as_graph(allowed[key], f'/{NAMESPACE}', key[1]).items()}


@pytest.fixture(scope='module')
def observed(ros2_cli: CliEnv, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Observed]:
    """The graph probe started first (to see the spawners too), then the bringup; shared by the module."""
    if (why := ros2_control_missing(ros2_cli.env)) is not None:
        pytest.skip(why)
    work = tmp_path_factory.mktemp('policy')
    allowed = rules(policy_xml(f'/{NAMESPACE}'), f'/{NAMESPACE}')
    expected = {_fqn(node): {k: sorted(v) for k, v in _expected(allowed, (path, node)).items()}
                for path, node in LONG_LIVED}
    spec, out, ready = work / 'expected.json', work / 'graph.json', work / 'ready'
    spec.write_text(json.dumps({'deadline': DEADLINE_S, 'nodes': expected}), encoding='utf-8')
    probe = Background([sys.executable, str(PROBE), str(spec), str(out), str(ready)], ros2_cli.env)
    try:
        deadline = time.monotonic() + 60.0
        while not ready.exists() and probe.proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)  # polls for the probe's ready file, bounded by the deadline
        assert ready.exists(), f'the graph probe did not start: {probe.output()[-2000:]}'
        with fourbar_launch(ros2_cli, NAMESPACE, ['use_ros2_control:=true', 'mode:=trajectory',
                                                  'trajectory_interface:=action', 'enclaves:=true'],
                            'Configured and activated joint_trajectory_controller') as launch:
            assert probe.wait_exit(DEADLINE_S + 30.0) == 0, probe.output()[-3000:]
            processes = []
            for p in launch.descendants():
                try:
                    processes.append(p.cmdline())
                except psutil.Error:  # it ended meanwhile (a spawner)
                    continue
            yield Observed(allowed, json.loads(out.read_text(encoding='utf-8')), processes)
    finally:
        probe.kill()


@pytest.mark.parametrize('key', LONG_LIVED, ids=lambda k: k[1])
def test_each_node_uses_exactly_what_its_profile_allows(observed: Observed, key: tuple[str, str]) -> None:
    want = _expected(observed.allowed, key)
    got = {k: set(v) for k, v in observed.graph.get(_fqn(key[1]), {}).items()}
    assert got, f'{_fqn(key[1])} never seen; the graph showed {sorted(observed.graph)}'
    diff = {k: {'not allowed': sorted(got[k] - want[k]), 'allowed, unused': sorted(want[k] - got[k])}
            for k in want if got[k] != want[k]}
    assert not diff, f'{_fqn(key[1])} in enclave {key[0]}: {diff}'


def test_nodes_that_came_and_went_used_only_what_their_profile_allows(observed: Observed) -> None:
    # fourbar_node has a profile per mode: this bringup's is the trajectory mode's
    profiles = {node: path for path, node in observed.allowed if path in BRINGUP_ENCLAVES.values()}
    profiles[NODE_NAME] = enclave(Mode.TRAJECTORY)
    ours = [n for n in observed.graph if n.startswith(f'/{NAMESPACE}/')]
    unknown = [n for n in ours if n.rsplit('/', 1)[1] not in profiles]
    assert not unknown, f'nodes of the bringup with no profile in the policy: {unknown}'
    for fqn in ours:
        node = fqn.rsplit('/', 1)[1]
        allowed = as_graph(observed.allowed[profiles[node], node], f'/{NAMESPACE}', node)
        extra = {k: sorted(set(v) - allowed[k]) for k, v in observed.graph[fqn].items() if set(v) - allowed[k]}
        assert not extra, f'{fqn} used what enclave {profiles[node]} does not allow: {extra}'


def test_every_process_of_the_bringup_runs_in_its_enclave(observed: Observed) -> None:
    seen = set()
    for cmd in observed.processes:
        if '--ros-args' not in cmd:
            continue  # ros2 launch itself
        name = next((n for n in EXECUTABLE_ENCLAVE if any(Path(a).name in (n, f'{n}.bin') for a in cmd)), None)
        assert name is not None, f'a process of the bringup with no enclave of the package: {cmd}'
        at = cmd.index('--enclave') if '--enclave' in cmd else -1
        assert at >= 0 and cmd[at + 1] == EXECUTABLE_ENCLAVE[name], cmd
        seen.add(name)
    assert {'fourbar_node', 'robot_state_publisher', 'ros2_control_node'} <= seen, observed.processes
