"""The completion rule: the measured driven joint completed to the whole linkage, per message and per block.

Checked: the completion of the configured forward pose gives back its theta and the other rocker (the branch
mapping, every driven rocker and branch, several geometries); the per-message path is the core's exact solution
(the same calls); the per-message and block paths agree within the ulp bound over the rocker's whole range, down to
1e-15 of its ends; the load torque of the effort the statics need gives back the load; what is left out where it is
unbounded; the range check. No ROS.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from support import ulp_jitter
from support.ulp_bounds import CHAIN_ULPS, EPS, assert_close_ulps, completion_scales

from fourbar_ros.config.antenna_config import AntennaConfig, config_from_values
from fourbar_ros.core.antenna import Branch, Driven
from fourbar_ros.core.completion import complete
from fourbar_ros.core.loads import pose
from fourbar_ros.core.numeric import DEAD_TOL, FloatArray
from fourbar_ros.rules.completion import (
    CompletionRule,
    complete_block,
    completed_names,
    joint_state_names,
    measured,
    turn_starts,
)

#: Geometries (frame, rocker AB, coupler, rocker CD in m; tilt range in rad) with either branch mapping.
GEOMETRIES = [
    {},
    {'frame_length': 0.5, 'rocker_ab_length': 0.3, 'coupler_length': 0.35, 'rocker_cd_length': 0.25,
     'theta_min': -0.2, 'theta_max': 0.2},
    {'frame_length': 0.18, 'rocker_ab_length': 0.31, 'coupler_length': 0.82, 'rocker_cd_length': 0.62,
     'theta_min': -0.2, 'theta_max': 0.2},  # a coupler longer than the frame: from_rocker counts the other branch
]


def configs() -> list[AntennaConfig]:
    out = []
    for geometry in GEOMETRIES:
        for driven in ('gamma', 'delta'):
            for branch in ('upper', 'lower'):
                try:
                    out.append(config_from_values({**geometry, 'driven_rocker': driven, 'branch': branch}))
                except ValueError:
                    continue
    return out


CONFIGS = configs()


def test_the_configs_cover_both_branch_mappings() -> None:
    mapped = {CompletionRule(cfg).branch == cfg.branch for cfg in CONFIGS}
    assert mapped == {True, False}, 'a geometry whose from_rocker branch differs from the configured one is needed'


@pytest.mark.parametrize('cfg', CONFIGS, ids=lambda c: f'{c.frame_length}-{c.driven.value}-{c.branch.name}')
def test_completing_the_forward_pose_gives_back_its_theta(cfg: AntennaConfig) -> None:
    rule = CompletionRule(cfg)
    for theta in np.linspace(cfg.theta_min, cfg.theta_max, 25).tolist():
        p = pose(cfg, theta)
        q, other = (p.gamma, p.delta) if cfg.driven is Driven.GAMMA else (p.delta, p.gamma)
        done = rule.one(q, None, p.input_torque)
        rates = cfg.linkage.rates_at(theta, p.gamma, p.delta)
        dq = float(rates[0] if cfg.driven is Driven.GAMMA else rates[1])
        # theta from q: n ulps of pi + |theta| + |q dtheta/dq| (core.completion's test), the forward solve's q
        # n ulps of 1 + |q| + |theta dq/dtheta|, carried by dtheta/dq.
        scale = math.pi + abs(theta) + abs(q / dq) + (1 + abs(q) + abs(theta * dq)) / abs(dq)
        assert_close_ulps(done.theta, theta, 2 * CHAIN_ULPS, scale, f'theta at {theta}')
        assert done.positions[0] == q and done.efforts == [p.input_torque, 0.0, 0.0]  # the measurement's own
        assert abs(done.positions[1] - other) < 1e-9  # the same assembly (the other branch is ~0.8 rad away)
        assert done.load_torque is not None
        assert done.load_torque == pytest.approx(cfg.load_torque, rel=1e-9)  # power balance: the load comes back


def dead_point_lever(cfg: AntennaConfig, rule: CompletionRule, q: float) -> tuple[float, float]:
    """The driven rocker's lever (sin of its angle to the coupler) at q, as the core's dead-point test computes it
    per message, and that test's threshold DEAD_TOL (1 + |q| + |theta|)."""
    c = complete(cfg.linkage, q, cfg.driven, rule.branch)
    theta, other = float(c.theta), float(c.other)
    gamma, delta = (q, other) if cfg.driven is Driven.GAMMA else (other, q)
    lever = math.sin(delta - theta if cfg.driven is Driven.GAMMA else gamma + theta)
    return lever, DEAD_TOL * (1.0 + abs(q) + abs(theta))


