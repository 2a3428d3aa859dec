"""Usage errors of every `fourbar` subcommand (a mistyped option, a bad choice, a missing argument) are one line on
stderr in the form of every other error, `fourbar <command>: error: ...`, with a pointer to `--help`; status 2."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest
from support.paths import REPO

from fourbar_ros.commands import build_parser, command_names
from fourbar_ros.commands import main as cli_main


def _subcommands() -> list[str]:
    action = next(a for a in build_parser()._actions if a.dest == 'command')
    assert action.choices is not None
    return sorted(action.choices)


def _usage_error(argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    with pytest.raises(SystemExit) as info:
        cli_main(argv)
    assert info.value.code == 2
    captured = capsys.readouterr()
    assert captured.out == ''
    return captured.err


@pytest.mark.parametrize('command', _subcommands())
def test_every_subcommand_reports_usage_in_one_line(command: str,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    err = _usage_error([command, '--no-such-option-xyz'], capsys)  # or its missing arguments, whichever first
    assert err.startswith(f'fourbar {command}: error: ') and err.count('\n') == 1, err
    assert err.endswith(f' (see fourbar {command} --help)\n'), err


@pytest.mark.parametrize(('argv', 'message'), [
    (['design', '--pairs', '0.1,0.2', '0.3,0.5', '0.9,1.1', '--parms', 'x'], 'unrecognized arguments: --parms x'),
    (['replay', 'bag', '--rte', '2'], 'unrecognized arguments: --rte 2'),
    (['solve', '--theta', '0.1', '--driven', 'beta'],
     "argument --driven: invalid choice: 'beta' (choose from 'gamma', 'delta')"),
    (['check', '--driven', 'beta'], "argument --driven: invalid choice: 'beta' (choose from 'gamma', 'delta')"),
    (['record', 'out', '--storage', 'rosbag1'],
     "argument --storage: invalid choice: 'rosbag1' (choose from mcap, sqlite3)"),
    (['process', 'in', 'out', '--storage', 'db3'],
     "argument --storage: invalid choice: 'db3' (choose from mcap, sqlite3)"),
    (['solve'], 'one of the arguments --theta --gamma --delta is required'),
    (['solve', '--theta', 'abc'], "argument --theta: invalid float value: 'abc'"),
])
def test_reported_usage_errors(argv: list[str], message: str, capsys: pytest.CaptureFixture[str]) -> None:
    err = _usage_error(argv, capsys)
    assert err == f'fourbar {argv[0]}: error: {message} (see fourbar {argv[0]} --help)\n'


def test_no_or_unknown_command_is_one_line_of_the_top_level(capsys: pytest.CaptureFixture[str]) -> None:
    assert _usage_error([], capsys) == ('fourbar: error: the following arguments are required: COMMAND '
                                        '(see fourbar --help)\n')
    err = _usage_error(['sovle'], capsys)
    assert err.startswith("fourbar: error: argument COMMAND: invalid choice: 'sovle'") and err.count('\n') == 1


def test_the_console_script_prints_the_same_line() -> None:
    out = subprocess.run([sys.executable, '-m', 'fourbar_ros.commands', 'solve', '--theta', '0.1', '--rte', '2'],
                         capture_output=True, text=True, timeout=60, check=False)
    assert (out.returncode, out.stdout) == (2, '')
    assert out.stderr == 'fourbar solve: error: unrecognized arguments: --rte 2 (see fourbar solve --help)\n'


def test_only_the_chosen_command_is_imported() -> None:
    """`fourbar calibrate` imports the calibrate module alone (each command imports what it needs: a command line is
    not slowed by the others'); `fourbar --help` lists them all."""
    probe = ('import sys\nfrom fourbar_ros.commands import build_parser\n'
             'argv = ["calibrate", "BAG", "--params", "P.yaml", "--angle-topic", "/a"]\n'
             'args = build_parser("calibrate").parse_args(argv)\n'
             'print(args._prog, sorted(m for m in sys.modules if m.startswith("fourbar_ros.commands.")))\n')
    path = os.pathsep.join(filter(None, (str(REPO), os.environ.get('PYTHONPATH'))))
    out = subprocess.run([sys.executable, '-c', probe], capture_output=True, text=True, timeout=120, check=True,
                         env={**os.environ, 'PYTHONPATH': path})
    assert out.stdout == "fourbar calibrate ['fourbar_ros.commands.calibrate']\n"
    listing = build_parser().format_help()
    assert all(name in listing for name in command_names())
