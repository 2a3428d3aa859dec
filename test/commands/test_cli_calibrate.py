"""`fourbar calibrate` end to end on synthetic recordings (in process): the calibrated parameter file the node's
own reader accepts, the report, the plot; and the recordings that cannot calibrate (one line, exit 1, nothing
written)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from support.paths import REPO

from fourbar_ros.bags.calibration_sweep import Sweep, write_calibration_bag
from fourbar_ros.commands import main
from fourbar_ros.config.antenna_config import load_config
from fourbar_ros.core import calibration
from fourbar_ros.core.calibration import PARAMETER_NAMES, predict

CONFIG = REPO / 'config' / 'antenna.yaml'
TRUTH = {'frame_length': 0.1803, 'rocker_ab_length': 0.0598, 'coupler_length': 0.1021, 'rocker_cd_length': 0.0602,
         'driven_joint_offset': -math.radians(0.7), 'sensor_offset': 0.004}


def calibrate(tmp_path: Path, bag: Path, *extra: str, topic: str = '/antenna_inclinometer') -> int:
    return main(['calibrate', str(bag), '--params', str(CONFIG), '--angle-topic', topic,
                 '-o', str(tmp_path / 'out' / 'calibrated.yaml'), '--report', str(tmp_path / 'out' / 'report.json'),
                 *extra])


@pytest.fixture
def out(tmp_path: Path) -> Path:
    (tmp_path / 'out').mkdir()
    return tmp_path / 'out'


def test_calibrates_and_writes_what_the_node_loads(tmp_path: Path, out: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    sweep = Sweep(TRUTH, duration=240.0, cycles=4.0)
    bag = write_calibration_bag(tmp_path / 'rec', sweep)
    assert calibrate(tmp_path, bag) == 0
    assert sorted(p.name for p in out.iterdir()) == ['calibrated.png', 'calibrated.yaml', 'report.json']
    report = json.loads((out / 'report.json').read_text())
    params = report['parameters']
    assert list(params) == list(PARAMETER_NAMES)
    for name, p in params.items():
        assert set(p) >= {'value', 'sd', 'determined_by_data'}
        assert abs(p['value'] - TRUTH[name]) <= 4.0 * p['sd'], name
    assert report['directions_determined_by_data'] == 3
    assert report['residual_rms_rad'] == pytest.approx(1e-3, rel=0.1)
    assert report['residual_rms_before_rad'] > 5e-3
    assert report['largest_residual_rad'] < 6e-3
    # The node's own reader and validation accept the file; only the lengths and the offsets changed: the
    # transmission offset is the file's (0.0) plus the fitted correction, the sensor's the fitted one.
    cfg, before = load_config(out / 'calibrated.yaml'), load_config(CONFIG)
    for name in calibration.LENGTH_NAMES:
        assert getattr(cfg, name) == params[name]['value']
    assert before.driven_joint_offset == 0.0
    assert cfg.driven_joint_offset == params['driven_joint_offset']['value']
    assert cfg.antenna_sensor_offset == params['sensor_offset']['value']
    assert report['offsets_in_parameter_file'] == {'driven_joint_offset': cfg.driven_joint_offset,
                                                   'antenna_sensor_offset': cfg.antenna_sensor_offset}
    changed = {k for k, v in cfg.as_values().items() if before.as_values()[k] != v}
    assert changed == {*calibration.LENGTH_NAMES, 'driven_joint_offset', 'antenna_sensor_offset'}
    # The calibrated model predicts the noiseless reading within 1e-4 rad over the swept range.
    values = np.array([params[n]['value'] for n in PARAMETER_NAMES])
    truth = np.array([TRUTH[n] for n in PARAMETER_NAMES])
    grid = sweep.measured_q(sweep.true_q(np.linspace(*sweep.theta_range, 501)))
    error = predict(values, grid, cfg.driven, cfg.measured_branch) - predict(truth, grid, cfg.driven,
                                                                             cfg.measured_branch)
    assert np.max(np.abs(error)) < 1e-4
    assert (out / 'calibrated.png').read_bytes().startswith(b'\x89PNG')
    printed = capsys.readouterr().out
    assert 'the data determine 3 of 6 directions' in printed
    assert (f"to the parameter file: driven_joint_offset {cfg.driven_joint_offset:.9g} rad (the file's 0 plus the "
            f"fitted), antenna_sensor_offset {cfg.antenna_sensor_offset:.9g} rad") in printed


def test_the_transmission_offset_in_effect_is_added_to(tmp_path: Path, out: Path) -> None:
    """Recorded with the transmission's <offset> at 0.1 rad (the parameter file's driven_joint_offset): the joint
    the drive reports is the actuator's plus 0.1 rad, the fitted correction is the same as with 0.0 (the recording
    is the same), and the file gets 0.1 rad plus it."""
    params = tmp_path / 'antenna.yaml'
    params.write_text(CONFIG.read_text(encoding='utf-8').replace('driven_joint_offset: 0.0 ',
                                                                 'driven_joint_offset: 0.1 ', 1), encoding='utf-8')
    assert load_config(params).driven_joint_offset == 0.1
    bag = write_calibration_bag(tmp_path / 'rec', Sweep(TRUTH, duration=60.0, cycles=1.0))
    assert main(['calibrate', str(bag), '--params', str(params), '--angle-topic', '/antenna_inclinometer',
                 '-o', str(out / 'calibrated.yaml'), '--report', str(out / 'report.json')]) == 0
    report = json.loads((out / 'report.json').read_text())
    correction = report['parameters']['driven_joint_offset']['value']
    assert abs(correction - TRUTH['driven_joint_offset']) <= 4.0 * report['parameters']['driven_joint_offset']['sd']
    assert report['driven_joint_offset_recorded_rad'] == 0.1
    assert load_config(out / 'calibrated.yaml').driven_joint_offset == 0.1 + correction


def test_imu_recording(tmp_path: Path, out: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bag = write_calibration_bag(tmp_path / 'imu', Sweep(TRUTH, duration=120.0, cycles=2.0, sensor='imu',
                                                        sensor_rate=100.0, joint_rate=200.0, seed=4),
                                angle_topic='/imu/data')
    assert calibrate(tmp_path, bag, topic='/imu/data') == 0
    report = json.loads((out / 'report.json').read_text())
    assert report['sensor_type'] == 'sensor_msgs/msg/Imu'
    for name, p in report['parameters'].items():
        assert abs(p['value'] - TRUTH[name]) <= 4.0 * p['sd'], name


def refused(tmp_path: Path, out: Path, capsys: pytest.CaptureFixture[str], bag: Path, message: str,
            topic: str = '/antenna_inclinometer') -> None:
    assert calibrate(tmp_path, bag, topic=topic) == 1
    err = capsys.readouterr().err
    assert err == f'fourbar calibrate: error: {message}\n'
    assert list(out.iterdir()) == []  # nothing written, no temporary left


def test_a_recording_at_one_angle(tmp_path: Path, out: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bag = write_calibration_bag(tmp_path / 'still', Sweep(TRUTH, duration=10.0, theta_range=(0.05, 0.05)))
    refused(tmp_path, out, capsys, bag, 'the recording spans 0.0 deg of tilt: it cannot determine the geometry; '
            'sweep the tilt range')


def test_a_sensor_topic_of_the_wrong_type(tmp_path: Path, out: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bag = write_calibration_bag(tmp_path / 'rec', Sweep(TRUTH, duration=5.0))
    topic = '/joint_state_broadcaster/joint_states'
    refused(tmp_path, out, capsys, bag, f'{bag}: sensor topic {topic} has type sensor_msgs/msg/JointState, '
            'expected std_msgs/msg/Float64 or sensor_msgs/msg/Imu', topic=topic)


def test_streams_that_do_not_overlap(tmp_path: Path, out: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bag = write_calibration_bag(tmp_path / 'apart', Sweep(TRUTH, duration=5.0, sensor_clock_offset=-60.0))
    # times from the first message, the sensor's at 1.3 ms: the joint states' run 59.9987 s to 64.9887 s
    refused(tmp_path, out, capsys, bag, 'the streams do not overlap in time: joint states [59.999, 64.989], '
            'sensor [0.000, 4.980] (s from the first message); record both at once, with their clocks agreeing')


def test_a_fit_that_does_not_converge(tmp_path: Path, out: Path, capsys: pytest.CaptureFixture[str],
                                      monkeypatch: pytest.MonkeyPatch) -> None:
    bag = write_calibration_bag(tmp_path / 'rec', Sweep(TRUTH, duration=10.0))
    monkeypatch.setattr(calibration, 'MAX_ITERATIONS', 1)
    assert calibrate(tmp_path, bag) == 1
    err = capsys.readouterr().err
    assert err.startswith('fourbar calibrate: error: the fit did not converge in 1 iterations (last step ')
    assert err.count('\n') == 1
    assert list(out.iterdir()) == []


def test_bad_input_is_status_2(tmp_path: Path, out: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert calibrate(tmp_path, tmp_path / 'missing') == 2
    assert capsys.readouterr().err == f'fourbar calibrate: error: {tmp_path / "missing"}: no such bag\n'
    bag = write_calibration_bag(tmp_path / 'rec', Sweep(TRUTH, duration=2.0))
    assert calibrate(tmp_path, bag, '--length-tolerance', '0') == 2
    assert 'must be finite and positive' in capsys.readouterr().err
    assert list(out.iterdir()) == []


def test_the_load_from_the_measured_effort(tmp_path: Path, out: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A recording whose joint states carry velocity and effort: the load model is fitted too, and the node's
    parameters the data determined are written to the file."""
    load = {'antenna_mass': 2.0, 'com_offset_along': 0.03, 'com_offset_normal': 0.02, 'coulomb_friction': 0.05,
            'reducer_efficiency': 0.7}
    bag = write_calibration_bag(tmp_path / 'rec', Sweep(TRUTH, duration=120.0, cycles=2.0, load=load, seed=2))
    assert calibrate(tmp_path, bag) == 0
    report = json.loads((out / 'report.json').read_text())
    fitted = report['load']
    assert fitted['velocity'] == 'measured'
    assert fitted['noise_sd_N_m'] == pytest.approx(0.02, rel=0.1)
    for name, p in fitted['parameters'].items():
        assert abs(p['value'] - load[name]) <= 4.0 * p['sd'], name
    written = fitted['written_to_parameter_file']
    assert set(written) == {'antenna_mass', 'com_offset_along', 'com_offset_normal', 'reducer_efficiency'}
    cfg = load_config(out / 'calibrated.yaml')
    for name, value in written.items():
        assert getattr(cfg, name) == value
    assert 'load from the measured effort' in capsys.readouterr().out


def test_no_effort_no_load_model(tmp_path: Path, out: Path) -> None:
    bag = write_calibration_bag(tmp_path / 'rec', Sweep(TRUTH, duration=60.0))
    assert calibrate(tmp_path, bag) == 0
    assert json.loads((out / 'report.json').read_text())['load'] is None
    assert load_config(out / 'calibrated.yaml').antenna_mass == load_config(CONFIG).antenna_mass