def rocker_angles(cfg: AntennaConfig) -> FloatArray:
    """Angles (rad) across the driven rocker's range, down to 1e-15 of it from either end, both signs."""
    r = cfg.linkage.rocker_reach(cfg.driven)
    fractions = np.concatenate([np.linspace(0.0, 1.0, 41), 1 - 10.0 ** -np.arange(1, 16), 10.0 ** -np.arange(1, 16)])
    mags = np.clip(r.theta_gap + fractions * (r.theta_max - r.theta_gap), r.theta_gap, r.theta_max)
    return np.concatenate([mags, -mags])


@pytest.mark.parametrize('cfg', CONFIGS, ids=lambda c: f'{c.frame_length}-{c.driven.value}-{c.branch.name}')
def test_per_message_and_block_paths_agree(cfg: AntennaConfig) -> None:
    rule = CompletionRule(cfg)
    q = rocker_angles(cfg)
    q_dot, effort = 0.37, -0.021  # rad/s, N m
    block = complete_block(cfg, q, np.full(q.size, q_dot), np.full(q.size, effort), rule)
    exact = complete(cfg.linkage, q, cfg.driven, rule.branch, q_rate=q_dot, effort=effort, on_invalid='nan')
    ok = block.valid
    assert ok.sum() > 0.9 * q.size
    assert np.array_equal(block.theta[ok], exact.theta[ok])  # the block is the core's array path, as is
    theta, other = block.theta[ok], block.positions[ok, 1]
    assert np.array_equal(block.positions[ok, 0], q[ok]) and (block.efforts[ok] == [effort, 0.0, 0.0]).all()
    qs = q[ok]
    theta_scale, other_scale, x_scale, rate_scale, other_rate_scale, load_scale = completion_scales(
        cfg.linkage, cfg.driven, qs, theta, other)
    n = 2 * CHAIN_ULPS  # two paths, each within CHAIN_ULPS of the scale
    for i, (qi, ti) in enumerate(zip(qs.tolist(), theta.tolist(), strict=True)):
        one = rule.one(qi, q_dot, effort)
        assert_close_ulps(one.theta, ti, n, theta_scale[i], f'theta at q={qi!r}')
        assert one.positions[0] == qi and one.efforts == [effort, 0.0, 0.0]
        assert_close_ulps(one.positions[1], other[i], n, other_scale[i], f'other at q={qi!r}')
        assert_close_ulps(one.positions[2], block.positions[ok][i, 2], n, x_scale[i], f'coupler at q={qi!r}')
        if bool(one.velocities) == bool(np.isnan(block.theta_rate[ok][i])):
            # the dead-point test (the lever's sine within the core's tolerance) decided differently by the paths'
            # ulps: only at a dead point (the rocker's range's end, or an inner one), where the inverse solve is at
            # its own fold and its angles carry the square root of their rounding, sqrt(64 eps) ~ 1.2e-7 rad: the
            # lever is that small there, whatever the path
            lever, limit = dead_point_lever(cfg, rule, qi)
            assert abs(lever) <= limit + math.sqrt(64 * EPS), (qi, lever, limit)
        elif one.velocities:
            assert_close_ulps(one.theta_rate, block.theta_rate[ok][i], n, q_dot * rate_scale[i], f'rate at {qi!r}')
            assert one.velocities[0] == q_dot == block.velocities[ok][i, 0]
            assert_close_ulps(one.velocities[1], block.velocities[ok][i, 1], n, q_dot * other_rate_scale[i],
                              f'other rate at q={qi!r}')
            assert_close_ulps(one.velocities[2], block.velocities[ok][i, 2], n,
                              q_dot * (1 + rate_scale[i] + other_rate_scale[i]), f'coupler rate at q={qi!r}')
        else:  # the dead point: unbounded in both paths
            assert np.isnan(block.velocities[ok][i]).all(), qi
        if one.load_torque is not None:
            assert_close_ulps(one.load_torque, block.load_torque[ok][i], n, abs(effort) * load_scale[i],
                              f'load at q={qi!r}')
        else:
            assert np.isnan(block.load_torque[ok][i]), qi
    assert not block.valid[~ok].any()


