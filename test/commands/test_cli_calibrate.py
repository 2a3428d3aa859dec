"""`fourbar calibrate` end to end on synthetic recordings (in process): the calibrated parameter file the node's
own reader accepts, the report, the plot; a real sensor's faults, each giving the node's absolute angle within its
reported 4 sd of the truth or refused; the absolute angle pinned by a reference; and the recordings that cannot
calibrate (one line, exit 1, nothing written)."""

from __future__ import annotations

import json
import math
import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

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
    # And the live check's: the sensor's latency, its noise and that noise's correlation, the map's largest sd.
    live = report['live_check_in_parameter_file']
    assert live == {'antenna_sensor_latency': report['direction_dependent']['latency_s'],
                    'antenna_sensor_noise': report['noise_sd_rad'],
                    'antenna_sensor_noise_correlation': max(report['noise_lag1_correlation'], 0.0),
                    'antenna_sensor_map_sd': report['absolute_angle']['sensor_map_largest_sd_rad']}
    assert all(getattr(cfg, k) == v for k, v in live.items())
    assert cfg.antenna_sensor_noise == pytest.approx(1e-3, rel=0.1)  # the recording's noise sd
    changed = {k for k, v in cfg.as_values().items() if before.as_values()[k] != v}
    fitted = {*calibration.LENGTH_NAMES, 'driven_joint_offset', 'antenna_sensor_offset'}
    assert fitted <= changed <= fitted | set(live), changed
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
    """A recording whose joint states carry velocity and effort: the load model is fitted too, on the calibrated
    geometry with its uncertainty, and the node's parameters whose sds meet their targets are written to the file
    (the centre of mass only with the mass)."""
    load = {'antenna_mass': 2.0, 'com_offset_along': 0.03, 'com_offset_normal': 0.02, 'coulomb_friction': 0.05,
            'viscous_friction': 3.0, 'reducer_efficiency': 0.7}
    bag = write_calibration_bag(tmp_path / 'rec', Sweep(TRUTH, duration=120.0, cycles=2.0, load=load, seed=2))
    assert calibrate(tmp_path, bag) == 0
    report = json.loads((out / 'report.json').read_text())
    fitted = report['load']
    assert fitted['velocity'] == 'measured'
    assert fitted['noise_sd_N_m'] == pytest.approx(0.02, rel=0.1)
    for name, p in fitted['parameters'].items():
        assert abs(p['value'] - load[name]) <= 4.0 * p['sd'], name
    written = fitted['written_to_parameter_file']
    with capsys.disabled():
        print('\nload fitted (value, sd, target sd; truth):', {name: (f'{p["value"]:.4g}', f'{p["sd"]:.2g}',
              p['target_sd'] and f'{p["target_sd"]:.2g}', load[name]) for name, p in fitted['parameters'].items()},
              'written:', written)
    for name, p in fitted['parameters'].items():
        if p['target_sd'] is not None and p['sd'] <= p['target_sd'] and name != 'antenna_mass':
            mass = fitted['parameters']['antenna_mass']
            assert name in written or (name.startswith('com_') and mass['sd'] > mass['target_sd']), name
        assert name not in written or p['sd'] <= p['target_sd'], name
    cfg = load_config(out / 'calibrated.yaml')
    for name, value in written.items():
        assert getattr(cfg, name) == value
    assert 'load from the measured effort' in capsys.readouterr().out


def test_no_effort_no_load_model(tmp_path: Path, out: Path) -> None:
    bag = write_calibration_bag(tmp_path / 'rec', Sweep(TRUTH, duration=60.0))
    assert calibrate(tmp_path, bag) == 0
    assert json.loads((out / 'report.json').read_text())['load'] is None
    assert load_config(out / 'calibrated.yaml').antenna_mass == load_config(CONFIG).antenna_mass


# ---------------------------------------------------------------- a real sensor's faults

#: A sweep of 2 minutes, -6..+7 deg down and up twice: 6000 readings at 50 Hz.
FAULT_SWEEP = {'duration': 120.0, 'cycles': 2.0}


