"""fourbar_node's live check of the model over the real middleware (actuator modes, ``antenna_sensor_type``): an
antenna sensor on antenna_angle_sensor, a Float64 or an Imu, against the angle the node completes from the measured
driven joint. A sensor that reads the core's angle for the measured joint is OK; one 0.01 rad off is WARN with the
mismatch reading 0.01 rad; past model_mismatch_error ERROR; an Imu between two measurements is compared with the
joint interpolated at its stamp; bad readings are counted and skipped. Without the parameter there is no
subscription (test_node_interface).

Nodes run in-process, each test's in its own namespace.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator
from typing import Any

import pytest
from geometry_msgs.msg import Vector3
from rclpy.parameter import Parameter
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import Float64
from support.paths import REPO
from support.ros_support import RosSession

from fourbar_ros.config.antenna_config import default_config
from fourbar_ros.interface.topics import MEASURED_JOINT_STATES
from fourbar_ros.node.fourbar_node import FourBarNode
from fourbar_ros.rules.diagnostics import Level

pytestmark = pytest.mark.ros

YAML = REPO / 'config' / 'antenna.yaml'
CFG = default_config()
DRIVEN = CFG.driven_joint
G = 9.80665  # m/s^2
_ns = itertools.count()


def core_theta(q: float) -> float:
    """The antenna angle (rad) the core gives for the measured driven joint q (rad)."""
    return float(CFG.linkage.from_rocker(q, CFG.driven, CFG.measured_branch).theta)


#: The driven joint (rad) at theta = 0.05 rad and at 0.06 rad.
Q0 = float(CFG.linkage.rocker_angles(0.05, CFG.branch)[0 if CFG.gamma_joint == DRIVEN else 1])
Q1 = float(CFG.linkage.rocker_angles(0.06, CFG.branch)[0 if CFG.gamma_joint == DRIVEN else 1])


class Rig:
    """fourbar_node in trajectory mode with an antenna sensor, a publisher of measurements and one of readings."""

    def __init__(self, ros: RosSession, sensor: str, **overrides: Any) -> None:
        self.ros = ros
        self.ns = f'/model_check_test_{next(_ns)}'
        params = [Parameter('mode', value='trajectory'), Parameter('joint_state_rate', value=0.0),
                  Parameter('antenna_sensor_type', value=sensor), Parameter('tracking_window', value=600.0),
                  Parameter('measurement_timeout', value=60.0),
                  *(Parameter(k, value=v) for k, v in overrides.items())]
        self.node = FourBarNode(context=ros.context, namespace=self.ns, parameter_overrides=params,
                                cli_args=['--ros-args', '--params-file', str(YAML)])
        ros.add_node(self.node)
        self.measured = ros.publisher(JointState, f'{self.ns}/{MEASURED_JOINT_STATES.name}')
        self.sensor = ros.publisher(Imu if sensor == 'imu' else Float64, f'{self.ns}/antenna_angle_sensor')
        ros.wait_subscribers(self.measured)
        ros.wait_subscribers(self.sensor)
        assert self.node.completion is not None and self.node.model_check is not None
        self.completed = self.node.completion.counters
        self.counters = self.node.model_check.check.counters

    def measure(self, q: float, sec: int, nanosec: int) -> None:
        """Publish one measurement and wait until the node completed it."""
        before = self.completed.measurements_completed
        msg = JointState(name=[DRIVEN], position=[q])
        msg.header.stamp.sec, msg.header.stamp.nanosec = sec, nanosec
        self.measured.publish(msg)
        self.ros.wait_for(lambda: self.completed.measurements_completed > before, what='the measurement completed')

    def read(self, msg: Any) -> None:
        """Publish one reading and wait until the node counted it (compared or skipped)."""
        before = self.seen()
        self.sensor.publish(msg)
        self.ros.wait_for(lambda: self.seen() > before, what='the reading taken')

    def seen(self) -> int:
        c = self.counters
        return (c.sensor_readings_compared + c.sensor_readings_skipped_not_finite
                + c.sensor_readings_skipped_no_gravity + c.sensor_readings_skipped_no_measurement
                + c.sensor_readings_skipped_out_of_reach)

    def status(self) -> tuple[Level, str, dict[str, str]]:
        with self.ros.paused():  # not halfway through a callback
            s = self.node.diagnostic_status()
        return Level(s.level[0]), s.message, {kv.key: kv.value for kv in s.values}

    def close(self) -> None:
        self.ros.destroy(self.measured, self.sensor)
        self.ros.remove_node(self.node)


@pytest.fixture
def rig(ros: RosSession) -> Iterator[Any]:
    made: list[Rig] = []

    def make(sensor: str, **overrides: Any) -> Rig:
        made.append(Rig(ros, sensor, **overrides))
        return made[-1]

    yield make
    for r in made:
        r.close()


def _now(r: Rig) -> tuple[int, int]:
    stamp = r.node.get_clock().now().to_msg()
    return stamp.sec, stamp.nanosec


def test_a_consistent_float64_sensor_is_ok(rig: Any) -> None:
    r = rig('float64')
    r.read(Float64(data=0.05))  # before any measurement: counted, skipped
    assert r.counters.sensor_readings_skipped_no_measurement == 1
    r.measure(Q0, *_now(r))  # the Float64 is timed by its arrival, after this stamp
    for _ in range(3):
        r.read(Float64(data=core_theta(Q0)))
    r.read(Float64(data=math.nan))
    assert r.counters.sensor_readings_compared == 3 and r.counters.sensor_readings_skipped_not_finite == 1
    level, message, values = r.status()
    assert level is Level.OK, message
    assert values['antenna_sensor_type'] == 'float64'
    assert float(values['model_mismatch_rad']) == pytest.approx(0.0, abs=1e-12)
    assert float(values['model_mismatch_rms_rad']) == pytest.approx(0.0, abs=1e-12)
    assert values['model_mismatch_window_readings'] == '3'
    assert values['sensor_readings_skipped_no_measurement'] == '1'


def test_a_float64_sensor_off_by_0_01_rad_is_warn_and_past_the_error_threshold_error(rig: Any) -> None:
    r = rig('float64')
    r.measure(Q0, *_now(r))
    for _ in range(3):
        r.read(Float64(data=core_theta(Q0) + 0.01))
    level, message, values = r.status()
    assert level is Level.WARN, message
    assert 'model_mismatch_warn' in message
    assert float(values['model_mismatch_rad']) == pytest.approx(0.01, abs=1e-12)
    assert float(values['model_mismatch_rms_rad']) == pytest.approx(0.01, abs=1e-12)
    # The sensor's offset counts: the same readings with antenna_sensor_offset -0.02 rad are 0.03 rad off.
    r2 = rig('float64', antenna_sensor_offset=-0.02)
    r2.measure(Q0, *_now(r2))
    r2.read(Float64(data=core_theta(Q0) + 0.01))
    level, message, values = r2.status()
    assert level is Level.ERROR and 'model_mismatch_error' in message, message
    assert float(values['model_mismatch_rad']) == pytest.approx(0.03, abs=1e-12)


def _imu(theta: float, sec: int, nanosec: int, g: float = G, roll: float = 0.0, yaw: float = 0.0) -> Imu:
    """An Imu at rest on the antenna tilted by theta (rad), rolled by ``roll`` (rad) about its x axis, then yawed by
    ``yaw`` about its z: gravity's reaction in the coupler frame turned by the roll, then by the yaw."""
    x, y = -g * math.sin(theta), g * math.cos(theta) * math.sin(roll)
    msg = Imu(linear_acceleration=Vector3(x=math.cos(yaw) * x + math.sin(yaw) * y,
                                          y=-math.sin(yaw) * x + math.cos(yaw) * y,
                                          z=g * math.cos(theta) * math.cos(roll)))
    msg.header.stamp.sec, msg.header.stamp.nanosec = sec, nanosec
    return msg