def test_nothing_unbounded_is_published_at_the_ends_of_the_ranges() -> None:
    for cfg in CONFIGS:
        rule = CompletionRule(cfg)
        top = rule.reach.theta_max
        reach = cfg.linkage.reach()
        limit_gamma, limit_delta = cfg.linkage.rocker_angles(reach.theta_max, cfg.branch)
        limit_q = float(limit_gamma if cfg.driven is Driven.GAMMA else limit_delta)
        # The driven rocker's reach limit (a dead point: the rates are unbounded, left out within the core's
        # tolerance) and the antenna's (rockers parallel: the load torque is unbounded, left out likewise).
        for q in (top, -top, math.nextafter(top, 0.0), limit_q):
            done = rule.one(q, 0.1, 0.01)
            values = [done.theta, *done.positions, *done.velocities, done.theta_rate or 0.0, done.load_torque or 0.0]
            assert all(math.isfinite(v) for v in values), (cfg, q, done)
            assert len(done.velocities) in (0, 3) and (done.theta_rate is None) == (not done.velocities)


def test_what_is_not_given_is_not_computed_and_names() -> None:
    cfg = CONFIGS[0]
    rule = CompletionRule(cfg)
    done = rule.one(0.5)
    assert done.velocities == [] and done.theta_rate is None and done.load_torque is None
    assert done.positions[0] == 0.5 and done.efforts == []
    assert list(completed_names(cfg)) == [cfg.delta_joint, cfg.coupler_joint]
    assert rule.names == list(joint_state_names(cfg)) == [cfg.gamma_joint, cfg.delta_joint, cfg.coupler_joint]
    block = complete_block(cfg, np.array([0.5, 0.6]), np.full(2, np.nan), np.array([np.nan, 0.01]))
    assert np.isnan(block.velocities).all() and np.isnan(block.theta_rate).all()
    assert np.isnan(block.load_torque[0]) and np.isfinite(block.load_torque[1])


def test_a_nan_velocity_or_effort_is_not_measured_and_an_infinite_one_is_refused() -> None:
    # joint_state_broadcaster publishes NaN for a state interface the joint lacks: that value is absent.
    assert measured(0.5, 0.1, -0.02) == (0.5, 0.1, -0.02)
    assert measured(0.5, None, None) == (0.5, None, None)
    assert measured(0.5, math.nan, -0.02) == (0.5, None, -0.02)
    assert measured(0.5, 0.1, -math.nan) == (0.5, 0.1, None)
    assert measured(0.5, math.nan, math.nan) == (0.5, None, None)
    for q in (math.nan, -math.nan, math.inf, -math.inf):  # no position: refused, whatever else it has
        assert measured(q, 0.1, 0.0) is None and measured(q, None, None) is None
    for bad in (math.inf, -math.inf):
        assert measured(0.5, bad, 0.0) is None and measured(0.5, 0.1, bad) is None
        assert measured(0.5, bad, math.nan) is None and measured(0.5, math.nan, bad) is None
    # What is not measured is not published: the same as a message without that array.
    rule = CompletionRule(CONFIGS[0])
    q, q_dot, effort = measured(0.5, math.nan, 0.01) or (0.0, 0.0, 0.0)
    assert rule.one(q, q_dot, effort) == rule.one(0.5, None, 0.01)
    assert rule.one(0.5, None, 0.01).velocities == [] and rule.one(0.5, None, 0.01).load_torque is not None