def absolute_error_in_sd(report: dict[str, object], truth: dict[str, float] = TRUTH) -> tuple[float, float]:
    """(largest |the node's angle - the truth| / its reported sd, largest error (rad)) over the report's grid: the
    truth is the true linkage at the measured joint plus the true correction, without the sensor's offset."""
    absolute = report['absolute_angle']
    assert isinstance(absolute, dict)
    cfg = load_config(CONFIG)
    joint = np.array(absolute['joint_rad'])
    antenna = np.array([*(truth[n] for n in PARAMETER_NAMES[:5]), 0.0])
    error = np.abs(np.array(absolute['theta_rad']) - predict(antenna, joint, cfg.driven, cfg.measured_branch))
    return float(np.max(error / np.array(absolute['sd_rad']))), float(np.max(error))


def map_error_in_sd(report: dict[str, object]) -> float:
    """The largest |the predicted sensor reading - the true noiseless one| over its reported sd, over the grid."""
    absolute = report['absolute_angle']
    assert isinstance(absolute, dict)
    cfg = load_config(CONFIG)
    truth = np.array([TRUTH[n] for n in PARAMETER_NAMES])
    error = np.abs(np.array(absolute['sensor_reading_rad'])
                   - predict(truth, np.array(absolute['joint_rad']), cfg.driven, cfg.measured_branch))
    return float(np.max(error / np.array(absolute['sensor_reading_sd_rad'])))


@pytest.fixture(scope='module')
def faults() -> Iterator[list[tuple[str, str, str, str]]]:
    """The fault recordings' table: (recording, absolute angle 1 sd, largest error (in sds), set by or refused),
    printed when the module ends (``python -m pytest -s test/commands/test_cli_calibrate.py``)."""
    rows: list[tuple[str, str, str, str]] = []
    yield rows
    print('\n| recording and options | absolute angle, 1 sd | error | set by, or the refusal |')
    print('| --- | --- | --- | --- |')
    for row in rows:
        print('| ' + ' | '.join(row) + ' |')


def tabled(faults: list[tuple[str, str, str, str]], name: str, report: dict[str, Any],
           truth: dict[str, float] = TRUTH) -> None:
    """Add a calibrated recording's row to the fault table."""
    in_sd, error = absolute_error_in_sd(report, truth)
    absolute = report['absolute_angle']
    faults.append((name, f'{1e3 * absolute["largest_sd_rad"]:.3g} mrad', f'{1e3 * error:.2g} mrad ({in_sd:.2f} sd)',
                   absolute['set_by']))


def test_the_summary_gives_the_map_and_the_absolute_angle(tmp_path: Path, out: Path,
                                                          capsys: pytest.CaptureFixture[str],
                                                          faults: list[tuple[str, str, str, str]]) -> None:
    bag = write_calibration_bag(tmp_path / 'rec', Sweep(TRUTH, **FAULT_SWEEP))
    assert calibrate(tmp_path, bag) == 0
    report = json.loads((out / 'report.json').read_text())
    absolute = report['absolute_angle']
    in_sd, _ = absolute_error_in_sd(report)
    assert in_sd <= 4.0  # a Gaussian error passes 4 sd once in 16000
    assert map_error_in_sd(report) <= 4.0
    assert absolute['sensor_map_largest_sd_rad'] < 1e-4  # hundredths of a mrad
    assert absolute['largest_sd_rad'] > 1e-3  # mrad: the offsets trade against each other
    assert sum(absolute['variance_shares_at_largest_sd'].values()) == pytest.approx(1.0, rel=1e-9)
    tabled(faults, 'a sweep, the default priors', report)
    printed = capsys.readouterr().out
    assert (f'the joint-to-sensor map is fixed to {1e3 * absolute["sensor_map_largest_sd_rad"]:.2g} mrad; the '
            f'antenna\'s absolute angle to {1e3 * absolute["largest_sd_rad"]:.2g} mrad, set by '
            f'{absolute["set_by"]}: ') in printed