def test_an_imu_is_compared_with_the_joint_interpolated_at_its_stamp(rig: Any) -> None:
    r = rig('imu')
    r.read(_imu(0.05, 99, 0))  # before any measurement
    r.measure(Q0, 100, 0)
    r.measure(Q1, 100, 10_000_000)
    q_mid = Q0 + (Q1 - Q0) * 0.5
    r.read(_imu(core_theta(q_mid), 100, 5_000_000))
    level, message, values = r.status()
    assert level is Level.OK, message
    assert float(values['model_mismatch_rad']) == pytest.approx(0.0, abs=1e-12)
    # Not the latest measurement's angle: about 0.005 rad from either.
    assert abs(core_theta(q_mid) - core_theta(Q1)) > 0.004
    r.read(_imu(0.0, 100, 7_000_000, g=0.0))  # no gravity: no tilt to read
    r.read(_imu(math.nan, 100, 7_000_000))
    r.read(_imu(core_theta(q_mid) + 0.01, 100, 5_000_000))
    r.read(_imu(core_theta(Q1) + 0.01, 100, 20_000_000))  # after the last measurement: that one
    c = r.counters
    assert (c.sensor_readings_compared, c.sensor_readings_skipped_no_measurement,
            c.sensor_readings_skipped_no_gravity, c.sensor_readings_skipped_not_finite) == (3, 1, 1, 1)
    level, message, values = r.status()
    assert level is Level.WARN, message
    assert float(values['model_mismatch_rad']) == pytest.approx(0.01, abs=1e-12)
    assert float(values['model_mismatch_rms_rad']) == pytest.approx(0.01 * math.sqrt(2.0 / 3.0), abs=1e-12)
    assert values['antenna_sensor_type'] == 'imu' and values['sensor_readings_skipped_no_gravity'] == '1'


def test_an_imu_rolled_about_the_antenna_reads_the_same_angle(rig: Any) -> None:
    """Turned 15 deg about its x axis the IMU reads the same tilt: atan2(-a_x, a_z) would read it 3.5% large."""
    r = rig('imu')
    r.measure(Q1, 100, 0)
    theta = core_theta(Q1)
    assert abs(theta) > 0.01  # so that the roll would show: 3.5% of it is above 0.35 mrad
    r.read(_imu(theta, 100, 0, roll=math.radians(15.0)))
    level, message, values = r.status()
    assert level is Level.OK, message
    assert float(values['model_mismatch_rad']) == pytest.approx(0.0, abs=1e-12)


def test_an_imu_yawed_reads_the_same_angle_with_its_yaw_given(rig: Any) -> None:
    """Turned 5 deg about its own z (and rolled 15 deg) the IMU reads the same tilt once antenna_imu_yaw (what
    fourbar calibrate finds) turns its readings back; without it, the yaw turns part of the roll into the tilt:
    about sin(5 deg) sin(15 deg) = 0.023 rad."""
    yaw = math.radians(5.0)
    theta = core_theta(Q1)
    mismatch = {}
    for given in (yaw, 0.0):
        r = rig('imu', antenna_imu_yaw=given)
        r.measure(Q1, 100, 0)
        r.read(_imu(theta, 100, 0, roll=math.radians(15.0), yaw=yaw))
        mismatch[given] = float(r.status()[2]['model_mismatch_rad'])
    assert mismatch[yaw] == pytest.approx(0.0, abs=1e-12), mismatch  # a few ulps of the turned components
    assert abs(mismatch[0.0]) > 0.02, mismatch
