"""The URDF robot model: generated from the node's parameters, REP-103 conventions, and both kinematic chains
meet at C when the joints take the solver's positions.

The forward kinematics (support.urdf_kinematics) reads only the URDF text: it shares no code with the core.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import replace
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pytest
from support.cli_support import fourbar
from support.paths import REPO
from support.urdf_kinematics import Matrix, link_poses, vector

from fourbar_ros.config.antenna_config import AntennaConfig, config_from_values, default_config, load_config
from fourbar_ros.config.robot_model import robot_description
from fourbar_ros.core.antenna import Branch, Driven
from fourbar_ros.core.completion import coupler_joint_position
from fourbar_ros.core.transforms import antenna_joint_positions

YAML = REPO / 'config' / 'antenna.yaml'
EPS = float(np.finfo(np.float64).eps)


def joint_positions(cfg: AntennaConfig, theta: float) -> dict[str, float]:
    """The node's JointState for command theta (rad), from the core's solve."""
    gamma, delta = cfg.linkage.rocker_angles(theta, cfg.branch)
    return {cfg.gamma_joint: float(gamma), cfg.delta_joint: float(delta),
            cfg.coupler_joint: coupler_joint_position(float(gamma), theta)}


def _configs() -> list[tuple[str, AntennaConfig]]:
    base = default_config()
    return [
        ('turnantenna', base),
        ('lower-branch', replace(base, branch=Branch.LOWER)),
        ('driven-delta', replace(base, driven=Driven.DELTA)),
        ('coupler-longer-than-frame', config_from_values({
            'frame_length': 0.1, 'rocker_ab_length': 0.08, 'coupler_length': 0.15, 'rocker_cd_length': 0.07,
            'theta_min': -0.2, 'theta_max': 0.3})),
        ('scaled-up', config_from_values({
            'frame_length': 1.8, 'rocker_ab_length': 0.6, 'coupler_length': 1.02, 'rocker_cd_length': 0.65,
            'theta_min': -0.3, 'theta_max': 0.2})),
    ]


CONFIGS = _configs()


@pytest.mark.parametrize(('name', 'cfg'), CONFIGS, ids=[c[0] for c in CONFIGS])
def test_both_chains_meet_at_c_with_the_solvers_joint_positions(name: str, cfg: AntennaConfig) -> None:
    urdf = robot_description(cfg)
    H, ab, h, cd = cfg.frame_length, cfg.rocker_ab_length, cfg.coupler_length, cfg.rocker_cd_length
    # Each point is a sum of at most four link vectors L_i u_i. Every unit vector carries the solver's angle error
    # (a few ulps: condition ~1 inside a configured tilt range), the rounding of gamma + theta, of sin/cos and of
    # up to five 3x3 products (a few ulps each): 16 ulps of the summed lengths covers all of it.
    bound = 16 * EPS * (H + ab + h + cd)
    worst = 0.0
    for i in range(41):
        theta = cfg.theta_min + (cfg.theta_max - cfg.theta_min) * i / 40
        poses = link_poses(urdf, joint_positions(cfg, theta))
        c_left, c_right = poses['coupler_c'][:3, 3], poses['rocker_cd_c'][:3, 3]
        gap = float(np.linalg.norm(c_left - c_right))
        worst = max(worst, gap)
        assert gap <= bound, f'{name}: theta={theta!r}: C through B and C through D are {gap:.3g} m apart'
    assert worst <= bound


@pytest.mark.parametrize(('name', 'cfg'), CONFIGS, ids=[c[0] for c in CONFIGS])
def test_frames_follow_rep103_and_the_planar_convention(name: str, cfg: AntennaConfig) -> None:
    """A at the root's origin, D at (H, 0, 0), everything in the x-z plane, z up; B and C where the planar
    convention (x along A->D, y up) puts them; the coupler's x axis along B->C; link frames at A, B, D."""
    urdf = robot_description(cfg)
    H, ab, h, cd = cfg.frame_length, cfg.rocker_ab_length, cfg.coupler_length, cfg.rocker_cd_length
    bound = 16 * EPS * (H + ab + h + cd)  # as above
    for theta in (cfg.theta_min, 0.5 * (cfg.theta_min + cfg.theta_max), cfg.theta_max):
        q = joint_positions(cfg, theta)
        poses = link_poses(urdf, q)
        planar = antenna_joint_positions(H, ab, h, cd, theta, q[cfg.joint_names[0]], q[cfg.joint_names[1]])

        def in_xz(p: npt.ArrayLike) -> Matrix:
            x, y = np.asarray(p, dtype=np.float64)
            return np.array([x, 0.0, y])

        np.testing.assert_allclose(poses[cfg.frame_id][:3, 3], [0.0, 0.0, 0.0], rtol=0, atol=0)
        np.testing.assert_allclose(poses['rocker_ab'][:3, 3], in_xz(planar.a), rtol=0, atol=bound)
        np.testing.assert_allclose(poses['rocker_cd'][:3, 3], [H, 0.0, 0.0], rtol=0, atol=0)
        np.testing.assert_allclose(poses['coupler'][:3, 3], in_xz(planar.b), rtol=0, atol=bound)
        np.testing.assert_allclose(poses['coupler_c'][:3, 3], in_xz(planar.c), rtol=0, atol=bound)
        for link, pose in poses.items():
            assert abs(pose[1, 3]) <= bound, f'{link} leaves the x-z plane'
            np.testing.assert_allclose(np.abs(pose[:3, 1]), [0.0, 1.0, 0.0], rtol=0, atol=4 * EPS)  # y: the joint axis
        # Link x axes: rocker AB along A->B, coupler along B->C (theta > 0 points it down), rocker CD along D->C.
        np.testing.assert_allclose(poses['rocker_ab'][:3, 0], in_xz(planar.b) / ab, rtol=0, atol=bound / ab)
        np.testing.assert_allclose(poses['coupler'][:3, 0], [math.cos(theta), 0.0, -math.sin(theta)],
                                   rtol=0, atol=bound / h)
        np.testing.assert_allclose(poses['rocker_cd'][:3, 0], (in_xz(planar.c) - [H, 0, 0]) / cd,
                                   rtol=0, atol=bound / cd)
        # Zero joint positions: both rockers lie on the frame line, pointing inwards (gamma from AD, delta from DA).
    zero = link_poses(urdf, dict.fromkeys(q, 0.0))
    np.testing.assert_allclose(zero['rocker_ab'][:3, 0], [1.0, 0.0, 0.0], rtol=0, atol=4 * EPS)
    np.testing.assert_allclose(zero['rocker_cd'][:3, 0], [-1.0, 0.0, 0.0], rtol=0, atol=4 * EPS)
    # Positive gamma and delta lift B and C (z up).
    lifted = link_poses(urdf, {**dict.fromkeys(q, 0.0), cfg.joint_names[0]: 0.1, cfg.joint_names[1]: 0.1})
    assert lifted['coupler'][2, 3] > 0.0 and lifted['rocker_cd_c'][2, 3] > 0.0


