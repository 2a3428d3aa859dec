"""`fourbar mjcf`, in this process: the model written (atomically) or printed, the same text as ``mjcf``, and
refusals in one line with status 2."""

from __future__ import annotations

from pathlib import Path

import pytest
from support.paths import REPO
from support_plant import mujoco, needs_mujoco

from fourbar_ros.commands import main as cli_main
from fourbar_ros.config.antenna_config import default_config, load_config
from fourbar_ros.plant.mjcf import DriveModel, mjcf

PARAMS = REPO / 'config' / 'antenna.yaml'


def run(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    status = cli_main(['mjcf', *argv])
    out = capsys.readouterr()
    return status, out.out, out.err


def test_it_writes_the_generated_model(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    target = tmp_path / 'plant.xml'
    target.write_text('old', encoding='utf-8')  # replaced whole
    assert run(['--params', str(PARAMS), '-o', str(target)], capsys) == (0, '', '')
    assert target.read_text(encoding='utf-8') == mjcf(load_config(PARAMS))
    assert sorted(p.name for p in tmp_path.iterdir()) == ['plant.xml']  # no temporary left


def test_without_output_it_prints_the_default_configurations_model(capsys: pytest.CaptureFixture[str]) -> None:
    status, out, err = run([], capsys)
    assert (status, err) == (0, '') and out == mjcf(default_config())


def test_the_drive_options_reach_the_model(capsys: pytest.CaptureFixture[str]) -> None:
    status, out, _ = run(['--rotor-inertia', '2e-5', '--kp', '2.0', '--kv', '0.01', '--timestep', '5e-4',
                          '--reducer-stiffness', '3000.0', '--backlash', '0.001'], capsys)
    drive = DriveModel(timestep=5e-4, rotor_inertia=2e-5, kp=2.0, kv=0.01, reducer_stiffness=3000.0, backlash=0.001)
    assert status == 0 and out == mjcf(default_config(), drive)
    assert 'springlength="-0.0005 0.0005"' in out
    status, out, _ = run(['--stepper-torque', '0.009', '--stepper-teeth', '200'], capsys)
    assert status == 0 and out == mjcf(default_config(), DriveModel(stepper_torque=0.009, stepper_teeth=200))


@needs_mujoco
def test_the_written_model_loads_in_mujoco(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    target = tmp_path / 'plant.xml'
    assert run(['-o', str(target)], capsys)[0] == 0
    model = mujoco.MjModel.from_xml_path(str(target))
    cfg = default_config()
    assert {model.joint(i).name for i in range(model.njnt)} == {*cfg.joint_names, f'{cfg.driven_joint}_motor'}


@pytest.mark.parametrize(('argv', 'message'), [
    (['-o', '{tmp}'], '-o {tmp}: is a directory'),
    (['-o', '{tmp}/missing/plant.xml'], '{tmp}/missing/plant.xml: directory {tmp}/missing does not exist'),
    (['--params', str(PARAMS), '-o', str(PARAMS)], f'-o {PARAMS}: the same file as the input {PARAMS}; give each '
                                                   'output a path of its own'),
    (['--backlash', '0.001'], 'backlash: needs a compliant reducer (reducer_stiffness)'),
    (['--kp', '-1.0'], 'kp: must be a positive finite number, got -1.0'),
    (['--stepper-teeth', '0'], 'stepper_teeth: must be at least 1, got 0'),
    (['--params', '{tmp}/none.yaml'], '{tmp}/none.yaml: cannot read: No such file or directory'),
])
def test_refusals_are_one_line_with_status_2(argv: list[str], message: str, tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    argv = [a.format(tmp=tmp_path) for a in argv]
    status, out, err = run(argv, capsys)
    assert (status, out) == (2, '')
    assert err == f'fourbar mjcf: error: {message.format(tmp=tmp_path)}\n'
    assert PARAMS.read_text(encoding='utf-8').startswith('# fourbar_node parameters')  # the input untouched
