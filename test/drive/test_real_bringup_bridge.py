"""The drive bridge's bringup on the real ros2_control stack never moves the drive uncommanded.

The controller manager starts the topic-based plugin's component inactive (``hardware_components_initial_state``);
the bridge (its executable, ``backend:=recording_drive:RecordingDrive``, every write recorded) activates it after a
reading of the drive inside the driven range; the controllers are spawned after that. From drive angles at both ends
of the range, one ulp inside each, mid-range (away from the model's ``initial_value``), and one ulp outside each end
(a bridge that refuses, then one in range on the same manager): no write moves the drive before the first command,
the broadcaster never publishes ``initial_value``, and the first motion is the commanded one. (The launch file as
users type it: test/package/test_real_bringup.py; a respawned manager: test_bridge_respawn.py.)

Skipped, with the reason, where ros2_control or the topic plugin is not installed.
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytest.importorskip('rclpy')

from builtin_interfaces.msg import Duration
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
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
from fourbar_ros.drive.rules import ACTIVATED_MARK

pytestmark = [pytest.mark.ros, pytest.mark.slow]

MID = 0.5 * (LIMITS.lower + LIMITS.upper)
BACKEND = 'recording_drive:RecordingDrive'
REFUSED = 'not activating hardware component'
PLUGIN_THRESHOLD = 1e-5  # rad: JointStateTopicSystem's default trigger_joint_command_threshold

#: (case, the drive's angle at bringup rad, an angle outside the range a first bridge refuses on the same manager).
CASES = [
    ('lower end', LIMITS.lower, math.nextafter(LIMITS.lower, -math.inf)),
    ('one ulp above the lower end', math.nextafter(LIMITS.lower, math.inf), None),
    ('mid-range', MID, None),
    ('one ulp below the upper end', math.nextafter(LIMITS.upper, -math.inf), None),
    ('upper end', LIMITS.upper, math.nextafter(LIMITS.upper, math.inf)),
]


def _direction(start: float) -> float:
    """The commanded move's sign: inwards from an end; mid-range away from INITIAL (so its path never crosses it)."""
    if start == MID:
        return 1.0 if MID > INITIAL else -1.0
    return 1.0 if start < MID else -1.0


