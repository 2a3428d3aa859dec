"""fourbar_drive_bridge against the simulated backend: in-process on the session's domain (states before any
command, commands through the rules, a failing backend counted), then as a process (SIGTERM exits 0, a bad
backend exits 2)."""

from __future__ import annotations

import math
import signal
import subprocess
import sys
from collections.abc import Iterator
from typing import Any

import pytest

pytest.importorskip('rclpy')

from diagnostic_msgs.msg import DiagnosticArray
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState
from support.ros_support import RosSession

from fourbar_ros.config.antenna_config import default_config
from fourbar_ros.drive.backend import Reading, SimulatedBackend
from fourbar_ros.drive.bridge_node import NODE_NAME, DriveBridge
from fourbar_ros.drive.rules import DriveLimits
from fourbar_ros.motion.limits import JointLimits

pytestmark = pytest.mark.ros

CFG = default_config()
JOINT = CFG.driven_joint
START = 0.95  # rad: inside the range, away from the model's initial value (0.8632 rad)
SPEED = JointLimits.from_config(CFG).at_rocker(1)
LIMITS = DriveLimits.from_config(CFG)
TIMEOUT = 30.0


class FlakyBackend(SimulatedBackend):
    """The simulated drive whose read raises while ``failing``."""

    failing = False

    def read(self) -> Reading:
        if self.failing:
            raise OSError('the bus is down')
        return super().read()


def _command(position: float, joint: str = JOINT) -> JointState:
    msg = JointState()
    msg.name = [joint]
    msg.position = [position]
    return msg


class Bridge:
    """An in-process bridge on topics of its own, its backend, and the test's ends of its topics."""

    def __init__(self, ros: RosSession, tag: str, backend: SimulatedBackend) -> None:
        self.commands_topic, self.states_topic = f'/drive_test_{tag}/commands', f'/drive_test_{tag}/states'
        self.backend = backend
        self.node = DriveBridge(backend=backend, context=ros.context, parameter_overrides=[
            Parameter('joint_commands_topic', value=self.commands_topic),
            Parameter('joint_states_topic', value=self.states_topic)])
        self.states = ros.collect(JointState, self.states_topic)
        self.commands = ros.publisher(JointState, self.commands_topic)
        ros.add_node(self.node)
        ros.wait_subscribers(self.commands)
        ros.wait_publishers(self.states)


@pytest.fixture
def bridge(ros: RosSession, request: pytest.FixtureRequest) -> Iterator[Bridge]:
    made = Bridge(ros, request.node.name.replace('test_', '')[:40], FlakyBackend(START, SPEED))
    try:
        yield made
    finally:
        ros.remove_node(made.node)


def test_the_drive_is_published_before_anything_is_commanded(bridge: Bridge) -> None:
    msg = bridge.states.wait_match(lambda m: list(m.name) == [JOINT], TIMEOUT)
    assert list(msg.position) == [START] and list(msg.velocity) == [0.0] and list(msg.effort) == [0.0]
    assert bridge.backend.writes == []


def test_a_command_moves_the_drive_and_a_bad_one_holds_it(bridge: Bridge, ros: RosSession) -> None:
    bridge.states.wait_count(1, TIMEOUT)
    target = START + 0.5 * LIMITS.max_step
    bridge.commands.publish(_command(target))
    bridge.states.wait_match(lambda m: abs(m.position[0] - target) < 1e-12, TIMEOUT)
    assert bridge.backend.writes[0] == target
    for bad in (math.nan, math.inf, LIMITS.upper + 0.1):
        bridge.commands.publish(_command(bad))
    bridge.commands.publish(_command(target, joint='another_joint'))
    counters = bridge.node.rules.counters
    ros.wait_for(lambda: counters.held_not_finite == 3 and counters.held_out_of_range == 1, TIMEOUT,
                 'the bad commands counted')
    assert all(LIMITS.in_range(w) for w in bridge.backend.writes)
    assert bridge.node.rules.status.startswith('held: ')


def test_a_failing_backend_is_counted_and_the_node_goes_on(bridge: Bridge, ros: RosSession) -> None:
    backend: Any = bridge.backend
    bridge.states.wait_count(1, TIMEOUT)
    backend.failing = True
    ros.wait_for(lambda: bridge.node.read_errors >= 3, TIMEOUT, 'read errors counted')
    start = len(bridge.states.messages)
    backend.failing = False
    bridge.states.wait_match(lambda m: list(m.position) == [START], TIMEOUT, start=start)
    diagnostics = ros.collect(DiagnosticArray, '/diagnostics')
    status = diagnostics.wait_match(
        lambda m: any(s.name == f'{NODE_NAME}: drive' and s.hardware_id == JOINT for s in m.status), TIMEOUT)
    values = {kv.key: kv.value for s in status.status for kv in s.values}
    assert int(values['read_errors']) >= 3 and values['backend'] == 'FlakyBackend'


def _bridge_process(ros: RosSession, *params: str) -> subprocess.Popen[str]:
    args = [sys.executable, '-m', 'fourbar_ros.drive.run', '--ros-args']
    for p in params:
        args += ['-p', p]
    return subprocess.Popen(args, env=ros.env(), stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


def test_the_process_publishes_the_simulated_drive_and_exits_0_on_sigterm(ros: RosSession) -> None:
    topic = '/drive_test_process/states'
    states = ros.collect(JointState, topic)
    proc = _bridge_process(ros, 'simulated_position:=0.9', f'joint_states_topic:={topic}',
                           'joint_commands_topic:=/drive_test_process/commands')
    try:
        states.wait_match(lambda m: list(m.position) == [0.9], TIMEOUT)
        proc.send_signal(signal.SIGTERM)
        out, _ = proc.communicate(timeout=TIMEOUT)
        assert proc.returncode == 0, out
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()


def test_a_backend_that_cannot_be_loaded_exits_2_with_one_line(ros: RosSession) -> None:
    proc = _bridge_process(ros, 'backend:=no_such_module:Drive')
    out, _ = proc.communicate(timeout=TIMEOUT)
    assert proc.returncode == 2
    assert out.strip().splitlines()[-1].startswith("fourbar_drive_bridge: error: backend 'no_such_module:Drive'")
