"""fourbar_mujoco_drive: the drive bridge on the MuJoCo plant, in-process on a fake clock the test advances (the
plant is frozen between advances, so what it publishes is of a known state): the step count on the joint states,
the antenna's Imu, the truth, the wind topic; then as a process (SIGTERM exits 0, a bad parameter exits 2)."""

from __future__ import annotations

import math
import signal
import subprocess
import sys
from collections.abc import Iterator

import pytest

pytest.importorskip('rclpy')
pytest.importorskip('mujoco', reason='the MuJoCo plant needs the mujoco package (the plant extra)')

from diagnostic_msgs.msg import DiagnosticArray
from rclpy.parameter import Parameter
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import Float64
from support.ros_support import RosSession

from fourbar_ros.config.antenna_config import default_config
from fourbar_ros.config.robot_model import LINKS
from fourbar_ros.drive.bridge_node import NODE_NAME
from fourbar_ros.plant.plant_node import ANTENNA_LINK, TRUTH_TOPIC, WIND_TOPIC, MujocoDrive
from fourbar_ros.rules.model_check import imu_theta

pytestmark = pytest.mark.ros

CFG = default_config()
JOINT = CFG.driven_joint
CYCLE = 2.0 * math.pi / 50  # rad at the motor: the default stepper's electrical cycle
NS = '/plant_node_test'
TIMEOUT = 30.0


class FakeClock:
    """Seconds the test sets (read by the node's executor thread: one float, set atomically)."""

    now = 0.0

    def __call__(self) -> float:
        return self.now


class Drive:
    """The node in-process, its clock, and the test's ends of its topics."""

    def __init__(self, ros: RosSession) -> None:
        self.clock = FakeClock()
        self.node = MujocoDrive(clock=self.clock, context=ros.context, namespace=NS, parameter_overrides=[
            Parameter('joint_commands_topic', value=f'{NS}/commands'),
            Parameter('joint_states_topic', value=f'{NS}/states')])
        self.backend = self.node.plant_backend
        self.states = ros.collect(JointState, f'{NS}/states')
        self.truth = ros.collect(JointState, f'{NS}/{TRUTH_TOPIC}')
        self.imu = ros.collect(Imu, f'{NS}/antenna_angle_sensor', qos_profile_sensor_data)
        self.wind = ros.publisher(Float64, f'{NS}/{WIND_TOPIC}', 10)
        ros.add_node(self.node)
        ros.wait_subscribers(self.wind)
        ros.wait_publishers(self.states)

    def advance(self, ros: RosSession, seconds: float) -> None:
        """Move the clock on and wait until the node's next reading has stepped the plant to it."""
        target = self.backend.simulated_time + seconds
        self.clock.now += seconds
        ros.wait_for(lambda: self.backend.simulated_time >= target - 0.5 * self.backend.plant.timestep, TIMEOUT,
                     f'the plant stepped to {target} s (at {self.backend.simulated_time} s)')

    def next_truth(self) -> JointState:
        """A truth message published after now (of the present, frozen state)."""
        return self.truth.wait_match(lambda m: True, TIMEOUT, start=len(self.truth.messages) + 1)


@pytest.fixture(scope='module')
def drive(ros: RosSession) -> Iterator[Drive]:
    made = Drive(ros)
    try:
        made.advance(ros, 1.0)  # at rest under the design load
        yield made
    finally:
        ros.remove_node(made.node)


def test_the_bridge_publishes_the_step_count(drive: Drive) -> None:
    msg = drive.states.wait_match(lambda m: list(m.name) == [JOINT], TIMEOUT)
    assert list(msg.position) == [drive.backend.commanded_position]  # the open loop's count
    assert list(msg.velocity) == [0.0] and list(msg.effort) == []  # differenced by the bridge; no effort