def test_model_has_every_node_joint_and_limits_spanning_the_tilt_range() -> None:
    cfg = default_config()
    robot = ET.fromstring(robot_description(cfg))
    movable = {j.attrib['name']: j for j in robot.findall('joint') if j.attrib['type'] != 'fixed'}
    assert set(movable) == set(cfg.joint_names)
    for theta in (cfg.theta_min, cfg.theta_max, 0.0):
        for joint, value in joint_positions(cfg, theta).items():
            limit = movable[joint].find('limit')
            assert limit is not None
            assert float(limit.attrib['lower']) <= value <= float(limit.attrib['upper']), (joint, theta)
    driven = movable[cfg.joint_names[0]].find('limit')
    assert driven is not None and float(driven.attrib['effort']) == cfg.output_torque_limit
    links = {link.attrib['name'] for link in robot.findall('link')}
    assert {'antenna', 'coupler_c', 'rocker_cd_c', cfg.frame_id} <= links


def test_lengths_come_from_the_parameter_file(tmp_path: Path) -> None:
    """No hand-kept copy: change the file and the model follows, through the command users run."""
    text = YAML.read_text(encoding='utf-8').replace('frame_length: 0.180', 'frame_length: 0.2')
    text = text.replace('frame_id: fourbar_base', 'frame_id: mast')
    params = tmp_path / 'robot.yaml'
    params.write_text(text, encoding='utf-8')
    out = fourbar('urdf', '--params', str(params))
    assert out.returncode == 0, out.stderr
    assert out.stdout == robot_description(load_config(params))
    robot = ET.fromstring(out.stdout)
    by_name = {j.attrib['name']: j for j in robot.findall('joint')}
    d_origin = by_name['rocker_cd_joint'].find('origin')
    assert d_origin is not None and vector(d_origin.attrib['xyz']).tolist() == [0.2, 0.0, 0.0]
    parent = by_name['rocker_ab_joint'].find('parent')
    assert parent is not None and parent.attrib['link'] == 'mast'


def test_default_output_is_the_shipped_configuration() -> None:
    out = fourbar('urdf', '--params', str(YAML))
    assert out.returncode == 0, out.stderr
    assert out.stdout == robot_description(load_config(YAML))


def test_bad_parameter_file_is_one_line_and_exit_2(tmp_path: Path) -> None:
    params = tmp_path / 'bad.yaml'
    params.write_text('/**:\n  ros__parameters:\n    frame_length: -1.0\n', encoding='utf-8')
    out_file = tmp_path / 'model.urdf'
    out = fourbar('urdf', '--params', str(params), '-o', str(out_file))
    assert out.returncode == 2
    assert out.stdout == ''
    assert len(out.stderr.strip().splitlines()) == 1 and 'frame_length' in out.stderr, out.stderr
    assert not out_file.exists() and list(tmp_path.iterdir()) == [params]


def test_output_file_is_written_whole(tmp_path: Path) -> None:
    out_file = tmp_path / 'model.urdf'
    out = fourbar('urdf', '-o', str(out_file))
    assert out.returncode == 0, out.stderr
    assert out_file.read_text(encoding='utf-8') == robot_description(default_config())
    assert sorted(p.name for p in tmp_path.iterdir()) == ['model.urdf']


def test_coupler_joint_name_comes_from_the_parameter_file(tmp_path: Path) -> None:
    params = tmp_path / 'named.yaml'
    params.write_text(YAML.read_text(encoding='utf-8').replace('coupler_joint: coupler_joint ',
                                                                'coupler_joint: bc_joint '), encoding='utf-8')
    out = fourbar('urdf', '--params', str(params))
    assert out.returncode == 0, out.stderr
    movable = {j.attrib['name'] for j in ET.fromstring(out.stdout).findall('joint') if j.attrib['type'] != 'fixed'}
    assert movable == {'rocker_ab_joint', 'bc_joint', 'rocker_cd_joint'}
