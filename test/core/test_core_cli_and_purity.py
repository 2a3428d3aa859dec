"""`fourbar solve` end to end, and the core's promise to import no ROS."""

from __future__ import annotations

import json
import math
import subprocess
import sys

import pytest
from support.cli_support import fourbar
from support.paths import REPO

CONFIG = REPO / 'config' / 'antenna.yaml'

KNOWN = [
    (-6.0, 40.921022829819, 56.378807215667, 1.518562886208, -0.981111583723),
    (0.0, 49.458398126495, 49.458398126495, 1.307692307692, -1.307692307692),
    (7.0, 57.328038082382, 39.390113547656, 0.916954003692, -1.542784836266),
]


@pytest.mark.parametrize(('theta', 'gamma', 'delta', 'dg', 'dd'), KNOWN)
def test_solve_json_reproduces_notes_table(theta: float, gamma: float, delta: float, dg: float,
                                            dd: float) -> None:
    out = fourbar('solve', '--theta', str(theta), '--deg', '--params', str(CONFIG), '--json')
    assert out.returncode == 0, out.stderr
    v = json.loads(out.stdout)
    assert {'theta', 'gamma', 'delta', 'dgamma_dtheta', 'ddelta_dtheta', 'input_torque',
            'mechanical_advantage'} <= set(v)
    assert abs(math.degrees(v['gamma']) - gamma) < 1e-10
    assert abs(math.degrees(v['delta']) - delta) < 1e-10
    assert abs(v['dgamma_dtheta'] - dg) < 1e-12 and abs(v['ddelta_dtheta'] - dd) < 1e-12
    # Shipped load: 3.5 N m design wind, gamma driven: tau_in * dq/dtheta = tau_load.
    assert v['input_torque'] * v['mechanical_advantage'] == pytest.approx(3.5, rel=1e-14)
    assert v['mechanical_advantage'] == v['dgamma_dtheta']


def test_solve_text_and_geometry_flags() -> None:
    out = fourbar('solve', '--theta', '0.05', '--frame', '0.18', '--rocker', '0.06', '--coupler', '0.102',
                  '--load-torque', '2', '--driven', 'delta')
    assert out.returncode == 0, out.stderr
    assert 'input_torque' in out.stdout and 'N m' in out.stdout and 'driven rocker delta' in out.stdout


@pytest.mark.parametrize(('args', 'match'), [
    (['--theta', '50', '--deg'], 'out of reach; reachable: [-0.686404945843 rad (-39.3281 deg)'),
    (['--theta', 'nan'], 'theta=nan is not a number; reachable:'),
    (['--theta', 'inf'], 'theta=inf is not finite'),
    (['--theta', '0', '--frame', '1.0'], 'never assembles'),
    (['--theta', '0', '--frame', '-1'], 'frame=-1.0 m must be finite and positive'),
    (['--theta', '0', '--params', 'config/antenna.yaml', '--frame', '0.2'], 'exclude each other'),
    (['--theta', '0', '--params', 'no/such/file.yaml'], 'no/such/file.yaml'),
    (['--theta', '0', '--load-torque', 'nan'], 'must be finite'),
])
def test_solve_bad_input_exits_2_with_one_line(args: list[str], match: str) -> None:
    out = fourbar('solve', *args)
    assert out.returncode == 2
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1, out.stderr
    assert lines[0].startswith('fourbar solve: error: ') and match in lines[0]
    assert out.stdout == ''


#: What `fourbar solve` loads: the core, the configuration and the command line (the core's own purity: test_layers).
CORE_MODULES = ['fourbar_ros', 'fourbar_ros.core.antenna', 'fourbar_ros.core.general', 'fourbar_ros.config.params',
                'fourbar_ros.config.antenna_config', 'fourbar_ros.commands', 'fourbar_ros.commands.solve']


def test_core_imports_no_ros() -> None:
    code = ('import sys\n'
            f'for m in {CORE_MODULES!r}: __import__(m)\n'
            'from fourbar_ros.commands import build_parser\n'
            'build_parser()\n'
            "bad = sorted(m for m in sys.modules if m.split('.')[0] in "
            "{'rclpy', 'std_msgs', 'sensor_msgs', 'rosbags', 'matplotlib', 'mcap'})\n"
            'print(bad)\n')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, check=True, timeout=60)
    assert out.stdout.strip() == '[]'