def test_a_reference_pins_the_absolute_angle(tmp_path: Path, out: Path,
                                            faults: list[tuple[str, str, str, str]]) -> None:
    """A precision level on the antenna at one pose (0.05 mrad): the node's angle within 0.2 mrad of the truth over
    the whole range."""
    sweep = Sweep(TRUTH, **FAULT_SWEEP)
    bag = write_calibration_bag(tmp_path / 'rec', sweep)
    cfg = load_config(CONFIG)
    joint = float(sweep.measured_q(sweep.true_q(np.array([0.02])))[0])
    antenna = np.array([*(TRUTH[n] for n in PARAMETER_NAMES[:5]), 0.0])
    theta = float(predict(antenna, np.array([joint]), cfg.driven, cfg.measured_branch)[0])
    assert calibrate(tmp_path, bag, f'--reference={joint!r}:{theta!r}:5e-5') == 0
    report = json.loads((out / 'report.json').read_text())
    in_sd, error = absolute_error_in_sd(report)
    assert error < 2e-4 and in_sd <= 4.0
    assert report['absolute_angle']['set_by'] != 'the prior of sensor_offset (sd 0.1 rad)'
    assert report['references'][0]['joint_rad'] == joint
    tabled(faults, f'a sweep, `--reference {joint:.5f}:{theta:.5f}:5e-5`', report)


def test_a_datasheet_sensor_offset(tmp_path: Path, out: Path, faults: list[tuple[str, str, str, str]]) -> None:
    bag = write_calibration_bag(tmp_path / 'rec', Sweep(TRUTH, **FAULT_SWEEP))
    assert calibrate(tmp_path, bag, '--sensor-offset', '0.0041', '--sensor-offset-sd', '2e-4') == 0
    report = json.loads((out / 'report.json').read_text())
    assert absolute_error_in_sd(report)[0] <= 4.0
    assert report['absolute_angle']['set_by'] == 'the prior of sensor_offset (sd 0.0002 rad)'
    assert report['parameters']['sensor_offset']['prior'] == 0.0041
    tabled(faults, 'a sweep, `--sensor-offset 0.0041 --sensor-offset-sd 2e-4`', report)


def test_spikes_and_invalid_readings(tmp_path: Path, out: Path, capsys: pytest.CaptureFixture[str],
                                     faults: list[tuple[str, str, str, str]]) -> None:
    """Three +0.4 rad spikes, one +0.2 rad glitch and three NaN readings among 6000: the NaN dropped, the spikes set
    aside, both counted; the noise is the sensor's and the absolute angle within 4 sd."""
    glitches = ((700, 0.4), (2500, 0.4), (4100, 0.4), (3333, 0.2), (10, math.nan), (11, math.nan), (5000, math.nan))
    bag = write_calibration_bag(tmp_path / 'rec', Sweep(TRUTH, **FAULT_SWEEP, glitches=glitches))
    assert calibrate(tmp_path, bag) == 0
    report = json.loads((out / 'report.json').read_text())
    assert report['sensor_readings_invalid'] == 3 and report['readings_set_aside'] == 4
    assert report['noise_sd_rad'] == pytest.approx(1e-3, rel=0.05)  # 6000 readings: the sd's own sd is 0.9%
    assert report['largest_residual_rad'] < 6e-3
    assert absolute_error_in_sd(report)[0] <= 4.0
    assert '4 set aside as outliers, 3 invalid sensor readings dropped' in capsys.readouterr().out
    tabled(faults, '3 spikes of +0.4 rad, a +0.2 rad glitch, 3 NaN (4 set aside, 3 dropped)', report)


@pytest.mark.parametrize(('scale', 'cause'), [
    (-1.0, 'its sign is flipped (theta is positive tilting the antenna down)'),
    (math.degrees(1.0), 'it reports degrees, not rad')])
def test_a_sensor_of_the_wrong_sign_or_unit_is_refused(tmp_path: Path, out: Path, capsys: pytest.CaptureFixture[str],
                                                       scale: float, cause: str,
                                                       faults: list[tuple[str, str, str, str]]) -> None:
    bag = write_calibration_bag(tmp_path / 'rec', Sweep(TRUTH, **FAULT_SWEEP, sensor_scale=scale))
    assert calibrate(tmp_path, bag) == 1
    err = capsys.readouterr().err
    found = re.fullmatch(r'fourbar calibrate: error: the sensor moves (\S+) times as far as the model over the same '
                         r'joint motion \(expected 0\.8\.\.1\.25\): (.*)\n', err)
    assert found is not None, err
    # the design's model against the true linkage (lengths, the encoder's zero 0.7 deg off): 2.2% less span
    assert float(found[1]) == pytest.approx(scale * 0.978, rel=0.01)
    assert found[2] == cause
    assert list(out.iterdir()) == []
    faults.append((f'a sensor reading {scale:.4g} times theta', '-', '-', f'refused (exit 1): {found[2]}'))


