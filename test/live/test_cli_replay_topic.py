"""`fourbar replay --bag-topic`: a namespaced recording (two antennas, /robot/... and /spare/...) replayed into
fourbar_node started in /robot, through the real middleware on a leased domain id."""

from __future__ import annotations

from pathlib import Path

import pytest
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64
from support.bag_support import CONFIG, expected_outputs, run_tool
from support.ros_support import ONE_JOINT_STATE_PER_COMMAND, NodeProcess, RosSession, sync_probe

from fourbar_ros.bags.storage import FLOAT64, AtomicBagWriter, float64_cdr, read_commands, recorded_qos
from fourbar_ros.config.antenna_config import load_config

pytestmark = [pytest.mark.ros, pytest.mark.slow]

T0 = 1_700_000_000_000_000_000  # ns since the epoch


def _two_antenna_bag(path: Path, robot: list[float], spare: list[float]) -> Path:
    """Commands of two namespaced nodes, as `ros2 bag record` of a robot with two antennas writes them."""
    with AtomicBagWriter(path) as bag:
        conns = {ns: bag.add_topic(f'/{ns}/antenna_angle_cmd', FLOAT64, [recorded_qos()])
                 for ns in ('robot', 'spare')}
        for k, (a, b) in enumerate(zip(robot, spare, strict=True)):
            bag.write(conns['robot'], T0 + 10_000_000 * k, float64_cdr(a))
            bag.write(conns['spare'], T0 + 10_000_000 * k + 1, float64_cdr(b))
    return path


def test_namespaced_recording_replays_with_bag_topic(ros: RosSession, tmp_path: Path) -> None:
    cfg = load_config(CONFIG)
    n = 40
    robot = [cfg.theta_min + (cfg.theta_max - cfg.theta_min) * (k + 0.5) / n for k in range(n)]
    spare = [0.0] * n
    bag = _two_antenna_bag(tmp_path / 'two_antennas', robot, spare)
    assert read_commands(bag, '/robot/antenna_angle_cmd').values == tuple(robot)

    # Two */antenna_angle_cmd topics: without the option the command topic is ambiguous (one line, status 2).
    rc, lines, _ = run_tool(['replay', bag, '--no-progress', '--wait', '1'], ros.env())
    assert rc == 2 and len(lines) == 1 and lines[0].startswith('fourbar replay: error: '), lines
    assert '/robot/antenna_angle_cmd' in lines[0] and '/spare/antenna_angle_cmd' in lines[0]

    answers = ros.collect(JointState, '/robot/joint_states')
    try:
        with NodeProcess(['--ros-args', '--params-file', str(CONFIG), '-r', '__ns:=/robot',
                          *ONE_JOINT_STATE_PER_COMMAND], ros.env()) as node:
            ros.wait_publishers(answers)  # matched with the node's publisher before the first answer
            # ... and the node with this subscription: it publishes joint_states only while it sees a subscriber.
            # Probe commands come back once it does (then the answers are cleared).
            probe = ros.publisher(Float64, '/robot/antenna_angle_cmd')
            ros.wait_subscribers(probe)
            probes = [cfg.theta_min + (cfg.theta_max - cfg.theta_min) * (k + 0.5) / 600 for k in range(600)]
            sync_probe(lambda t: probe.publish(Float64(data=t)), [answers], probes,
                       lambda col, msg, t: bool(msg.position[0] == expected_outputs([t], cfg)[0].gamma))
            ros.destroy(probe)
            rc, lines, _ = run_tool(['replay', bag, '--bag-topic', '/robot/antenna_angle_cmd',
                                     '--as-fast-as-node-keeps-up', '--no-progress'], ros.env())
            assert rc == 0, lines
            # Published on the recorded name, answered on the node's input_torque next to it (one per command).
            assert f'{n} answers on /robot/input_torque' in lines[-1], lines
            got = answers.wait_count(n)
            assert node.running()
    finally:
        ros.uncollect(answers)
    assert len(got) == n
    for exp, msg in zip(expected_outputs(robot, cfg), got, strict=True):
        # Exact: the node and expected_outputs run the same scalar core code on the same float theta.
        assert (msg.position[0], msg.position[1]) == (exp.gamma, exp.delta)
