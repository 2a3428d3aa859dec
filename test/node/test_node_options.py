"""The options of the nodes' console scripts outside ``--ros-args``: ``--help`` prints them and exits 0 without
starting the node; an unknown option is one line and status 2. Both scripts parse them alike."""

from __future__ import annotations

import subprocess
import sys

import pytest

from fourbar_ros.interface.topics import NODE_EXECUTABLE, SIM_EXECUTABLE

#: The console scripts' entry points (setup.py), started as the scripts start them.
ENTRY = {NODE_EXECUTABLE: 'main', SIM_EXECUTABLE: 'sim_actuator_main'}
TIMEOUT = 60  # s: a deadline for a process that should exit at once (not a timing assertion)


def _run(executable: str, *args: str) -> subprocess.CompletedProcess[str]:
    code = f'import sys; from fourbar_ros.node import {ENTRY[executable]}; sys.exit({ENTRY[executable]}())'
    return subprocess.run([sys.executable, '-c', code, *args], capture_output=True, text=True, timeout=TIMEOUT,
                          check=False, stdin=subprocess.DEVNULL)


@pytest.mark.parametrize('executable', list(ENTRY))
def test_help_prints_the_options_and_starts_nothing(executable: str) -> None:
    out = _run(executable, '--help')
    assert out.returncode == 0, out.stderr
    assert out.stdout.startswith(f'usage: {executable} ') and '--executor' in out.stdout and '--ros-args' in out.stdout
    assert 'callbacks run on' not in out.stdout + out.stderr  # the node never started


@pytest.mark.parametrize('executable', list(ENTRY))
def test_an_unknown_option_is_one_line(executable: str) -> None:
    out = _run(executable, '--no-such-option', '--ros-args', '-p', 'frame_length:=0.18')
    assert out.returncode == 2 and out.stdout == ''
    assert out.stderr == f'{executable}: error: unrecognized arguments: --no-such-option\n'
