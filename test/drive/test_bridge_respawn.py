"""The drive bridge across a controller manager's death and respawn, on the real ros2_control stack.

The manager (the topic-based plugin's component started inactive) is killed with SIGKILL after the bridge (its
executable, ``backend:=recording_drive:RecordingDrive``, every write recorded) activated the component and the
controllers were spawned; a new manager is started in its place, as the launch file's respawn does. The bridge
activates the new manager's component once, on a reading it published after that manager's report of the component
inactive (the activation line names it: the drive's own position); the broadcaster of neither manager publishes the
model's ``initial_value``; no write moves the drive before the command sent after the respawn, and the first motion
is the commanded one. A probe records the manager's activity with its publication sequence numbers: the respawned
manager's restart (what tells the bridge a new manager from the old one).

Skipped, with the reason, where ros2_control or the topic plugin is not installed.
"""

from __future__ import annotations

import math
import os
import signal
import sys
import time
from pathlib import Path

import pytest

pytest.importorskip('rclpy')

from builtin_interfaces.msg import Duration
from recording_drive import LOG_ENV, START_ENV, writes
from sensor_msgs.msg import JointState
from support.drive_stack import (
    COMMANDS,
    COMPONENT,
    INITIAL,
    JOINT,
    LIMITS,
    RESEND_S,
    STATES,
    STEP,
    STEP_S,
    TIMEOUT,
    Processes,
    joint_position,
    manager_executable,
    publish_description,
    topic_plugin_missing,
)
from support.paths import REPO
from support.ros2_control_support import with_ros2_control
from support.ros_support import RosSession
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from fourbar_ros.config.controllers import CONTROLLERS_FILE
from fourbar_ros.drive.rules import ACTIVATED_MARK, activated_line

pytestmark = [pytest.mark.ros, pytest.mark.slow]

#: The drive's angle (rad): a quarter of the range from the end farther from INITIAL (never the plugin's start).
START = (0.75 * LIMITS.lower + 0.25 * LIMITS.upper if 0.5 * (LIMITS.lower + LIMITS.upper) < INITIAL
         else 0.25 * LIMITS.lower + 0.75 * LIMITS.upper)
TARGET = START + math.copysign(STEP, START - INITIAL)
NAMESPACE = '/respawn_bridge'
MANAGER = f'{NAMESPACE}/controller_manager'

#: A probe on the manager's activity (reliable, transient local, as the manager publishes it): one line per report,
#: ``<publication sequence number> <the component's state label> <source timestamp ns, system clock>``
#: (controller_manager_msgs needs ros2_control's paths, so it runs as a child process).
PROBE = '''
import sys, rclpy
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from controller_manager_msgs.msg import ControllerManagerActivity
from fourbar_ros.runtime.executor import MessageInfoCallback
rclpy.init()
node = rclpy.create_node('activity_probe')
def on(msg, info):
    states = [c.state.label for c in msg.hardware_components if c.name == sys.argv[2]]
    print(info['publication_sequence_number'], states[0] if states else '-', info['source_timestamp'], flush=True)
node.create_subscription(ControllerManagerActivity, sys.argv[1], MessageInfoCallback(on), QoSProfile(
    depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL))
try:
    rclpy.spin(node)
except BaseException:
    pass
'''


def _activations(processes: Processes) -> list[str]:
    return [line for line in processes.log('bridge').splitlines() if ACTIVATED_MARK in line]


def _reports(processes: Processes, after_ns: int = 0, before_ns: float = math.inf) -> list[tuple[int, str]]:
    """The probe's (sequence number, state) of the reports published in (``after_ns``, ``before_ns``) (their
    source timestamps, system clock, ns), in the order heard."""
    rows = [line.split() for line in processes.log('activity').splitlines()]
    return [(int(row[0]), row[1]) for row in rows
            if len(row) == 3 and row[0].isdigit() and row[2].isdigit() and after_ns < int(row[2]) < before_ns]


