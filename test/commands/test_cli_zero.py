"""`fourbar zero` end to end on synthetic recordings at rest (in process): the driven joint's zero within its
reported 4 sd of the truth, spikes and non-finite readings set aside and counted, the parameter file written with
it and read back by the node's own reader; a joint that moves, a recording without enough finite readings and an
output that cannot be written are refused in one line, nothing written."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from support.paths import REPO

from fourbar_ros.bags.calibration_sweep import Sweep, write_calibration_bag
from fourbar_ros.commands import CommandError, main
from fourbar_ros.commands._param_file import param_file_with, write_atomically
from fourbar_ros.config.antenna_config import load_config
from fourbar_ros.core.calibration import SET_ASIDE_SDS

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
    assert f'(2 set aside: 1 beyond {SET_ASIDE_SDS:g} noise sds, 1 not finite)' in printed


def test_a_moving_joint_is_refused(tmp_path: Path, calibrated: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bag = write_calibration_bag(tmp_path / 'moving', Sweep(TRUTH, duration=5.0))
    out = tmp_path / 'zeroed.yaml'
    assert zero(bag, calibrated, '-o', str(out)) == 1
    err = capsys.readouterr().err
    assert err.startswith('fourbar zero: error: the joint moved ') and err.endswith('record the antenna at rest\n')
    assert err.count('\n') == 1 and not out.exists()


@pytest.mark.parametrize('bad', [math.nan, math.inf, -math.inf])
def test_non_finite_readings_are_counted_as_set_aside(tmp_path: Path, calibrated: Path,
                                                      capsys: pytest.CaptureFixture[str], bad: float) -> None:
    half = tuple((i, bad) for i in range(0, 250, 2))
    bag = write_calibration_bag(tmp_path / 'rest', Sweep(TRUTH, **REST, glitches=half))
    assert zero(bag, calibrated) == 0
    printed = capsys.readouterr().out
    offset, sd = parse(printed)
    assert abs(offset - TRUTH['driven_joint_offset']) <= 4.0 * sd, printed
    assert f'from 125 readings at rest (125 set aside: 0 beyond {SET_ASIDE_SDS:g} noise sds, 125 not finite)' in \
        printed


@pytest.mark.parametrize('finite', [0, 1])
def test_a_recording_without_enough_finite_readings_is_refused(tmp_path: Path, calibrated: Path,
                                                               capsys: pytest.CaptureFixture[str], finite: int) -> None:
    bad = (math.nan, math.inf, -math.inf)
    bag = write_calibration_bag(tmp_path / 'rest', Sweep(TRUTH, **REST, glitches=tuple(
        (i, bad[i % 3]) for i in range(finite, 250))))
    out = tmp_path / 'zeroed.yaml'
    assert zero(bag, calibrated, '-o', str(out)) == 1
    err = capsys.readouterr().err
    want = (f'{bag}: no finite sensor reading' if finite == 0 else
            f'{bag}: 249 of the 250 readings on /antenna_inclinometer are not finite (NaN or inf), leaving 1 paired '
            'with the joint states: too few for a zero')
    assert err == f'fourbar zero: error: {want}\n'
    assert not out.exists()


def test_an_output_that_is_a_directory_is_refused(tmp_path: Path, calibrated: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    bag = write_calibration_bag(tmp_path / 'rest', Sweep(TRUTH, **REST))
    folder = tmp_path / 'zeroed.yaml'
    folder.mkdir()
    assert zero(tmp_path / 'missing', calibrated, '-o', str(folder)) == 2  # before the recording is read
    assert capsys.readouterr().err == f'fourbar zero: error: -o {folder}: is a directory\n'
    assert zero(bag, calibrated, '-o', str(folder)) == 2
    assert capsys.readouterr().err == f'fourbar zero: error: -o {folder}: is a directory\n'
    assert list(folder.iterdir()) == [] and sorted(p.name for p in tmp_path.iterdir()) == [
        'calibrated.yaml', 'rest', 'zeroed.yaml']


def test_a_failed_write_names_the_target_and_writes_nothing(tmp_path: Path) -> None:
    (tmp_path / 'folder').mkdir()
    for files, named in (({tmp_path / 'a.yaml': b'a', tmp_path / 'folder': b'b'}, 'folder'),
                         ({tmp_path / 'a.yaml': b'a', tmp_path / 'gone' / 'b.json': b'b'}, 'gone/b.json')):
        with pytest.raises(CommandError) as err:
            write_atomically(files)
        assert str(err.value).startswith(f'cannot write {tmp_path / named}: '), err.value
        assert sorted(p.name for p in tmp_path.iterdir()) == ['folder'] and list((tmp_path / 'folder').iterdir()) == []
