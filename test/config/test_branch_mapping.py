"""The configured (forward) branch and from_rocker's branch differ for some geometries (here a coupler longer than
the frame): every path from a measured or planned driven-rocker angle back to theta must land on the configured
pose (``AntennaConfig.measured_branch``). No ROS."""

from __future__ import annotations

import importlib.util
import json
import math

import numpy as np
import pytest
from support.ulp_bounds import CHAIN_ULPS, EPS

from fourbar_ros.commands import main
from fourbar_ros.config.antenna_config import AntennaConfig, config_from_values, default_config
from fourbar_ros.core.antenna import Driven
from fourbar_ros.core.loads import pose
from fourbar_ros.motion.limits import JointLimits
from fourbar_ros.motion.planner import JointMotionState, driven_angles, plan_to_angle, trajectory_points
from fourbar_ros.motion.refine import dtheta_dq_bounds
from fourbar_ros.rules.simulated_drive import effort_at

#: frame 0.10 m, rockers 0.06 m, coupler 0.12 m: the forward solve's upper branch is from_rocker's lower one.
GEOMETRY = {'frame_length': 0.10, 'rocker_ab_length': 0.06, 'rocker_cd_length': 0.06, 'coupler_length': 0.12}


def long_coupler(driven: Driven = Driven.GAMMA) -> AntennaConfig:
    return config_from_values({**default_config().as_values(), **GEOMETRY, 'driven_rocker': driven.value})


@pytest.mark.parametrize('driven', list(Driven))
def test_the_branches_differ_here_and_the_mapping_gives_back_the_forward_pose(driven: Driven) -> None:
    cfg = long_coupler(driven)
    assert cfg.measured_branch is not cfg.branch  # the geometry this file is about
    assert default_config().measured_branch is default_config().branch  # Turnantenna: the same
    theta = np.linspace(cfg.theta_min, cfg.theta_max, 41)
    q = driven_angles(cfg, theta)
    back = np.asarray(cfg.linkage.from_rocker(q, driven, cfg.measured_branch).theta)
    wrong = np.asarray(cfg.linkage.from_rocker(q, driven, cfg.branch).theta)
    # Round trip forward and back: a few ulps of 1 + |theta| times |dtheta/dq| (<= 2 here, asserted).
    assert max(abs(b) for b in dtheta_dq_bounds(cfg)) <= 2.0
    assert np.max(np.abs(back - theta)) <= CHAIN_ULPS * EPS * 2.0 * 4
    assert np.min(np.abs(wrong - theta)) > 0.1  # the unmapped branch is another pose altogether


def test_the_simulated_actuators_effort_is_the_configured_poses() -> None:
    cfg = long_coupler()
    for theta in (cfg.theta_min, 0.0, cfg.theta_max):
        q = float(driven_angles(cfg, np.array([theta]))[0])
        want = pose(cfg, theta).input_torque
        # The same statics at theta recovered within a few ulps (above): relative CHAIN_ULPS-scale agreement.
        assert effort_at(cfg, q) == pytest.approx(want, rel=1e-12, abs=1e-15)


@pytest.mark.skipif(importlib.util.find_spec('ruckig') is None, reason='ruckig not installed (pip only)')
def test_planned_points_follow_the_configured_pose() -> None:
    cfg = long_coupler()
    limits = JointLimits.from_config(cfg)
    q0 = float(driven_angles(cfg, np.array([cfg.theta_min]))[0])
    points = trajectory_points(cfg, limits, plan_to_angle(cfg, limits, JointMotionState(q0), cfg.theta_max), 0.05)
    theta = np.asarray(points.antenna.theta)
    assert theta[0] == pytest.approx(cfg.theta_min, abs=1e-12) and theta[-1] == pytest.approx(cfg.theta_max, abs=1e-12)
    assert np.all((theta >= cfg.theta_min - 1e-12) & (theta <= cfg.theta_max + 1e-12))


@pytest.mark.parametrize('branch', ['upper', 'lower'])
def test_solve_measured_rocker_means_the_same_branch_as_theta(capsys: pytest.CaptureFixture[str],
                                                              branch: str) -> None:
    geometry = ['--frame', '0.10', '--rocker', '0.06', '--coupler', '0.12', '--branch', branch, '--json']
    for theta in (-0.1, 0.0, 0.1):
        assert main(['solve', '--theta', repr(theta), *geometry]) == 0
        forward = json.loads(capsys.readouterr().out)
        for rocker in Driven:
            assert main(['solve', f'--{rocker.value}', repr(forward[rocker.value]), *geometry]) == 0
            measured = json.loads(capsys.readouterr().out)
            for key in ('theta', 'gamma', 'delta'):  # forward and back, as above; rocker angles up to whole turns
                miss = math.remainder(measured[key] - forward[key], 2.0 * math.pi)
                assert abs(miss) <= CHAIN_ULPS * EPS * 2.0 * 4 * (1 + abs(forward[key])), (rocker, key)
            assert measured['theta'] == pytest.approx(forward['theta'], abs=1e-12)  # the same pose, not another
