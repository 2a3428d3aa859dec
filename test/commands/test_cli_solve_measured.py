"""`fourbar solve --gamma V / --delta V`: the pose a measured rocker angle completes, as the same JSON as --theta,
and the second derivatives for every input form (in process, no ROS)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from support.ulp_bounds import CHAIN_ULPS, EPS

from fourbar_ros.commands import main
from fourbar_ros.config.antenna_config import default_config
from fourbar_ros.core.antenna import Driven

CFG = default_config()
LINK = CFG.linkage


def solve_json(capsys: pytest.CaptureFixture[str], *argv: str) -> dict[str, object]:
    assert main(['solve', *argv, '--json']) == 0
    out = capsys.readouterr().out

    def refuse(constant: str) -> object:
        raise AssertionError(f'{constant} is not JSON')

    value: dict[str, object] = json.loads(out, parse_constant=refuse)
    return value


def as_float(v: object) -> float:
    assert isinstance(v, float), v
    return v


@pytest.mark.parametrize('driven', list(Driven))
@pytest.mark.parametrize('theta_deg', [-6.0, 0.0, 7.0])
def test_measured_rocker_gives_the_theta_pose(capsys: pytest.CaptureFixture[str], driven: Driven,
                                              theta_deg: float) -> None:
    forward = solve_json(capsys, '--theta', str(theta_deg), '--deg')
    q = as_float(forward[driven.value])
    measured = solve_json(capsys, f'--{driven.value}', repr(q))
    assert measured.keys() == forward.keys() and measured['null_reasons'] == {}
    assert measured[driven.value] == q  # the measured angle is printed as given
    for key in ('theta', 'gamma', 'delta', 'dgamma_dtheta', 'ddelta_dtheta', 'd2gamma_dtheta2', 'd2delta_dtheta2',
                'input_torque'):
        # Round trip through the forward solve and back: well conditioned here (|dq/dtheta| >= 0.9, the dead
        # points at +-19.3 deg are far), so a few ulps of 1 + |value| times the amplification |dtheta/dq| <= 1.2.
        want, got = as_float(forward[key]), as_float(measured[key])
        assert abs(got - want) <= CHAIN_ULPS * EPS * 16 * (1 + abs(want)), (key, got, want)


@pytest.mark.parametrize('driven', list(Driven))
def test_a_measured_rocker_angle_gives_back_the_pose_it_came_from(capsys: pytest.CaptureFixture[str],
                                                                 driven: Driven) -> None:
    """Over the whole tilt range, the rocker angle of a pose of the configured branch gives that pose back. Both of
    from_rocker's poses can be poses of that branch with the same rocker angle (for gamma at theta = 0: theta 0 and
    0.626 rad), so the choice is the node's branch (measured_branch), not which pose gives the rocker angle back
    closer in its last ulps."""
    for theta in np.linspace(CFG.theta_min, CFG.theta_max, 201).tolist():
        gamma, delta = LINK.rocker_angles(theta, CFG.branch)
        q = float(gamma if driven is Driven.GAMMA else delta)
        got = as_float(solve_json(capsys, f'--{driven.value}', repr(q))['theta'])
        # theta from the rocker angle: a few ulps of 1 + |theta| times |dtheta/dq| <= 1.2 over the tilt range.
        assert abs(got - theta) <= CHAIN_ULPS * EPS * 16 * (1 + abs(theta)), (q, got, theta)


def test_degrees_and_second_derivatives_are_the_cores(capsys: pytest.CaptureFixture[str]) -> None:
    v = solve_json(capsys, '--delta', '45', '--deg')
    theta, gamma = LINK.from_rocker(math.radians(45.0), Driven.DELTA, CFG.measured_branch)
    assert v['theta'] == theta and v['gamma'] == gamma and v['delta'] == math.radians(45.0)
    second = LINK.second_derivatives_at(theta, gamma, math.radians(45.0))
    assert (v['d2gamma_dtheta2'], v['d2delta_dtheta2']) == tuple(second)
    t = solve_json(capsys, '--theta', '0.05')
    assert (t['d2gamma_dtheta2'], t['d2delta_dtheta2']) == tuple(LINK.rocker_second_derivatives(0.05, CFG.branch))
    assert main(['solve', '--gamma', '0.9']) == 0
    text = capsys.readouterr().out
    assert 'd2gamma_dtheta2: ' in text and 'd2delta_dtheta2: ' in text and ' /rad' in text


def test_second_derivatives_at_the_reach_limit_are_null_with_a_reason(capsys: pytest.CaptureFixture[str]) -> None:
    v = solve_json(capsys, '--theta', repr(LINK.reach().theta_max))
    reasons = v['null_reasons']
    assert isinstance(reasons, dict)
    for key in ('d2gamma_dtheta2', 'd2delta_dtheta2'):
        assert v[key] is None and 'reach limit' in reasons[key]


@pytest.mark.parametrize('driven', list(Driven))
@pytest.mark.parametrize('value', ['2.0', '-1.2', 'nan', 'inf'])
def test_out_of_the_rockers_range_is_one_line_status_2(capsys: pytest.CaptureFixture[str], driven: Driven,
                                                       value: str) -> None:
    assert main(['solve', f'--{driven.value}', value]) == 2
    captured = capsys.readouterr()
    err = captured.err.strip()
    assert captured.out == '' and '\n' not in err and 'Traceback' not in err
    top = LINK.rocker_reach(driven).theta_max
    assert f'q={float(value)!r}' in err and f'the {driven.value} rocker' in err and f'{top:.12g}' in err


def test_one_input_form_only(capsys: pytest.CaptureFixture[str]) -> None:
    for argv in (['--theta', '0.1', '--gamma', '0.9'], ['--gamma', '0.9', '--delta', '0.9'], []):
        with pytest.raises(SystemExit) as exc:
            main(['solve', *argv])
        assert exc.value.code == 2
        err = capsys.readouterr().err
        # One line in the form of every other error, naming the input options.
        assert err.count('\n') == 1 and err.startswith('fourbar solve: error: ') and '--gamma' in err, err