def test_the_imu_and_the_truth_are_of_one_state(drive: Drive) -> None:
    """At rest imu_theta of the Imu is the truth's theta (coupler less gamma) of the same stamp, within the bound of
    test_plant_backend: the site's acceleration over g, from the (frozen) state's joint accelerations and speeds."""
    truth = drive.next_truth()
    imu = drive.imu.wait_match(lambda m: m.header.stamp == truth.header.stamp, TIMEOUT)
    assert imu.header.frame_id == ANTENNA_LINK and ANTENNA_LINK in LINKS
    assert imu.orientation_covariance[0] == -1.0
    a = imu.linear_acceleration
    names = list(truth.name)
    theta = truth.position[names.index(CFG.joint_names[2])] - truth.position[names.index(CFG.joint_names[0])]
    data = drive.backend.plant.data
    reach = CFG.rocker_ab_length + CFG.coupler_length
    bound = reach * (sum(abs(data.qacc)) + sum(abs(data.qvel)) ** 2) / CFG.gravity + 1e-15
    measured = imu_theta(a.x, a.y, a.z)
    assert isinstance(measured, float) and abs(measured - theta) <= bound, (measured, theta, bound)
    # The truth's effort at the driven joint is the drive torque: the design load's (N m).
    assert truth.effort[names.index(JOINT)] == pytest.approx(drive.backend.drive_torque, rel=1e-12)
    assert names[-1] == f'{JOINT}_motor'


def test_a_wind_on_the_topic_slips_the_truth_and_the_count_stays(drive: Drive, ros: RosSession) -> None:
    """Three design loads for 0.3 s (beyond pull-out, test_plant_backend), then calm: the joint states keep the
    count; the truth's rocker rests whole electrical cycles / ratio off it (1e-9 rad: test_plant_backend)."""
    count = drive.backend.commanded_position
    for wind in (-3.0 * CFG.load_torque, math.inf):  # the second refused: not finite
        drive.wind.publish(Float64(data=wind))
    ros.wait_for(lambda: drive.node.get_parameter('wind_torque').value == -3.0 * CFG.load_torque
                 and drive.backend.wind_torque == -3.0 * CFG.load_torque, TIMEOUT, 'the gust set')
    ros.wait_for(lambda: drive.node.wind_refused == 1, TIMEOUT, 'the infinite wind refused')
    assert drive.backend.wind_torque == -3.0 * CFG.load_torque
    drive.advance(ros, 0.3)
    drive.wind.publish(Float64(data=0.0))
    ros.wait_for(lambda: drive.backend.wind_torque == 0.0, TIMEOUT, 'the calm set')
    drive.advance(ros, 1.0)
    cycles = drive.backend.slipped_cycles
    assert cycles < 0, 'the way the wind pushed it'
    truth = drive.next_truth()
    rocker = truth.position[list(truth.name).index(JOINT)]
    assert abs(rocker - count - cycles * CYCLE / CFG.reducer_ratio) < 1e-9, (rocker, count, cycles)
    start = len(drive.states.messages)
    state = drive.states.wait_match(lambda m: True, TIMEOUT, start=start + 1)
    assert list(state.position) == [count]
    diagnostics = ros.collect(DiagnosticArray, '/diagnostics')
    status = diagnostics.wait_match(lambda m: any(s.name == f'{NS[1:]}/{NODE_NAME}: drive' and
                                                  any(kv.key == 'slipped_cycles' for kv in s.values)
                                                  for s in m.status), TIMEOUT)
    values = {kv.key: kv.value for s in status.status for kv in s.values}
    assert int(values['slipped_cycles']) == cycles and values['backend'] == 'PlantBackend'
    ros.uncollect(diagnostics)


def _process(ros: RosSession, *params: str) -> subprocess.Popen[str]:
    args = [sys.executable, '-m', 'fourbar_ros.plant.run', '--ros-args', '-r', f'__ns:={NS}_process']
    for p in params:
        args += ['-p', p]
    return subprocess.Popen(args, env=ros.env(), stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


def test_the_process_publishes_the_imu_and_exits_0_on_sigterm(ros: RosSession) -> None:
    imu = ros.collect(Imu, f'{NS}_process/antenna_angle_sensor', qos_profile_sensor_data)
    proc = _process(ros, f'joint_states_topic:={NS}_process/states', f'joint_commands_topic:={NS}_process/cmd')
    try:
        imu.wait_match(lambda m: m.header.frame_id == ANTENNA_LINK, TIMEOUT)
        proc.send_signal(signal.SIGTERM)
        out, _ = proc.communicate(timeout=TIMEOUT)
        assert proc.returncode == 0, out
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
        ros.uncollect(imu)


def test_a_bad_plant_parameter_exits_2_with_one_line(ros: RosSession) -> None:
    proc = _process(ros, 'microsteps:=0')
    out, _ = proc.communicate(timeout=TIMEOUT)
    assert proc.returncode == 2, out
    assert out.strip().splitlines()[-1] == 'fourbar_mujoco_drive: error: plant: microsteps: must be at least 1, got 0'