@pytest.mark.parametrize(('case', 'start', 'outside'), CASES, ids=[c[0] for c in CASES])
def test_the_bringup_moves_the_drive_only_as_commanded(ros: RosSession, processes: Processes, tmp_path: Path,
                                                       case: str, start: float, outside: float | None) -> None:
    env = with_ros2_control(ros.env(PYTHON=sys.executable))
    if (why := topic_plugin_missing(env)) is not None:
        pytest.skip(why)
    assert start != INITIAL and LIMITS.in_range(start) and (outside is None or not LIMITS.in_range(outside))
    namespace = f'/bringup_{CASES.index((case, start, outside))}'
    manager = f'{namespace}/controller_manager'
    env['PYTHONPATH'] = os.pathsep.join([str(Path(__file__).parent), env.get('PYTHONPATH', '')])
    publish_description(ros, namespace)
    measured = ros.collect(JointState, f'{namespace}/joint_state_broadcaster/joint_states')
    drive = ros.collect(JointState, f'{namespace}/{STATES}')
    diagnostics = ros.collect(DiagnosticArray, '/diagnostics')
    initial_state = tmp_path / 'initial_state.yaml'
    initial_state.write_text(f'{manager}:\n  ros__parameters:\n    hardware_components_initial_state:\n'
                             f'      inactive: [{COMPONENT}]\n', encoding='utf-8')

    def bridge(name: str, position: float) -> subprocess.Popen[bytes]:
        child = {**env, START_ENV: position.hex(), LOG_ENV: str(tmp_path / f'{name}.writes')}
        return processes.start(name, [sys.executable, '-m', 'fourbar_ros.drive.run', '--ros-args',
                                      '-r', f'__ns:={namespace}', '-p', f'backend:={BACKEND}',
                                      '-p', f'hardware_component:={COMPONENT}',
                                      '-p', f'joint_commands_topic:={COMMANDS}', '-p', f'joint_states_topic:={STATES}'],
                               child)

    try:
        processes.start('controller_manager', [
            manager_executable(env, 'ros2_control_node'), '--ros-args', '-r', f'__ns:={namespace}',
            '--params-file', str(REPO / CONTROLLERS_FILE), '--params-file', str(initial_state)], env)
        if outside is not None:  # a bridge on a drive just outside the range: it refuses, nothing moves
            refusing = bridge('outside', outside)
            ros.wait_for(lambda: REFUSED in processes.log('outside'), TIMEOUT, 'the refusal of the drive outside')
            status = diagnostics.wait_match(lambda m: any(s.hardware_id == JOINT and s.level == DiagnosticStatus.ERROR
                                                          for s in m.status), TIMEOUT)
            lines = [line for line in processes.log('outside').splitlines() if REFUSED in line]
            assert len(lines) == 1 and all(word in lines[0] for word in (JOINT, repr(outside), repr(LIMITS.lower),
                                                                        repr(LIMITS.upper))), lines
            messages = [s.message for s in status.status if s.hardware_id == JOINT]
            assert len(messages) == 1 and messages[0].startswith(REFUSED) and lines[0].endswith(messages[0]), messages
            assert processes.stop(refusing) == 0
            assert writes(tmp_path / 'outside.writes') == [], 'the refusing bridge wrote to the drive'
            assert ACTIVATED_MARK not in processes.log('outside')
        bridge('bridge', start)
        # The activation line needs the manager's report of the component inactive: after a refusing bridge, it
        # shows the component was still inactive.
        ros.wait_for(lambda: ACTIVATED_MARK in processes.log('bridge'), TIMEOUT, 'the bridge activating the hardware')
        spawner = processes.start('spawner', [sys.executable, manager_executable(env, 'spawner'),
                                              'joint_state_broadcaster', 'joint_trajectory_controller', '-c', manager],
                                  env)
        ros.wait_for(lambda: spawner.poll() is not None, TIMEOUT, 'the spawner')
        assert spawner.returncode == 0
        measured.wait_match(lambda m: joint_position(m) == start, TIMEOUT)
        trajectory = ros.publisher(JointTrajectory, f'{namespace}/joint_trajectory_controller/joint_trajectory', 10)
        ros.wait_subscribers(trajectory)
        target = start + _direction(start) * STEP
        assert LIMITS.in_range(target) and not min(start, target) <= INITIAL <= max(start, target)
        command = JointTrajectory(joint_names=[JOINT], points=[JointTrajectoryPoint(
            positions=[target], time_from_start=Duration(sec=STEP_S))])
        before, readings = len(measured.messages), len(drive.messages)
        commanded_at = time.monotonic()
        sent = [-math.inf]

        def moved() -> bool:
            # Sent again until the drive moves: a subscription that has not matched this publisher yet drops it.
            if time.monotonic() - sent[0] >= RESEND_S:
                trajectory.publish(command)
                sent[0] = time.monotonic()
            return any(joint_position(m) != start for m in drive.messages[readings:])
        ros.wait_for(moved, TIMEOUT, f'the drive moving on the command towards {target!r} rad')
        # The plugin sends no command within its trigger_joint_command_threshold of the state it read (1e-5 rad,
        # upstream's default): once the controller holds the target, the drive rests within that of it.
        drive.wait_match(lambda m: abs((joint_position(m) or math.inf) - target) <= PLUGIN_THRESHOLD, TIMEOUT)
        recorded = writes(tmp_path / 'bridge.writes')
        early = [(t, q, w) for t, q, w in recorded if t < commanded_at]
        moving = [(t, q, w) for t, q, w in recorded if w != q]
        largest = max((abs(w - q) for _, q, w in early), default=0.0)
        # No write before the command moves the drive at all: the simulated drive has no encoder count to allow.
        assert largest == 0.0, f'{case}: a write before the command moved the drive by {largest!r} rad: {early}'
        assert moving and moving[0][0] > commanded_at and (moving[0][2] - moving[0][1]) * _direction(start) > 0, \
            f'{case}: the first moving write {moving[:1]} (command at {commanded_at!r} s towards {target!r} rad)'
        seen = [joint_position(m) for m in measured.messages[:before]]
        assert seen and all(q == start for q in seen), f'{case}: the broadcaster before the command: {set(seen)}'
        published = [joint_position(m) for m in measured.messages]
        assert INITIAL not in published, f'{case}: initial_value {INITIAL!r} published'
        print(f'{case}: start {start!r} rad, {len(early)} writes before the command, largest motion {largest!r} rad; '
              f'first motion {moving[0][2] - moving[0][1]!r} rad towards {target!r}')
    except AssertionError as exc:
        raise AssertionError(f'{exc}\n{processes.logs()}') from None