def test_range_check_names_the_value_and_the_range() -> None:
    rule = CompletionRule(CONFIGS[0])
    top = rule.reach.theta_max
    assert rule.in_reach(top) and rule.in_reach(-top) and not rule.in_reach(math.nextafter(top, 4.0))
    assert not rule.in_reach(math.nan) and not rule.in_reach(math.inf)
    line = rule.out_of_range(2.5)
    assert '2.5 rad' in line and rule.reach.describe() in line and '\n' not in line
    block = complete_block(CONFIGS[0], np.array([2.5, math.nan, math.inf, top]), np.zeros(4), np.zeros(4))
    assert block.valid.tolist() == [False, False, False, True]
    assert np.isnan(block.positions[:3]).all()


def test_branch_of_the_measured_rocker_is_explicit() -> None:
    for cfg in CONFIGS:
        assert CompletionRule(cfg).branch in (Branch.UPPER, Branch.LOWER)
    assert EPS > 0


@pytest.mark.parametrize('cfg', CONFIGS, ids=lambda c: f'{c.frame_length}-{c.driven.value}-{c.branch.name}')
def test_every_reachable_angle_lies_well_inside_its_published_turn(cfg: AntennaConfig) -> None:
    # Over the driven rocker's whole reach (both signs, up to its ends), each published passive angle keeps far
    # more than rounding (1e-6 rad) from the edges of its turn: no ulp of any CPU can move it by 2 pi. The
    # configured range's angles are those of the open-loop pose (its turn: the URDF's limits hold them).
    rule = CompletionRule(cfg)
    q = rocker_angles(cfg)
    block = complete_block(cfg, q, np.full(q.size, np.nan), np.full(q.size, np.nan), rule)
    for j, start in enumerate(turn_starts(cfg), start=1):
        v = block.positions[block.valid, j]
        assert ((v - start > 1e-6) & (start + 2 * math.pi - v > 1e-6)).all(), (j, start, v.min(), v.max())
    for theta in np.linspace(cfg.theta_min, cfg.theta_max, 7).tolist():
        p = pose(cfg, theta)
        q_i, other = (p.gamma, p.delta) if cfg.driven is Driven.GAMMA else (p.delta, p.gamma)
        done = rule.one(q_i)
        assert abs(done.positions[1] - other) < 1e-9 and abs(done.positions[2] - (p.gamma + theta)) < 1e-9


@pytest.mark.parametrize('direction', ulp_jitter.DIRECTIONS)
@pytest.mark.parametrize('seed', [0, 1])
def test_both_paths_publish_the_same_turn_as_on_another_cpu(seed: int, direction: str) -> None:
    # The angle that once sat on a turn's edge (the coupler joint of this lower-branch geometry at q = 1.6375...
    # rad, published 2.1598 rad by one path and -4.1234 rad by the other when one ulp moved): with numpy's and
    # the math module's results moved by one ulp, per message and per block, every CONFIG, the same turn.
    with ulp_jitter.jittered(1.0, seed, direction=direction, math_names=tuple(ulp_jitter.MATH_FUNCS)):
        for cfg in CONFIGS:
            rule = CompletionRule(cfg)
            q = rocker_angles(cfg)
            if cfg.frame_length == 0.5 and cfg.driven is Driven.GAMMA and cfg.branch is Branch.LOWER:
                q = np.append(q, 1.6375124752051218)
            block = complete_block(cfg, q, np.full(q.size, np.nan), np.full(q.size, np.nan), rule)
            for i in np.flatnonzero(block.valid).tolist():
                one = rule.one(float(q[i]))
                assert np.abs(np.array(one.positions) - block.positions[i]).max() < 1e-6, (cfg, q[i])