def test_an_imu_rolled_15_deg(tmp_path: Path, out: Path, capsys: pytest.CaptureFixture[str],
                              faults: list[tuple[str, str, str, str]]) -> None:
    """The IMU turned 15 deg about the antenna's axis, with two all-zero readings: the tilt does not depend on the
    roll, which is reported; the driven joint's offset and the absolute angle within 4 sd of the truth."""
    sweep = Sweep(TRUTH, **FAULT_SWEEP, sensor='imu', imu_roll=math.radians(15.0), glitches=((99, math.nan),
                                                                                            (100, math.nan)))
    bag = write_calibration_bag(tmp_path / 'imu', sweep, angle_topic='/imu/data')
    assert calibrate(tmp_path, bag, topic='/imu/data') == 0
    report = json.loads((out / 'report.json').read_text())
    assert report['imu_roll_rad'] == pytest.approx(math.radians(15.0), abs=1e-3)  # 1 mrad noise on the tilt only
    assert report['sensor_readings_invalid'] == 2
    offset = report['parameters']['driven_joint_offset']
    assert abs(offset['value'] - TRUTH['driven_joint_offset']) <= 4.0 * offset['sd']
    assert absolute_error_in_sd(report)[0] <= 4.0
    # atan2(-a_x, a_z) would read the tilt 1/cos(15 deg) = 3.5% too large: the map would miss by 100s of its sds
    assert map_error_in_sd(report) <= 4.0
    assert 'the IMU rolled 15.00 deg about its x axis' in capsys.readouterr().out
    tabled(faults, 'an IMU rolled 15 deg about the antenna\'s axis, 2 all-zero readings (dropped)', report)


def test_an_imu_rolled_15_deg_and_yawed_5_deg(tmp_path: Path, out: Path, capsys: pytest.CaptureFixture[str],
                                             faults: list[tuple[str, str, str, str]]) -> None:
    """The IMU rolled 15 deg about the antenna's axis and turned 5 deg about its own z (x no longer along the
    antenna): the yaw is found from the great circle gravity traces over the sweep and undone, and written for the
    node's live check; the driven joint's offset, the map and the absolute angle within 4 sd of the truth."""
    sweep = Sweep(TRUTH, **FAULT_SWEEP, sensor='imu', imu_roll=math.radians(15.0), imu_yaw=math.radians(5.0))
    bag = write_calibration_bag(tmp_path / 'imu', sweep, angle_topic='/imu/data')
    assert calibrate(tmp_path, bag, topic='/imu/data') == 0
    report = json.loads((out / 'report.json').read_text())
    # the plane of 6000 readings with 1 mrad of noise on the tilt only: the yaw to a fraction of a mrad
    assert report['imu_yaw_rad'] == pytest.approx(math.radians(5.0), abs=1e-3)
    assert report['imu_roll_rad'] == pytest.approx(math.radians(15.0), abs=1e-3)
    offset = report['parameters']['driven_joint_offset']
    assert abs(offset['value'] - TRUTH['driven_joint_offset']) <= 4.0 * offset['sd']
    assert absolute_error_in_sd(report)[0] <= 4.0
    # untouched, the tilt reads sin(theta) cos(5 deg): 0.4% short, hundreds of the map's sds over the sweep
    assert map_error_in_sd(report) <= 4.0
    assert load_config(out / 'calibrated.yaml').antenna_imu_yaw == report['imu_yaw_rad']
    assert 'yawed 5.00 deg about its z axis' in capsys.readouterr().out
    tabled(faults, f'an IMU rolled 15 deg and yawed 5 deg (found {math.degrees(report["imu_yaw_rad"]):.3f} deg)',
           report)


def test_a_one_way_sweep_is_a_warning(tmp_path: Path, out: Path, capsys: pytest.CaptureFixture[str],
                                      faults: list[tuple[str, str, str, str]]) -> None:
    bag = write_calibration_bag(tmp_path / 'rec', Sweep(TRUTH, duration=120.0, cycles=0.5))
    assert calibrate(tmp_path, bag) == 0
    err = capsys.readouterr().err
    assert err.startswith('fourbar calibrate: warning: the recording sweeps the joint one way only')
    assert err.count('\n') == 1
    report = json.loads((out / 'report.json').read_text())
    assert report['warnings'] == [err.removeprefix('fourbar calibrate: warning: ').rstrip('\n')]
    assert absolute_error_in_sd(report)[0] <= 4.0
    tabled(faults, 'a sweep one way only (a warning)', report)


