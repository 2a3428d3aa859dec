"""`fourbar solve` tells what happened: strict JSON, the pose at the reach limit, out of reach vs outside the limits
(angles are numbers, not wrapped), messages that print true and distinct numbers; and decide() agrees (no ROS)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
from support.cli_support import fourbar

from fourbar_ros.config.antenna_config import default_config
from fourbar_ros.rules.policy import Outcome, Policy, decide, in_reach

CFG = default_config()
LO, HI = CFG.theta_min, CFG.theta_max
REACH = CFG.linkage.reach()


def strict_json(text: str) -> dict[str, object]:
    def refuse(constant: str) -> object:
        raise AssertionError(f'{constant} is not JSON')

    value: dict[str, object] = json.loads(text, parse_constant=refuse)
    return value


def test_overflowing_torque_is_null_with_a_reason() -> None:
    out = fourbar('solve', '--theta', '7', '--deg', '--load-torque', '1.7e308', '--json')
    assert out.returncode == 0, out.stderr
    v = strict_json(out.stdout)
    assert v['input_torque'] is None and v['load_torque'] == 1.7e308
    reasons = v['null_reasons']
    assert isinstance(reasons, dict) and set(reasons) == {'input_torque'} and 'overflow' in reasons['input_torque']
    assert isinstance(v['gamma'], float)  # the pose is still there
    text = fourbar('solve', '--theta', '7', '--deg', '--load-torque', '1.7e308')
    assert text.returncode == 0 and 'input_torque: none (overflow' in text.stdout and 'inf' not in text.stdout


@pytest.mark.parametrize('sign', [1.0, -1.0])
def test_pose_at_the_exact_reach_limit_with_unbounded_rates(sign: float) -> None:
    theta = sign * REACH.theta_max
    out = fourbar('solve', '--theta', repr(theta), '--json')
    assert out.returncode == 0, out.stderr
    v = strict_json(out.stdout)
    gamma, delta = CFG.linkage.rocker_angles(theta)
    assert v['theta'] == theta and v['gamma'] == gamma and v['delta'] == delta
    reasons = v['null_reasons']
    assert isinstance(reasons, dict)
    for key in ('dgamma_dtheta', 'ddelta_dtheta', 'mechanical_advantage'):
        assert v[key] is None and 'reach limit' in reasons[key]
    assert isinstance(v['transmission_angle'], float)
    text = fourbar('solve', '--theta', repr(theta))
    assert text.returncode == 0 and 'dgamma_dtheta: none (unbounded: theta is at the reach limit' in text.stdout


def test_inside_json_has_no_nulls() -> None:
    v = strict_json(fourbar('solve', '--theta', '0.05', '--json').stdout)
    assert v['null_reasons'] == {} and all(v[k] is not None for k in ('dgamma_dtheta', 'input_torque'))


@pytest.mark.parametrize(('theta', 'words'), [
    ('1e308', ['theta=1e+308 rad is out of reach']),
    (repr(2 * math.pi + 0.05), ['is out of reach', 'not taken modulo 2 pi']),
    (repr(-2 * math.pi), ['is out of reach', 'not taken modulo 2 pi']),
])
def test_out_of_reach_as_a_number(theta: str, words: list[str]) -> None:
    out = fourbar('solve', '--theta', theta)
    assert out.returncode == 2 and out.stdout == ''
    line = out.stderr.strip()
    assert '\n' not in line and 'inf deg' not in line
    for word in words:
        assert word in line


@pytest.mark.parametrize(('theta', 'policy', 'verdict'), [
    ('0.5', 'reject', '; rejected'), ('-0.5', 'clamp', '; clamped to theta_min'), ('0.05', 'reject', None)])
def test_outside_the_limits_is_a_note_of_the_nodes_verdict(theta: str, policy: str, verdict: str | None,
                                                           tmp_path: Path) -> None:
    """The pose is solved; the last line says what the node's policy (``decide``) does with such a command."""
    params = tmp_path / 'params.yaml'
    params.write_text(f'fourbar_node:\n  ros__parameters:\n    out_of_limits: {policy}\n')
    out = fourbar('solve', '--theta', theta, '--params', params)
    assert out.returncode == 0 and 'out of reach' not in out.stdout
    last = out.stdout.splitlines()[-1]
    if verdict is None:
        assert not last.startswith('note:')
        return
    assert last.startswith(f'note: as a command, the node would not serve it as is: command {theta} rad')
    assert 'outside the limits' in last and verdict in last


# ---------------------------------------------------------------- decide(): the node's policy, same convention

@pytest.mark.parametrize('command', [1e308, -1e308, 2 * math.pi + 0.05, -2 * math.pi - 0.05, 4 * math.pi])
def test_far_commands_are_out_of_reach_not_out_of_limits(command: float) -> None:
    assert not in_reach(REACH, command)
    d = decide(command, LO, HI, Policy.REJECT, REACH)
    assert d.outcome is Outcome.REJECTED_OUT_OF_REACH and 'out of reach' in d.reason
    assert 'inf' not in d.reason and '\n' not in d.reason
    c = decide(command, LO, HI, Policy.CLAMP, REACH)
    assert c.outcome is Outcome.CLAMPED and c.theta == (HI if command > 0 else LO) and 'out of reach' in c.reason


@pytest.mark.parametrize(('command', 'side'), [(0.5, 'above theta_max'), (-0.5, 'below theta_min'),
                                               (math.nextafter(HI, 1.0), 'above theta_max'),
                                               (math.nextafter(LO, -1.0), 'below theta_min')])
def test_inside_the_reach_outside_the_limits(command: float, side: str) -> None:
    assert in_reach(REACH, command)
    d = decide(command, LO, HI, Policy.REJECT, REACH)
    assert d.outcome is Outcome.REJECTED_OUT_OF_LIMITS
    assert 'outside the limits' in d.reason and 'out of reach' not in d.reason and side in d.reason
    limit = HI if command > 0 else LO
    # One ulp past a limit: the two doubles print differently (repr), and the excess is stated.
    assert repr(command) in d.reason and repr(limit) in d.reason and repr(command) != repr(limit)
    assert f'by {abs(command - limit):.3g} rad' in d.reason


def test_reach_edges_as_numbers() -> None:
    assert in_reach(REACH, REACH.theta_max) and in_reach(REACH, -REACH.theta_max)
    assert not in_reach(REACH, math.nextafter(REACH.theta_max, 1.0))
    assert not in_reach(REACH, math.nan) and not in_reach(REACH, math.inf)
