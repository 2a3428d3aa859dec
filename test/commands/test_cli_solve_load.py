"""`fourbar solve` prints the node's torque: the core's load model (constant load plus the antenna's weight at its
configured centre of mass) at the driven rocker, the same number the node publishes (``core.loads.pose_solver``
through ``rules.outputs.JointStateRule``) and `fourbar process` writes (``rules.outputs.outputs_block``). No ROS."""

from __future__ import annotations

import json
import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from support.cli_support import fourbar
from support.ulp_bounds import CHAIN_ULPS, assert_close_ulps, pose_scales

from fourbar_ros.config.antenna_config import AntennaConfig, load_config
from fourbar_ros.core.antenna import Driven
from fourbar_ros.core.loads import gravity_torque, pose
from fourbar_ros.rules.outputs import JointStateRule, outputs_block
from fourbar_ros.rules.velocity import VelocityState

#: (antenna_mass kg, load_torque N m, com_offset_along m, com_offset_normal m, driven rocker): weights with and
#: without offsets, a load that the weight partly cancels, both drives.
CASES = [
    (2.0, 2.0, 0.0, 0.0, 'gamma'),
    (4.0, 0.0, 0.0, 0.0, 'gamma'),
    (1.5, -1.0, 0.02, -0.01, 'gamma'),
    (3.0, 1.0, -0.01, 0.03, 'delta'),
    (0.5, 3.5, 0.03, 0.02, 'delta'),
]
#: Antenna angles (rad) over the default tilt range [-6, +7] deg, both ends included.
THETAS = [-0.10471975511965978, -0.091, 0.0, 0.06, 0.12217304763960307]


def params_file(tmp_path: Path, mass: float, load: float, along: float, normal: float, driven: str) -> Path:
    """A parameter file for the default linkage with this load (doubles written as Python's repr: exact)."""
    path = tmp_path / f'load_{mass}_{load}_{along}_{normal}_{driven}.yaml'
    path.write_text('/**:\n  ros__parameters:\n'
                    f'    antenna_mass: {mass!r}\n    load_torque: {load!r}\n'
                    f'    com_offset_along: {along!r}\n    com_offset_normal: {normal!r}\n'
                    f'    driven_rocker: {driven}\n', encoding='utf-8')
    return path


def solve_json(*argv: str | Path) -> dict[str, object]:
    out = fourbar('solve', *argv, '--json')
    assert out.returncode == 0, out.stderr
    value: dict[str, object] = json.loads(out.stdout)
    return value


def solve_text_torque(*argv: str | Path) -> float:
    """The input torque `fourbar solve` prints (text output: the repr of the double, N m)."""
    out = fourbar('solve', *argv)
    assert out.returncode == 0, out.stderr
    match = re.search(r'^ *input_torque: (\S+) N m$', out.stdout, re.MULTILINE)
    assert match, out.stdout
    return float(match.group(1))


def node_torque(cfg: AntennaConfig, theta: float) -> float:
    """The torque the node publishes for a served command theta (rad): input_torque and the JointState effort."""
    state = pose(cfg, theta)
    effort = JointStateRule(cfg).effort(state)
    assert effort[0 if cfg.driven is Driven.GAMMA else 1] == state.input_torque
    return state.input_torque