def test_a_parameter_far_from_its_prior_is_refused(tmp_path: Path, out: Path, capsys: pytest.CaptureFixture[str],
                                                   faults: list[tuple[str, str, str, str]]) -> None:
    """The sensor mounted 0.5 rad off, the prior 0 sd 0.1 rad: refused in one line naming it."""
    truth = {**TRUTH, 'sensor_offset': 0.5}
    bag = write_calibration_bag(tmp_path / 'rec', Sweep(truth, **FAULT_SWEEP))
    assert calibrate(tmp_path, bag) == 1
    err = capsys.readouterr().err
    assert err.startswith('fourbar calibrate: error: sensor_offset 0.49') and err.count('\n') == 1
    assert 'prior sds from its prior 0 (sd 0.1): the prior or the recording is wrong' in err
    assert list(out.iterdir()) == []
    faults.append(('a sensor mounted 0.5 rad off, the default prior', '-', '-',
                   f'refused (exit 1): {err.removeprefix("fourbar calibrate: error: ").strip()}'))
    # given as the mounting's prior, it calibrates
    assert calibrate(tmp_path, bag, '--sensor-offset', '0.5') == 0
    assert absolute_error_in_sd(json.loads((out / 'report.json').read_text()), truth)[0] <= 4.0


@pytest.mark.parametrize('bad', ['1:2', '0.1:0.2:0', 'a:b:c', '0.1:nan:1e-3'])
def test_a_malformed_reference_is_status_2(tmp_path: Path, out: Path, capsys: pytest.CaptureFixture[str],
                                           bad: str) -> None:
    assert calibrate(tmp_path, tmp_path / 'missing', f'--reference={bad}') == 2
    assert capsys.readouterr().err == (f"fourbar calibrate: error: --reference '{bad}': expected JOINT:THETA:SD in "
                                       'rad, finite, SD positive\n')


