"""`fourbar zero` end to end on synthetic recordings at rest (in process): the driven joint's zero within its
reported 4 sd of the truth, spikes set aside, the parameter file written with it and read back by the node's own
reader; a joint that moves is refused in one line."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from support.paths import REPO

from fourbar_ros.bags.calibration_sweep import Sweep, write_calibration_bag
from fourbar_ros.commands import main
from fourbar_ros.commands._param_file import param_file_with
from fourbar_ros.config.antenna_config import load_config

TRUTH = {'frame_length': 0.1803, 'rocker_ab_length': 0.0598, 'coupler_length': 0.1021, 'rocker_cd_length': 0.0602,
         'driven_joint_offset': -math.radians(0.7), 'sensor_offset': 0.004}
#: Five seconds at rest at 0.05 rad: 250 readings of 1 mrad noise.
REST = {'theta_range': (0.05, 0.05), 'duration': 5.0}


@pytest.fixture
def calibrated(tmp_path: Path) -> Path:
    """The parameter file as `fourbar calibrate` would leave it: the true lengths and sensor offset, the encoder's
    zero not yet corrected (driven_joint_offset 0)."""
    values = {name: TRUTH[name] for name in ('frame_length', 'rocker_ab_length', 'coupler_length',
                                             'rocker_cd_length')}
    values.update(antenna_sensor_offset=TRUTH['sensor_offset'], driven_joint_offset=0.0)
    path = tmp_path / 'calibrated.yaml'
    path.write_text(param_file_with(REPO / 'config' / 'antenna.yaml', tmp_path / 'sweep', values, 'test'))
    return path


def zero(bag: Path, params: Path, *extra: str) -> int:
    return main(['zero', str(bag), '--params', str(params), '--angle-topic', '/antenna_inclinometer', *extra])


def parse(out: str) -> tuple[float, float]:
    words = out.split()
    return float(words[1]), float(words[4])  # 'driven_joint_offset X rad (sd Y rad ...'


@pytest.mark.parametrize('seed', [0, 1, 2])
def test_the_zero_from_the_sensor_at_rest(tmp_path: Path, calibrated: Path, capsys: pytest.CaptureFixture[str],
                                          seed: int) -> None:
    bag = write_calibration_bag(tmp_path / 'rest', Sweep(TRUTH, **REST, seed=seed))
    out = tmp_path / 'zeroed.yaml'
    assert zero(bag, calibrated, '-o', str(out)) == 0
    printed = capsys.readouterr().out
    offset, sd = parse(printed)
    # the encoder reads q_true - driven_joint_offset, so the offset to add is the truth's
    assert abs(offset - TRUTH['driven_joint_offset']) <= 4.0 * sd, printed
    assert 1e-5 < sd < 1e-3  # 250 readings of 1 mrad: a few 0.1 mrad at the rocker
    assert load_config(out).driven_joint_offset == offset
    assert f'wrote {out}' in printed


def test_spikes_at_rest_are_set_aside(tmp_path: Path, calibrated: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bag = write_calibration_bag(tmp_path / 'rest', Sweep(TRUTH, **REST, glitches=((30, 0.3), (31, math.nan))))
    assert zero(bag, calibrated) == 0
    printed = capsys.readouterr().out
    offset, sd = parse(printed)
    assert abs(offset - TRUTH['driven_joint_offset']) <= 4.0 * sd, printed
    assert '(1 set aside)' in printed


def test_a_moving_joint_is_refused(tmp_path: Path, calibrated: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bag = write_calibration_bag(tmp_path / 'moving', Sweep(TRUTH, duration=5.0))
    out = tmp_path / 'zeroed.yaml'
    assert zero(bag, calibrated, '-o', str(out)) == 1
    err = capsys.readouterr().err
    assert err.startswith('fourbar zero: error: the joint moved ') and err.endswith('record the antenna at rest\n')
    assert err.count('\n') == 1 and not out.exists()
