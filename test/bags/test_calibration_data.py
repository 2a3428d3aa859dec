"""A calibration recording read and paired (fourbar_ros.bags.calibration_data), from synthetic recordings written
with the package's own bag writer: rates, stamps, the IMU's tilt and its sign, and the data problems."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from fourbar_ros.bags.calibration_data import imu_tilt, pair, read_calibration_data
from fourbar_ros.bags.calibration_sweep import GRAVITY, Sweep, write_calibration_bag
from fourbar_ros.bags.storage import JOINT_STATE
from fourbar_ros.core.calibration import CalibrationError, imu_roll, imu_valid, imu_yaw
from fourbar_ros.interface.topics import Storage

TRUTH = {'frame_length': 0.1803, 'rocker_ab_length': 0.0598, 'coupler_length': 0.1021, 'rocker_cd_length': 0.0602,
         'driven_joint_offset': -math.radians(0.7), 'sensor_offset': 0.004}
JOINT = 'rocker_ab_joint'


@pytest.mark.parametrize('roll_deg', [0.0, 15.0, -30.0])
def test_imu_tilt_sign_follows_the_coupler_frame(roll_deg: float) -> None:
    """theta > 0 tilts the antenna down: the coupler frame's x axis (along the antenna) turns toward -z, and the
    accelerometer at rest reads (-g sin theta, 0, g cos theta); rolled by phi about x, (-g sin theta,
    g cos theta sin phi, g cos theta cos phi): the tilt is the same and the roll is phi."""
    roll = math.radians(roll_deg)
    for theta in (-0.1, 0.0, 0.05, 0.12):
        a = (-GRAVITY * math.sin(theta), GRAVITY * math.cos(theta) * math.sin(roll),
             GRAVITY * math.cos(theta) * math.cos(roll))
        # a few ulps of the components' rounding through hypot and atan2
        assert float(imu_tilt(*a)) == pytest.approx(theta, abs=1e-15)
        assert float(imu_roll(*a)) == pytest.approx(roll, abs=1e-15)
        assert bool(imu_valid(*a))
    assert not imu_valid(0.0, 0.0, 0.0)
    assert not imu_valid(math.nan, 0.0, GRAVITY)
    assert not imu_valid(0.0, 0.0, 1.0)  # in g, not m/s^2


@pytest.mark.parametrize(('yaw_deg', 'roll_deg'), [(5.0, 0.0), (-5.0, 15.0), (30.0, -30.0), (0.0, 15.0)])
def test_an_imu_yawed_about_its_z_axis(yaw_deg: float, roll_deg: float) -> None:
    """An IMU rolled by phi about x, then yawed by psi about its z, reads Rz(-psi) of the rolled reading. Over a
    sweep its readings trace a great circle about the joint axis: imu_yaw finds psi from them (the plane's normal,
    exact to rounding for noiseless readings), and the tilt turned back by it is theta, the roll phi, for every
    reading; untouched, the tilt would be off by up to theta (1 - cos psi) and more."""
    yaw, roll = math.radians(yaw_deg), math.radians(roll_deg)
    theta = np.linspace(-0.1, 0.12, 50)
    x, y, z = (-GRAVITY * np.sin(theta), GRAVITY * np.cos(theta) * math.sin(roll),
               GRAVITY * np.cos(theta) * math.cos(roll))
    a = (math.cos(yaw) * x + math.sin(yaw) * y, -math.sin(yaw) * x + math.cos(yaw) * y, z)
    found = imu_yaw(*a)
    # the least singular vector of 50 unit vectors: rounding of order 1e-16 over the arc's singular value (~0.4)
    assert found == pytest.approx(yaw, abs=1e-12)
    # atan2 and hypot of components rounded to 1e-16 relative, turned by a yaw known to 1e-12 rad
    assert np.allclose(imu_tilt(*a, found), theta, rtol=0.0, atol=1e-12)
    assert np.allclose(imu_roll(*a, found), roll, rtol=0.0, atol=1e-12)
    if yaw_deg:
        assert np.abs(imu_tilt(*a) - theta).max() > 1e-4  # the yaw matters
    assert math.isnan(imu_yaw(*(np.full(50, c[0]) for c in a)))  # one pose: no arc, no yaw


@pytest.mark.parametrize('sensor', ['float64', 'imu'])
def test_invalid_readings_are_dropped_and_counted(tmp_path: Path, sensor: str) -> None:
    """Non-finite Float64 readings and all-zero IMU vectors are dropped, counted; the IMU's roll is reported."""
    sweep = Sweep(TRUTH, duration=10.0, cycles=1.0, sensor=sensor, sensor_noise=0.0, imu_roll=math.radians(15.0),
                  glitches=((3, math.nan), (40, math.nan), (41, math.nan)))
    topic = '/imu/data' if sensor == 'imu' else '/antenna_inclinometer'
    data = read_calibration_data(write_calibration_bag(tmp_path / sensor, sweep, angle_topic=topic), JOINT, topic)
    assert data.sensor_invalid == 3 and data.joint_invalid == 0
    assert data.sensor_times.size == 500 - 3
    assert np.max(np.abs(data.theta - (sweep.theta(data.times) + TRUTH['sensor_offset']))) < 1e-12
    if sensor == 'imu':
        assert data.imu_roll == pytest.approx(math.radians(15.0), abs=1e-12)
    else:
        assert math.isnan(data.imu_roll)