@pytest.fixture(scope='module')
def sweep_bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A short sweep that calibrates (the outputs then are what stops a run)."""
    return write_calibration_bag(tmp_path_factory.mktemp('sweep') / 'rec', Sweep(TRUTH, duration=30.0, cycles=2.0))


@pytest.mark.parametrize(('given', 'what'), [
    (('-o', 'x.yaml', '--report', 'x.yaml'), '--report {out}/x.yaml: the same file as -o {out}/x.yaml'),
    (('-o', 'x.yaml', '--report', 'sub/../x.yaml'), '--report {out}/sub/../x.yaml: the same file as -o {out}/x.yaml'),
    (('-o', 'x.yaml', '--report', 'x.png'), 'the residual plot {out}/x.png: the same file as --report {out}/x.png'),
    (('--report', 'x.png'), 'the residual plot {out}/x.png: the same file as --report {out}/x.png'),
])
def test_one_path_for_two_outputs_is_refused(tmp_path: Path, out: Path, capsys: pytest.CaptureFixture[str],
                                             sweep_bag: Path, given: tuple[str, ...], what: str) -> None:
    (out / 'sub').mkdir()
    argv = [str(out / a) if a.endswith(('.yaml', '.png')) else a for a in given]
    for bag in (sweep_bag, tmp_path / 'missing'):  # refused before the recording is read
        assert main(['calibrate', str(bag), '--params', str(CONFIG), '--angle-topic', '/antenna_inclinometer',
                     *argv]) == 2
        assert capsys.readouterr().err == (f'fourbar calibrate: error: {what.format(out=out)}; give each output a '
                                           'path of its own\n')
        assert [p.name for p in out.iterdir()] == ['sub'] and list((out / 'sub').iterdir()) == []


@pytest.mark.parametrize(('given', 'what'), [
    (('-o', 'calibrated.yaml', '--report', 'report.json'), '--report'),
    (('-o', 'calibrated.yaml', '--report', 'report.json'), '-o'),
    (('-o', 'calibrated.yaml'), 'the residual plot'),
])
def test_an_output_that_is_a_directory_is_refused(out: Path, capsys: pytest.CaptureFixture[str], sweep_bag: Path,
                                                  given: tuple[str, ...], what: str) -> None:
    argv = [str(out / a) if '.' in a else a for a in given]
    folder = out / 'calibrated.png' if what == 'the residual plot' else Path(argv[argv.index(what) + 1])
    folder.mkdir()
    assert main(['calibrate', str(sweep_bag), '--params', str(CONFIG), '--angle-topic', '/antenna_inclinometer',
                 *argv]) == 2
    assert capsys.readouterr().err == f'fourbar calibrate: error: {what} {folder}: is a directory\n'
    assert list(out.iterdir()) == [folder] and list(folder.iterdir()) == []


def test_a_sensor_with_correlated_noise(tmp_path: Path, out: Path, capsys: pytest.CaptureFixture[str],
                                        faults: list[tuple[str, str, str, str]]) -> None:
    """The sensor's noise filtered, AR(1) with a lag-1 correlation of 0.9: the 6000 readings count as about
    6000 (1 - 0.9) / (1 + 0.9) = 316 independent ones, and the map and the absolute angle stay within 4 of their
    widened sds (counted as 6000, the map's sds would be 4.4 times narrower: on this recording its error would be
    6 of them)."""
    bag = write_calibration_bag(tmp_path / 'rec', Sweep(TRUTH, **FAULT_SWEEP, noise_correlation=0.9))
    assert calibrate(tmp_path, bag) == 0
    report = json.loads((out / 'report.json').read_text())
    # the lag-1 estimate's own sd is sqrt((1 - 0.81) / 6000) = 0.006
    assert report['noise_lag1_correlation'] == pytest.approx(0.9, abs=0.03)
    assert report['independent_readings'] == pytest.approx(316, rel=0.25)
    assert map_error_in_sd(report) <= 4.0
    assert absolute_error_in_sd(report)[0] <= 4.0
    assert 'counts them as' in capsys.readouterr().out
    tabled(faults, f'noise with a lag-1 correlation of 0.9 ({report["independent_readings"]:.0f} independent '
           'readings)', report)


@pytest.mark.parametrize(('fault', 'latency', 'backlash', 'cause'), [
    ({'sensor_clock_offset': 0.1}, 0.1, 0.0, 'the sensor lags the encoder by 10'),
    ({'sensor_clock_offset': 0.3}, 0.3, 0.0, 'the sensor lags the encoder by 30'),
    ({'backlash': 0.002}, 0.0, 0.002, 'the drive has 2.'),
], ids=['latency-100ms', 'latency-300ms', 'backlash-2mrad'])
def test_a_latency_or_a_backlash_is_found_and_warned_of(tmp_path: Path, out: Path, capsys: pytest.CaptureFixture[str],
                                                        fault: dict[str, float], latency: float, backlash: float,
                                                        cause: str, faults: list[tuple[str, str, str, str]]) -> None:
    """A sensor 100 or 300 ms late, or 2 mrad of play in the drive, on sweeps both ways: the geometry is unbiased
    (the absolute angle within 4 sd), the latency and the backlash fitted to the residuals within 4 sd of the truth
    (the one absent within 4 sd of 0), and a warning names the one found."""
    bag = write_calibration_bag(tmp_path / 'rec', Sweep(TRUTH, **FAULT_SWEEP, **fault))
    assert calibrate(tmp_path, bag) == 0
    report = json.loads((out / 'report.json').read_text())
    found = report['direction_dependent']
    assert abs(found['latency_s'] - latency) <= 4.0 * found['latency_sd_s'], found
    assert abs(found['backlash_rad'] - backlash) <= 4.0 * found['backlash_sd_rad'], found
    assert absolute_error_in_sd(report)[0] <= 4.0
    assert map_error_in_sd(report) <= 4.0
    err = capsys.readouterr().err
    assert err.startswith(f'fourbar calibrate: warning: {cause}') and err.count('\n') == 1, err
    assert 'with the direction of motion' in err
    what = f'a sensor {1e3 * latency:.0f} ms late' if latency else f'{1e3 * backlash:.0f} mrad of play in the drive'
    tabled(faults, f'{what} (a warning: latency {1e3 * found["latency_s"]:.1f} ms sd '
           f'{1e3 * found["latency_sd_s"]:.2g}, backlash {1e3 * found["backlash_rad"]:.2f} mrad sd '
           f'{1e3 * found["backlash_sd_rad"]:.2g})', report)


def test_a_clean_sweep_shows_no_latency_nor_backlash(tmp_path: Path, out: Path,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    bag = write_calibration_bag(tmp_path / 'rec', Sweep(TRUTH, **FAULT_SWEEP))
    assert calibrate(tmp_path, bag) == 0
    found = json.loads((out / 'report.json').read_text())['direction_dependent']
    assert abs(found['latency_s']) <= 4.0 * found['latency_sd_s'] and found['latency_sd_s'] < 0.01, found
    assert abs(found['backlash_rad']) <= 4.0 * found['backlash_sd_rad'] and found['backlash_sd_rad'] < 2e-4, found
    assert capsys.readouterr().err == ''


#: Seeds of the z-score check: the sample RMS of 20 standard normal values has an sd of about 1/sqrt(40) = 0.16.
Z_SEEDS = 20


@pytest.mark.stress
def test_the_reported_sds_are_honest_over_seeds(tmp_path: Path) -> None:
    """Simulation-based calibration: for each seed the true lengths are drawn from the prior the fit uses (the
    parameter file's, sd 0.5 mm), the offsets from N(0, 0.01 rad) (their prior, sd 0.1 rad, barely counts against
    the data), the noise fresh; then every reported quantity's z = (estimate - truth) / reported sd is a standard
    normal if the sds are honest. Its RMS over the seeds (printed) must be near 1: between 0.5 and 1.6 (beyond 3.5
    of the sample RMS's own sd either way for honest sds; sds off by a factor 2 fall outside)."""
    cfg = load_config(CONFIG)
    rng = np.random.default_rng(7)
    zs: dict[str, list[float]] = {}
    for seed in range(Z_SEEDS):
        truth = {name: getattr(cfg, name) + rng.normal(0.0, 5e-4) for name in PARAMETER_NAMES[:4]}
        truth.update(driven_joint_offset=rng.normal(0.0, 0.01), sensor_offset=rng.normal(0.0, 0.01))
        out = tmp_path / f'out{seed}'
        out.mkdir()
        bag = write_calibration_bag(tmp_path / f'rec{seed}', Sweep(truth, **FAULT_SWEEP, seed=seed))
        assert main(['calibrate', str(bag), '--params', str(CONFIG), '--angle-topic', '/antenna_inclinometer',
                     '--report', str(out / 'report.json')]) == 0
        report = json.loads((out / 'report.json').read_text())
        for name, p in report['parameters'].items():
            zs.setdefault(name, []).append((p['value'] - truth[name]) / p['sd'])
        absolute = report['absolute_angle']
        joint = np.array(absolute['joint_rad'])
        values = np.array([*(truth[n] for n in PARAMETER_NAMES)])
        antenna = predict(np.array([*values[:5], 0.0]), joint, cfg.driven, cfg.measured_branch)
        reading = predict(values, joint, cfg.driven, cfg.measured_branch)
        for k, where in ((0, 'first'), (len(joint) // 2, 'middle'), (len(joint) - 1, 'last')):
            zs.setdefault(f'absolute angle, {where} grid point', []).append(
                (absolute['theta_rad'][k] - antenna[k]) / absolute['sd_rad'][k])
            zs.setdefault(f'sensor reading, {where} grid point', []).append(
                (absolute['sensor_reading_rad'][k] - reading[k]) / absolute['sensor_reading_sd_rad'][k])
        found = report['direction_dependent']
        zs.setdefault('latency', []).append(found['latency_s'] / found['latency_sd_s'])
        zs.setdefault('backlash', []).append(found['backlash_rad'] / found['backlash_sd_rad'])
    rms = {name: float(np.sqrt(np.mean(np.square(z)))) for name, z in zs.items()}
    print('z-score RMS over', Z_SEEDS, 'seeds:', {name: round(v, 2) for name, v in rms.items()})
    off = {name: v for name, v in rms.items() if not 0.5 <= v <= 1.6}
    assert not off, f'reported sds not honest (z RMS over {Z_SEEDS} seeds): {off}'
