"""Defaults found through the installed share/ (config.share.share_path), and the one error path of the commands
(a command raises, `fourbar_ros.commands.main` prints one line and returns the status). No ROS running."""

from __future__ import annotations

import argparse
import itertools
import os
import subprocess
import sys
from pathlib import Path

import pytest
from support.paths import REPO

from fourbar_ros.commands import CommandError, build_parser, main
from fourbar_ros.config.share import share_path
from fourbar_ros.live.node_process import FREE_DOMAIN_IDS


def _indexed_prefix(root: Path, config_text: str) -> Path:
    """A prefix as `colcon build` leaves it: fourbar_ros in the ament index, share/fourbar_ros/config/antenna.yaml."""
    index = root / 'share' / 'ament_index' / 'resource_index' / 'packages'
    index.mkdir(parents=True)
    (index / 'fourbar_ros').write_text('')
    config = root / 'share' / 'fourbar_ros' / 'config'
    config.mkdir(parents=True)
    (config / 'antenna.yaml').write_text(config_text)
    return root


def test_share_path_prefers_the_ament_index(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    prefix = _indexed_prefix(tmp_path / 'install', 'x: 1\n')
    monkeypatch.setenv('AMENT_PREFIX_PATH', str(prefix))
    assert share_path('config/antenna.yaml') == prefix / 'share' / 'fourbar_ros' / 'config' / 'antenna.yaml'
    # Not in that share: the package data (the bag) or the source tree.
    assert share_path('bags/demo_sweep') == REPO / 'fourbar_ros' / 'data' / 'demo_sweep'


def test_share_path_falls_back_to_the_source_tree(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv('AMENT_PREFIX_PATH', str(tmp_path))  # an index without fourbar_ros
    assert share_path('config/antenna.yaml') == REPO / 'config' / 'antenna.yaml'
    assert (share_path('bags/demo_sweep') / 'metadata.yaml').is_file()


def test_share_path_without_any_ros_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    """A plain pip/venv setup has no AMENT_PREFIX_PATH: ament_index_python then raises OSError, which must not
    escape (`make demo` on a fresh clone failed with that traceback)."""
    monkeypatch.delenv('AMENT_PREFIX_PATH', raising=False)
    assert share_path('config/antenna.yaml') == REPO / 'config' / 'antenna.yaml'


def test_demo_default_params_come_from_the_installed_share(tmp_path: Path) -> None:
    """From a directory without config/, `fourbar demo` with no arguments reads the indexed share's file.

    The share's file is invalid on purpose, so the demo stops with its one-line error before ROS starts, and
    the line names the file it read.
    """
    good = (REPO / 'config' / 'antenna.yaml').read_text(encoding='utf-8')
    bad = good.replace('theta_max: 0.', 'theta_max: 1.')
    assert bad != good
    prefix = _indexed_prefix(tmp_path / 'install', bad)
    cwd = tmp_path / 'elsewhere'
    cwd.mkdir()
    env = {**os.environ, 'AMENT_PREFIX_PATH': str(prefix)}
    out = subprocess.run([sys.executable, '-m', 'fourbar_ros.commands', 'demo'], cwd=cwd, env=env,
                         capture_output=True, text=True, timeout=120, check=False)
    expected = prefix / 'share' / 'fourbar_ros' / 'config' / 'antenna.yaml'
    assert out.returncode == 2, out.stderr
    lines = out.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith(f'fourbar demo: error: {expected}: '), lines
    assert out.stdout == '' and list(cwd.iterdir()) == []  # nothing written


class _Parser:
    """Stands in for build_parser(): its parse_args gives a command whose run raises CommandError(status)."""

    def __init__(self, status: int) -> None:
        self.status = status

    def parse_args(self, argv: object) -> argparse.Namespace:
        def run(_: argparse.Namespace) -> int:
            raise CommandError('the node went away', status=self.status)
        return argparse.Namespace(_run=run, _prog='fourbar replay')


@pytest.mark.parametrize('status', [1, 2, 3])
def test_main_alone_prints_the_error_and_returns_its_status(status: int, capsys: pytest.CaptureFixture[str],
                                                            monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr('fourbar_ros.commands.build_parser', lambda only=None: _Parser(status))
    assert main([]) == status
    captured = capsys.readouterr()
    assert captured.out == '' and captured.err == 'fourbar replay: error: the node went away\n'


@pytest.mark.parametrize('argv', [['design', '--pairs', '1,2'], ['check', '--samples', '1'],
                                  ['solve', '--theta', 'nan'], ['urdf', '--params', '/nonexistent.yaml'],
                                  ['replay', 'x', '--window', '0'], ['record', 'x', '--wait', '0'],
                                  ['demo', '--domain-id', '300', '--params', str(REPO / 'config' / 'antenna.yaml')]])
def test_command_errors_are_raised_not_printed(argv: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    """Each command raises its error; the message main prints is the exception's, once."""
    args = build_parser().parse_args(argv)
    with pytest.raises(Exception) as info:
        args._run(args)
    assert capsys.readouterr().err == ''  # the command itself printed nothing
    assert main(argv) == 2
    assert capsys.readouterr().err == f'fourbar {argv[0]}: error: {info.value}\n'


def test_demo_domain_id_help_says_what_free_domain_id_does(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(['demo', '--help'])
    text = ' '.join(capsys.readouterr().out.split())
    assert '101 down to 1' not in text
    # The ids free_domain_id tries, as ranges: 90..101 and 215..232 today.
    runs = [FREE_DOMAIN_IDS[0]] + [b for a, b in itertools.pairwise(FREE_DOMAIN_IDS) if b != a + 1]
    assert len(runs) == 2
    assert f'{FREE_DOMAIN_IDS[0]}..' in text and f'{runs[1]}..{FREE_DOMAIN_IDS[-1]}' in text
    assert 'lock file' in text and 'discovery ports' in text