@pytest.mark.parametrize(('mass', 'load', 'along', 'normal', 'driven'), CASES)
def test_solve_prints_the_nodes_torque_with_the_antenna_weight(tmp_path: Path, mass: float, load: float,
                                                               along: float, normal: float, driven: str) -> None:
    params = params_file(tmp_path, mass, load, along, normal, driven)
    cfg = load_config(params)
    assert cfg.has_gravity_load and cfg.antenna_mass == mass and cfg.com_offset_normal == normal
    # The weight matters here: without it the torque differs by far more than any rounding (except at theta = 0
    # for a centre of mass on the coupler's midpoint, where the symmetric linkage's centre of mass is level).
    weightless = replace(cfg, antenna_mass=0.0)
    assert max(abs(node_torque(cfg, t) - pose(weightless, t).input_torque) for t in THETAS) > 0.1
    for theta in THETAS:
        want = node_torque(cfg, theta)
        # --theta: solve makes the node's calls (rocker_angles, rates_at, load_at_pose, torque_at) on the same
        # floats in the same order, so the doubles are equal, not merely close (JSON and text print the repr).
        v = solve_json('--params', params, '--theta', repr(theta))
        assert v['input_torque'] == want, (theta, v['input_torque'], want)
        assert solve_text_torque('--params', params, '--theta', repr(theta)) == want
        gamma, delta = cfg.linkage.rocker_angles(theta, cfg.branch)
        rates = cfg.linkage.rates_at(theta, gamma, delta)
        assert v['gravity_torque'] == gravity_torque(cfg, theta, gamma, rates.dgamma_dtheta)
        assert v['load_torque'] == load
        # A measured driven rocker: theta comes back from the rocker angle within a few ulps (|dtheta/dq| <= 1.2
        # over the tilt range), so the torque agrees within the bound of two float paths (ulp_bounds.pose_scales)
        # times 16, the margin the measured-rocker tests give a round trip.
        q = float(gamma if cfg.driven is Driven.GAMMA else delta)
        measured = solve_json('--params', params, f'--{driven}', repr(q))
        got = measured['input_torque']
        assert isinstance(got, float)
        _, _, tau_scale = pose_scales(cfg, np.array([theta]), np.array([want]))
        assert_close_ulps(got, want, 16 * CHAIN_ULPS, float(tau_scale[0]), f'measured {driven} at theta {theta!r}')


@pytest.mark.parametrize(('mass', 'load', 'along', 'normal', 'driven'), CASES[:2])
def test_process_writes_the_same_torque(tmp_path: Path, mass: float, load: float, along: float, normal: float,
                                        driven: str) -> None:
    """`fourbar process`'s block path (numpy) against solve's printed torque (math module): within the bound the
    rules tests hold the node's and process's paths to (CHAIN_ULPS of the torque's condition-weighted scale)."""
    params = params_file(tmp_path, mass, load, along, normal, driven)
    cfg = load_config(params)
    theta = np.array(THETAS)
    block = outputs_block(cfg, theta, np.arange(theta.size, dtype=np.int64) * 10**7, VelocityState())
    printed = np.array([solve_json('--params', params, '--theta', repr(t))['input_torque'] for t in THETAS])
    _, _, tau_scale = pose_scales(cfg, theta, printed)
    assert_close_ulps(block.input_torque, printed, CHAIN_ULPS, tau_scale, 'process against solve')


def test_without_a_weight_the_output_is_the_constant_load_only() -> None:
    v = solve_json('--theta', '0.06', '--load-torque', '2.0')
    assert v['gravity_torque'] == 0.0 and v['load_torque'] == 2.0
    out = fourbar('solve', '--theta', '0.06', '--load-torque', '2.0')
    assert 'gravity_torque' not in out.stdout  # printed only when there is a weight


def test_weight_at_the_reach_limit_is_undetermined_not_wrong(tmp_path: Path) -> None:
    """The weight's lever holds dgamma/dtheta, unbounded at the reach limit: null with a reason, never the constant
    load's torque (0 there) passed off as the answer."""
    params = params_file(tmp_path, 2.0, 0.0, 0.0, 0.0, 'gamma')
    theta = load_config(params).linkage.reach().theta_max
    v = solve_json('--params', params, '--theta', repr(theta))
    reasons = v['null_reasons']
    assert isinstance(reasons, dict)
    for key in ('input_torque', 'gravity_torque'):
        assert v[key] is None and 'reach limit' in reasons[key]
    text = fourbar('solve', '--params', params, '--theta', repr(theta)).stdout
    assert re.search(r'input_torque: none \(undetermined', text) and 'gravity_torque: none (' in text