def test_a_respawned_manager_is_activated_on_a_fresh_reading_and_nothing_moves_uncommanded(
        ros: RosSession, processes: Processes, tmp_path: Path) -> None:
    env = with_ros2_control(ros.env(PYTHON=sys.executable))
    if (why := topic_plugin_missing(env)) is not None:
        pytest.skip(why)
    assert START != INITIAL and LIMITS.in_range(START) and LIMITS.in_range(TARGET)
    env['PYTHONPATH'] = os.pathsep.join([str(Path(__file__).parent), env.get('PYTHONPATH', '')])
    publish_description(ros, NAMESPACE)
    # The bridge's readings are not subscribed here: its readiness must be the plugin's subscription alone.
    measured = ros.collect(JointState, f'{NAMESPACE}/joint_state_broadcaster/joint_states')
    initial_state = tmp_path / 'initial_state.yaml'
    initial_state.write_text(f'{MANAGER}:\n  ros__parameters:\n    hardware_components_initial_state:\n'
                             f'      inactive: [{COMPONENT}]\n', encoding='utf-8')
    manager_args = [manager_executable(env, 'ros2_control_node'), '--ros-args', '-r', f'__ns:={NAMESPACE}',
                    '--params-file', str(REPO / CONTROLLERS_FILE), '--params-file', str(initial_state)]
    record = tmp_path / 'bridge.writes'

    def spawn(name: str) -> None:
        spawner = processes.start(name, [sys.executable, manager_executable(env, 'spawner'),
                                         'joint_state_broadcaster', 'joint_trajectory_controller', '-c', MANAGER], env)
        ros.wait_for(lambda: spawner.poll() is not None, TIMEOUT, f'the {name}')
        assert spawner.returncode == 0, f'the {name} exited {spawner.returncode}'

    try:
        processes.start('activity', [sys.executable, '-c', PROBE, f'{MANAGER}/activity', COMPONENT], env)
        first = processes.start('controller_manager', manager_args, env)
        processes.start('bridge', [sys.executable, '-m', 'fourbar_ros.drive.run', '--ros-args',
                                   '-r', f'__ns:={NAMESPACE}', '-p', 'backend:=recording_drive:RecordingDrive',
                                   '-p', f'hardware_component:={COMPONENT}',
                                   '-p', f'joint_commands_topic:={COMMANDS}', '-p', f'joint_states_topic:={STATES}'],
                        {**env, START_ENV: START.hex(), LOG_ENV: str(record)})
        ros.wait_for(lambda: len(_activations(processes)) >= 1, TIMEOUT, 'the bridge activating the first manager')
        spawn('spawner')
        measured.wait_match(lambda m: joint_position(m) == START, TIMEOUT)
        ros.wait_for(lambda: any(s == 'active' for _, s in _reports(processes)), TIMEOUT, 'the report of it active')

        first.send_signal(signal.SIGKILL)
        first.wait()
        killed_at, killed_ns = time.monotonic(), time.time_ns()
        heard = len(measured.messages)
        lines_while_dead = _activations(processes)
        processes.start('controller_manager_2', manager_args, env)  # as the launch's respawn does
        ros.wait_for(lambda: len(_activations(processes)) >= 2, TIMEOUT, 'the bridge activating the new manager')
        reactivated_s = time.monotonic() - killed_at
        spawn('spawner_2')
        measured.wait_match(lambda m: joint_position(m) == START, TIMEOUT, start=heard)

        trajectory = ros.publisher(JointTrajectory, f'{NAMESPACE}/joint_trajectory_controller/joint_trajectory', 10)
        ros.wait_subscribers(trajectory)
        command = JointTrajectory(joint_names=[JOINT], points=[JointTrajectoryPoint(
            positions=[TARGET], time_from_start=Duration(sec=STEP_S))])
        before_command = len(measured.messages)
        commanded_at = time.monotonic()
        sent = [-math.inf]

        def moved() -> bool:
            # Sent again until the drive moves: a subscription that has not matched this publisher yet drops it.
            if time.monotonic() - sent[0] >= RESEND_S:
                trajectory.publish(command)
                sent[0] = time.monotonic()
            return any(w != q for _, q, w in writes(record))
        ros.wait_for(moved, TIMEOUT, f'the drive moving on the command towards {TARGET!r} rad')

        # The new manager's reports: its latest (after the spawners) says the component active.
        ros.wait_for(lambda: (_reports(processes, killed_ns)[-1:] or [(0, '')])[-1][1] == 'active', TIMEOUT,
                     'the probe hearing the new manager report the component active')
        lines, new = _activations(processes), _reports(processes, killed_ns)
        before_kill = _reports(processes, before_ns=killed_ns)
        assert len(lines_while_dead) == 1, f'activation lines before the new manager started: {lines_while_dead}'
        # Both activations on the drive's own position: a reading the bridge published, not the plugin's start.
        expected = activated_line(COMPONENT, JOINT, START)
        assert len(lines) == 2 and all(line.endswith(expected) for line in lines), lines
        assert before_kill and new[0][0] <= before_kill[-1][0], \
            f'the new manager\'s reports {new} after the old one\'s {before_kill}: its sequence did not restart'
        recorded = writes(record)
        early = [(t, q, w) for t, q, w in recorded if t < commanded_at]
        moving = [(t, q, w) for t, q, w in recorded if w != q]
        # Each controller holds the state it read at its activation (START exactly) and the plugin sends nothing
        # within its trigger_joint_command_threshold of the state it read: any write before the command is one
        # nobody gave.
        assert early == [], f'writes before the command (kill at {killed_at!r} s): {early}'
        assert moving[0][0] > commanded_at and (moving[0][2] - moving[0][1]) * (TARGET - START) > 0, \
            f'the first moving write {moving[:1]} (command at {commanded_at!r} s towards {TARGET!r} rad)'
        seen = [joint_position(m) for m in measured.messages[:before_command]]
        assert seen and all(q == START for q in seen), f'the broadcasters before the command: {set(seen)}'
        assert len(measured.messages[heard:before_command]) > 0, 'nothing heard from the new manager\'s broadcaster'
        assert INITIAL not in [joint_position(m) for m in measured.messages], f'initial_value {INITIAL!r} published'
        print(f'respawn: reports of the first manager {before_kill}, of the new one {new}; re-activated '
              f'{reactivated_s:.2f} s after the kill; no write before the command; first motion '
              f'{moving[0][2] - moving[0][1]!r} rad towards {TARGET!r}')
    except AssertionError as exc:
        raise AssertionError(f'{exc}\n{processes.logs()}') from None