@pytest.mark.parametrize('storage', list(Storage))
def test_float64_sensor_paired_at_its_receive_times(tmp_path: Path, storage: Storage) -> None:
    sweep = Sweep(TRUTH, duration=20.0, cycles=1.0, joint_rate=100.0, sensor_rate=50.0, sensor_noise=0.0)
    bag = write_calibration_bag(tmp_path / 'rec', sweep, storage=storage)
    data = read_calibration_data(bag, JOINT, '/antenna_inclinometer')
    assert data.joint_topic == '/joint_state_broadcaster/joint_states'
    assert data.joint_times.size == 2000 and data.sensor_times.size == 1000
    # the joint states are timed by their header stamps (received 0.2-2 ms later), exactly every 10 ms
    assert np.allclose(np.diff(data.joint_times), 0.01, rtol=0, atol=1e-9)
    # every reading falls inside the encoder's span (the last at 19.9813 s, the encoder's last at 19.99 s)
    assert data.times.size == 1000 and data.outside == 0
    t = data.times + 0.0  # s from the first joint state, the recording's start
    q_true = sweep.true_q(sweep.theta(t)) - TRUTH['driven_joint_offset']
    count = 2.0 * math.pi / (4096 * 500)
    assert np.max(np.abs(data.q - q_true)) < count + 1e-6  # counts + linear interpolation of a slow sweep
    assert np.max(np.abs(data.theta - (sweep.theta(t) + TRUTH['sensor_offset']))) < 1e-12


def test_imu_sensor_by_its_header_stamps(tmp_path: Path) -> None:
    sweep = Sweep(TRUTH, duration=10.0, cycles=1.0, sensor='imu', sensor_rate=40.0, sensor_noise=0.0)
    bag = write_calibration_bag(tmp_path / 'imu', sweep, angle_topic='/imu/data')
    data = read_calibration_data(bag, JOINT, '/imu/data')
    assert data.sensor_type == 'sensor_msgs/msg/Imu'
    assert np.max(np.abs(data.theta - (sweep.theta(data.times) + TRUTH['sensor_offset']))) < 1e-12


def test_pairing_stays_inside_the_encoder_span_and_out_of_its_gaps() -> None:
    tj = np.array([0.0, 0.01, 0.02, 0.03, 1.03, 1.04])  # a 1 s gap
    qj = np.arange(tj.size, dtype=float)
    ts = np.array([-0.005, 0.005, 0.025, 0.5, 1.035, 1.05])
    t, q, theta = pair(tj, qj, ts, ts * 10.0)
    assert list(t) == [0.005, 0.025, 1.035]
    assert q == pytest.approx([0.5, 2.5, 4.5])
    assert theta == pytest.approx([0.05, 0.25, 10.35])


def test_streams_that_do_not_overlap(tmp_path: Path) -> None:
    sweep = Sweep(TRUTH, duration=5.0, sensor_clock_offset=3600.0)
    bag = write_calibration_bag(tmp_path / 'apart', sweep)
    with pytest.raises(CalibrationError, match=r'^the streams do not overlap in time: joint states \[0\.000, 4\.990\]'):
        read_calibration_data(bag, JOINT, '/antenna_inclinometer')


def test_a_sensor_topic_of_the_wrong_type(tmp_path: Path) -> None:
    bag = write_calibration_bag(tmp_path / 'rec', Sweep(TRUTH, duration=2.0))
    topic = '/joint_state_broadcaster/joint_states'
    with pytest.raises(CalibrationError, match=f'sensor topic {topic} has type {JOINT_STATE}, expected '
                       'std_msgs/msg/Float64 or sensor_msgs/msg/Imu$'):
        read_calibration_data(bag, JOINT, topic)
    with pytest.raises(CalibrationError, match='no sensor topic /nowhere'):
        read_calibration_data(bag, JOINT, '/nowhere')
    with pytest.raises(CalibrationError, match=r"no JointState on .* has the driven joint 'rocker_cd_joint'"):
        read_calibration_data(bag, 'rocker_cd_joint', '/antenna_inclinometer')
