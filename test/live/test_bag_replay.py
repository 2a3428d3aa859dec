"""Every committed bag through the real node: fourbar_node, `fourbar record` and `fourbar replay` as separate
processes on a leased ROS_DOMAIN_ID. Each valid command must give exactly one JointState and one input_torque
equal to the core's values (bit for bit: the same scalar code on the same floats), each bad command none,
counted in /diagnostics; the recording must read back with rosbags and with an independent reader (mcap
package or sqlite3 + rclpy). The node's joint_states republish is off (``ONE_JOINT_STATE_PER_COMMAND``)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pytest
from diagnostic_msgs.msg import DiagnosticArray
from support.bag_support import (
    CONFIG,
    Tool,
    committed_bags,
    diag_values,
    expected_outputs,
    read_with_mcap,
    read_with_sqlite,
    run_tool,
    served,
    what_the_node_took,
)
from support.ros_support import ONE_JOINT_STATE_PER_COMMAND, NodeProcess, RosSession

from fourbar_ros.bags.storage import read_commands, read_messages
from fourbar_ros.config.antenna_config import AntennaConfig, load_config
from fourbar_ros.interface.topics import Storage

pytestmark = [pytest.mark.ros, pytest.mark.slow]

BAGS = committed_bags()
OUTPUTS = ('/joint_states', '/input_torque')


@pytest.fixture(scope='module')
def cfg() -> AntennaConfig:
    c = load_config(CONFIG)
    assert c.out_of_limits == 'reject' and not c.has_gravity_load
    return c


def check_outputs(recorded: dict[str, list[tuple[int, Any]]], thetas: list[float], cfg: AntennaConfig,
                  reader: str) -> None:
    """One JointState and one input_torque per served angle, in order, equal to the core."""
    joints = [m for _, m in recorded.get('/joint_states', [])]
    torques = [m for _, m in recorded.get('/input_torque', [])]
    assert len(joints) == len(thetas), f'{reader}: {len(joints)} joint_states for {len(thetas)} commands'
    assert len(torques) == len(thetas), f'{reader}: {len(torques)} input_torque for {len(thetas)} commands'
    driven = 0 if cfg.driven.value == 'gamma' else 1
    for i, (exp, js, tau) in enumerate(zip(expected_outputs(thetas, cfg), joints, torques, strict=True)):
        where = f'{reader}: answer {i} (theta = {exp.theta!r} rad)'
        assert list(js.name) == list(cfg.joint_names), where
        # Exact: the node (loads.pose_solver) and expected_outputs (AntennaLinkage.state) run the identical
        # scalar code, math-module only (rocker_angles' and torque_at's float paths), on the same float theta
        # (its CDR bytes are replayed unchanged), and float64 survives CDR exactly. No numpy on either side, so
        # a CPU whose SIMD transcendentals differ by an ulp changes nothing here.
        assert js.position[0] == exp.gamma, where
        assert js.position[1] == exp.delta, where
        assert js.position[2] == exp.gamma + exp.theta, where  # the coupler joint: the same addition
        assert js.effort[driven] == exp.torque and js.effort[1 - driven] == js.effort[2] == 0.0, where
        assert tau.data == exp.torque, where
        assert len(js.velocity) in (0, 3) and all(math.isfinite(v) for v in js.velocity), where


def replay_through_node(ros: RosSession, bag: Path, out: Path, cfg: AntennaConfig, node_args: list[str],
                        replay_args: list[str], policy: str | None = None) -> dict[str, str]:
    """Node + recorder + replay; check the recording. Returns the final diagnostics values."""
    stream = read_commands(bag)
    thetas = served(stream.values, cfg, policy)
    n = len(thetas)
    assert n > 0
    diagnostics = ros.collect(DiagnosticArray, '/diagnostics', qos=100)
    env = ros.env()
    try:
        # Diagnostics every 0.1 s: the final counts arrive within 0.1 s of the last command, not 1 s.
        with NodeProcess(['--ros-args', '--params-file', str(CONFIG), *ONE_JOINT_STATE_PER_COMMAND,
                          '-p', 'diagnostics_period:=0.1', *node_args], env) as node, \
                Tool(['record', out, '--storage', stream.storage, '--stop-after', f'joint_states={n}',
                      '--stop-after', f'input_torque={n}'], env) as recorder:
            recorder.wait_line('recording')
            rc, lines, _ = run_tool(['replay', bag, '--no-progress', *replay_args], env)
            assert rc == 0, lines
            try:
                assert recorder.wait() == 0, recorder.lines
                # The first status counting every command of the bag carries the final counts.
                final = diagnostics.wait_match(
                    lambda m: diag_values(m).get('commands_received') == str(len(stream)))
            except AssertionError as exc:
                raise AssertionError(f'{exc}; {what_the_node_took(diagnostics, len(stream), n)}') from None
            assert any(f'wrote {out}' in line for line in recorder.lines), recorder.lines
            assert node.running()
    finally:
        ros.uncollect(diagnostics)
    values = diag_values(final)

    recorded = read_messages(out)  # rosbags
    check_outputs(recorded, thetas, cfg, 'rosbags')
    independent = read_with_mcap(out) if stream.storage is Storage.MCAP else read_with_sqlite(out)
    check_outputs(independent, thetas, cfg, 'mcap' if stream.storage is Storage.MCAP else 'sqlite3+rclpy')
    assert int(values['joint_states_published']) == n and int(values['input_torque_published']) == n
    return values


@pytest.mark.parametrize('bag', BAGS, ids=[b.name for b in BAGS])
def test_lockstep_replay_of_every_bag(bag: Path, ros: RosSession, cfg: AntennaConfig, tmp_path: Path) -> None:
    values = replay_through_node(ros, bag, tmp_path / 'outputs', cfg, [], ['--as-fast-as-node-keeps-up'])
    stream = read_commands(bag)
    not_finite = sum(1 for v in stream.values if not math.isfinite(v))
    outside = sum(1 for v in stream.values if math.isfinite(v) and not cfg.theta_min <= v <= cfg.theta_max)
    rejected = (int(values['commands_rejected_not_finite']) + int(values['commands_rejected_out_of_limits'])
                + int(values['commands_rejected_out_of_reach']))
    assert int(values['commands_rejected_not_finite']) == not_finite
    assert rejected == not_finite + outside
    assert int(values['commands_accepted']) == len(stream) - rejected
    assert int(values['commands_clamped']) == 0


def test_clamp_policy_serves_the_nearer_limit(ros: RosSession, cfg: AntennaConfig, tmp_path: Path) -> None:
    bag = committed_bags()[0].parent / 'bad_values_mcap'
    values = replay_through_node(ros, bag, tmp_path / 'outputs', cfg, ['-p', 'out_of_limits:=clamp'],
                                 ['--as-fast-as-node-keeps-up'], policy='clamp')
    stream = read_commands(bag)
    outside = sum(1 for v in stream.values if math.isfinite(v) and not cfg.theta_min <= v <= cfg.theta_max)
    assert outside > 0 and int(values['commands_clamped']) == outside
    assert int(values['commands_rejected_not_finite']) == sum(1 for v in stream.values if not math.isfinite(v))


@pytest.mark.parametrize('name, rate', [('fast_ramp_mcap', 1.0), ('steps_sqlite3', 4.0), ('jitter_mcap', 2.0)])
def test_timed_replay_loses_nothing(name: str, rate: float, ros: RosSession, cfg: AntennaConfig,
                                    tmp_path: Path) -> None:
    """Recorded timing (scaled by the rate factor), no waiting for answers: still one answer per command."""
    bag = committed_bags()[0].parent / name
    replay_through_node(ros, bag, tmp_path / 'outputs', cfg, [], ['--rate', str(rate)])


def test_pipelined_lockstep_loses_nothing(ros: RosSession, cfg: AntennaConfig, tmp_path: Path) -> None:
    """Up to 32 answers outstanding (below the node's queue of 1000): still exactly one answer per command."""
    bag = committed_bags()[0].parent / 'jitter_sqlite3'
    replay_through_node(ros, bag, tmp_path / 'outputs', cfg, [], ['--as-fast-as-node-keeps-up', '--window', '32'])


def test_replay_without_a_node_fails_in_one_line(ros: RosSession) -> None:
    rc, lines, out = run_tool(['replay', committed_bags()[0], '--wait', '1', '--no-progress'], ros.env())
    assert rc == 1 and out == ''
    assert lines == [f'fourbar replay: error: no subscriber on /antenna_angle_cmd within 1 s '
                     f'(is fourbar_node running with ROS_DOMAIN_ID={ros.domain_id} in the namespace /? a node in '
                     'another namespace NS: --topic /NS/antenna_angle_cmd)']


def test_lockstep_reports_a_missing_answer(ros: RosSession, tmp_path: Path) -> None:
    """Predicting answers the node will not give (a clamp file against a rejecting node) must fail, not hang."""
    params = tmp_path / 'clamp.yaml'
    params.write_text(CONFIG.read_text().replace('out_of_limits: reject', 'out_of_limits: clamp'))
    bag = committed_bags()[0].parent / 'bad_values_mcap'
    with NodeProcess(['--ros-args', '--params-file', str(CONFIG)], ros.env()):
        rc, lines, _ = run_tool(['replay', bag, '--as-fast-as-node-keeps-up', '--params', params,
                                 '--deadline', '1', '--no-progress'], ros.env())
    assert rc == 1
    assert len(lines) == 1 and lines[0].startswith('fourbar replay: error: no answer on /input_torque to command ')
