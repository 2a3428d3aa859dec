"""The node's pure helpers, without ROS: command policy, loads, state cache, velocities, markers, diagnostics."""

from __future__ import annotations

import math

import numpy as np
import pytest
from support.ulp_bounds import CHAIN_ULPS, assert_close_ulps, pose_scales

from fourbar_ros.config.antenna_config import AntennaConfig, config_from_values, default_config
from fourbar_ros.core.antenna import Driven, LinkageState
from fourbar_ros.core.errors import FourBarError
from fourbar_ros.core.loads import (
    com_height_rate,
    gravity_torque,
    load_torque,
    motor_torque,
    pose_solver,
    poses,
    solve,
)
from fourbar_ros.core.transforms import antenna_joint_positions
from fourbar_ros.rules.diagnostics import Counters, Level, SequenceGaps, summarize
from fourbar_ros.rules.marker_geometry import linkage_points
from fourbar_ros.rules.policy import Outcome, Policy, decide
from fourbar_ros.rules.state_cache import StateCache
from fourbar_ros.rules.velocity import Sample, velocity_step

CFG = default_config()
LO, HI = CFG.theta_min, CFG.theta_max
REACH = CFG.linkage.reach()


# ----------------------------------------------------------------------------- command policy

@pytest.mark.parametrize('policy', list(Policy))
@pytest.mark.parametrize('command', [math.nan, math.inf, -math.inf])
def test_non_finite_always_rejected(policy: Policy, command: float) -> None:
    d = decide(command, LO, HI, policy, REACH)
    assert d.theta is None and d.outcome is Outcome.REJECTED_NOT_FINITE and d.outcome.rejected
    assert 'not finite' in d.reason and '\n' not in d.reason


@pytest.mark.parametrize('policy', list(Policy))
@pytest.mark.parametrize('command', [LO, HI, 0.0, -0.0, 0.5 * (LO + HI)])
def test_inside_and_exactly_at_limits_accepted_unchanged(policy: Policy, command: float) -> None:
    d = decide(command, LO, HI, policy, REACH)
    assert d.outcome is Outcome.ACCEPTED and d.theta == command and d.reason == ''


@pytest.mark.parametrize(('command', 'limit', 'rejected_as'), [
    (math.nextafter(HI, math.inf), HI, Outcome.REJECTED_OUT_OF_LIMITS),
    (math.nextafter(LO, -math.inf), LO, Outcome.REJECTED_OUT_OF_LIMITS),
    (0.5, HI, Outcome.REJECTED_OUT_OF_LIMITS),       # reachable, above the limit
    (1.0, HI, Outcome.REJECTED_OUT_OF_REACH),        # beyond the 39.3 deg reach
    (-3.0, LO, Outcome.REJECTED_OUT_OF_REACH),
    (1e300, HI, Outcome.REJECTED_OUT_OF_REACH),
])
def test_out_of_limits_reject_or_clamp(command: float, limit: float, rejected_as: Outcome) -> None:
    rejected = decide(command, LO, HI, Policy.REJECT, REACH)
    assert rejected.theta is None and rejected.outcome is rejected_as and 'rejected' in rejected.reason
    clamped = decide(command, LO, HI, Policy.CLAMP, REACH)
    assert clamped.outcome is Outcome.CLAMPED and clamped.theta == limit and 'clamped' in clamped.reason
    assert not clamped.outcome.rejected


# ----------------------------------------------------------------------------- loads

def test_solve_without_mass_is_the_core_state() -> None:
    for theta in np.linspace(LO, HI, 27):
        assert solve(CFG, float(theta)) == CFG.linkage.state(float(theta), 3.5, Driven.GAMMA)


@pytest.mark.parametrize('driven', ['gamma', 'delta'])
def test_power_balance_with_constant_load(driven: str) -> None:
    cfg = config_from_values({'driven_rocker': driven})
    for theta in np.linspace(LO, HI, 27):
        s = solve(cfg, float(theta))
        assert s.input_torque * s.mechanical_advantage == pytest.approx(cfg.load_torque, rel=1e-12)


def _com_height(cfg: AntennaConfig, theta: float) -> float:
    """Centre-of-mass height from the transform-matrix joint positions (independent of loads.py)."""
    g, d = cfg.linkage.rocker_angles(theta, cfg.branch)
    pos = antenna_joint_positions(cfg.frame_length, cfg.rocker_ab_length, cfg.coupler_length,
                                  cfg.rocker_cd_length, theta, g, d)
    b, c = pos.b, pos.c
    u = (c - b) / np.linalg.norm(c - b)
    n = np.array([-u[1], u[0]])
    com = b + (0.5 * cfg.coupler_length + cfg.com_offset_along) * u + cfg.com_offset_normal * n
    return float(com[1])


@pytest.mark.parametrize(('along', 'normal'), [(0.0, 0.0), (0.03, 0.0), (0.0, 0.05), (-0.02, -0.04)])
def test_gravity_torque_is_the_derivative_of_potential_energy(along: float, normal: float) -> None:
    cfg = config_from_values({'antenna_mass': 2.0, 'com_offset_along': along, 'com_offset_normal': normal,
                              'load_torque': 0.0})
    step = 1e-6
    for theta in np.linspace(LO, HI, 9):
        t = float(theta)
        s = cfg.linkage.state(t)
        numeric = (_com_height(cfg, t + step) - _com_height(cfg, t - step)) / (2 * step)
        assert com_height_rate(cfg, t, float(s.gamma), float(s.dgamma_dtheta)) == pytest.approx(
            numeric, rel=1e-6, abs=1e-9)
        expected = 2.0 * 9.80665 * numeric
        assert gravity_torque(cfg, t, float(s.gamma), float(s.dgamma_dtheta)) == pytest.approx(
            expected, rel=1e-6, abs=1e-8)
        full = solve(cfg, t)
        # Power balance at the rocker with the pose-dependent load.
        assert full.input_torque * full.mechanical_advantage == pytest.approx(
            load_torque(cfg, t, float(full.gamma), float(full.dgamma_dtheta)), rel=1e-12, abs=1e-15)


@pytest.mark.parametrize('driven', ['gamma', 'delta'])
@pytest.mark.parametrize('mass', [0.0, 1.5])
def test_pose_is_the_same_floats_as_solve(mass: float, driven: str) -> None:
    cfg = config_from_values({'antenna_mass': mass, 'com_offset_normal': 0.02, 'driven_rocker': driven})
    bound = pose_solver(cfg)
    for theta in np.linspace(LO, HI, 7):
        full = solve(cfg, float(theta))
        assert bound(float(theta)) == (full.gamma, full.delta, full.input_torque)


@pytest.mark.parametrize('branch', ['upper', 'lower'])
@pytest.mark.parametrize('driven', ['gamma', 'delta'])
@pytest.mark.parametrize('mass', [0.0, 1.5])
def test_the_scalar_and_the_array_pose_agree(mass: float, driven: str, branch: str) -> None:
    """pose_solver (one angle, math module) and poses (an array, numpy) over the whole reach, past its ends and
    at non-finite angles: the same angles solved (NaN on the array path where the scalar path raises), values
    within CHAIN_ULPS of their condition-weighted scales (ulp_bounds.pose_scales). Within a few ulps of the reach's
    ends, whether an angle is reachable is decided by rounding (reach() and the solve round on their own), so
    there the two paths need not agree on it; where both solve, their values are compared too."""
    cfg = config_from_values({'antenna_mass': mass, 'com_offset_normal': 0.02, 'driven_rocker': driven,
                              'branch': branch})
    reach = cfg.linkage.reach()
    lo, hi = -reach.theta_max, reach.theta_max
    theta = np.concatenate((np.linspace(lo - 0.1, hi + 0.1, 4001), [lo, hi, math.nan, math.inf, -math.inf]))
    scalar = []
    for t in theta.tolist():
        try:
            scalar.append(tuple(pose_solver(cfg)(t)))
        except FourBarError:
            scalar.append((math.nan,) * 3)
    want = np.array(scalar)
    got = np.column_stack(poses(cfg, theta))
    solved = np.isfinite(want).all(axis=1)
    solved_array = ~np.isnan(got).any(axis=1)
    edge = np.abs(np.abs(theta) - reach.theta_max) <= 4 * np.spacing(reach.theta_max)
    assert 1000 < np.count_nonzero(solved) < theta.size
    assert np.array_equal(solved[~edge], solved_array[~edge])
    both = solved & solved_array
    g_scale, d_scale, tau_scale = pose_scales(cfg, theta[both], want[both, 2])
    assert_close_ulps(got[both], want[both], CHAIN_ULPS, np.column_stack((g_scale, d_scale, tau_scale)), 'pose')


def test_no_mass_no_gravity() -> None:
    s = CFG.linkage.state(0.05)
    assert gravity_torque(CFG, 0.05, float(s.gamma), float(s.dgamma_dtheta)) == 0.0


def test_motor_torque_through_reducer() -> None:
    cfg = config_from_values({'reducer_efficiency': 0.8})
    assert motor_torque(cfg, 4.0) == pytest.approx(4.0 / (500.0 * 0.8), rel=1e-15)


# ----------------------------------------------------------------------------- state cache

def test_cache_counts_solves_and_repeats() -> None:
    calls: list[float] = []

    def fake(theta: float) -> LinkageState:
        calls.append(theta)
        return CFG.linkage.state(theta)

    cache = StateCache(fake)
    a = cache.get(0.01)
    assert cache.get(0.01) is a
    cache.get(0.02)
    cache.get(0.01)
    assert calls == [0.01, 0.02, 0.01] and (cache.computed, cache.reused) == (3, 1)
    cache.reset()
    cache.get(0.01)
    assert (cache.computed, cache.reused) == (4, 1)


# ----------------------------------------------------------------------------- velocities

def test_velocity_step_cases() -> None:
    prev = Sample(1_000_000_000, (0.5, 0.7))
    cur = Sample(1_010_000_000, (0.51, 0.68))
    v, anchor = velocity_step(prev, cur, timeout=0.5)
    # The same two float operations (subtract, divide) as the rule itself: equality is legitimate.
    assert v == [(0.51 - 0.5) / 0.01, (0.68 - 0.7) / 0.01] and anchor == cur
    assert velocity_step(None, cur, 0.5) == ([], cur)
    same = Sample(prev.stamp_ns, (0.6, 0.6))
    assert velocity_step(prev, same, 0.5) == ([], prev)              # same stamp: no velocity, anchor kept
    assert velocity_step(cur, prev, 0.5) == ([], prev)               # clock went back: restart from it
    stale = Sample(prev.stamp_ns + 600_000_000, (0.6, 0.6))
    assert velocity_step(prev, stale, 0.5) == ([], stale)            # older than the timeout: restart


def test_velocity_is_unbiased_when_commands_outpace_the_clock() -> None:
    """Commands at 100 Hz on a clock ticking at 40 Hz (sim time): many share a stamp. A constant-rate
    ramp must come out at its true rate on average, and no velocity over a zero interval."""
    rate = 0.3  # rad/s
    anchor: Sample | None = None
    velocities: list[float] = []
    for k in range(4000):
        t_true = k * 0.01                                   # s, command k
        stamp_ns = int(t_true // 0.025) * 25_000_000         # the clock's last tick
        v, anchor = velocity_step(anchor, Sample(stamp_ns, (rate * t_true,)), timeout=0.5)
        velocities += v
    assert len(velocities) == 4000 * 0.01 / 0.025 - 1        # one per tick after the first
    mean = sum(velocities) / len(velocities)
    # Each velocity spans first-command-of-tick to first-command-of-next-tick; their sum telescopes, so the
    # mean differs from the truth only by one command interval over the whole run (0.01 s / 40 s).
    assert abs(mean / rate - 1.0) < 1e-3
    assert all(0.5 * rate < v < 1.5 * rate for v in velocities)  # each within one command interval per tick


# ----------------------------------------------------------------------------- markers

@pytest.mark.parametrize('theta', [LO, 0.0, 0.05, HI])
def test_marker_points_match_transform_matrices(theta: float) -> None:
    s = CFG.linkage.state(theta)
    pts = linkage_points(0.18, 0.06, 0.102, 0.06, theta, float(s.gamma), float(s.delta))
    ref = antenna_joint_positions(0.18, 0.06, 0.102, 0.06, theta, s.gamma, s.delta)
    for got, want in ((pts.a, ref.a), (pts.b, ref.b), (pts.c, ref.c), (pts.d, ref.d)):
        assert got == pytest.approx(tuple(want), abs=1e-12)
    assert math.dist(pts.b, pts.c) == pytest.approx(0.102, abs=1e-12)
    dx, dy = pts.antenna_tip[0] - pts.antenna_tail[0], pts.antenna_tip[1] - pts.antenna_tail[1]
    assert math.atan2(-dy, dx) == pytest.approx(theta, abs=1e-12)  # theta > 0 points down


# ----------------------------------------------------------------------------- diagnostics

def _values(summary_values: list[tuple[str, str]]) -> dict[str, str]:
    return dict(summary_values)


def test_diagnostics_waiting_then_ok() -> None:
    counters = Counters()
    s = summarize(CFG, None, None, None, counters, 0, 0)
    assert s.level is Level.OK and 'waiting' in s.message
    d = decide(0.01, LO, HI, Policy.REJECT, REACH)
    counters.record(d.outcome)
    state = CFG.linkage.state(0.01, 3.5)
    s = summarize(CFG, d, 0.01, state, counters, 1, 0)
    v = _values(s.values)
    assert s.level is Level.OK
    assert float(v['gamma_rad']) == state.gamma and float(v['input_torque_nm']) == state.input_torque
    assert float(v['motor_torque_nm']) == state.input_torque / 500.0
    assert float(v['theta_max_margin_rad']) == HI - 0.01 and float(v['theta_min_margin_rad']) == 0.01 - LO
    assert float(v['reach_margin_rad']) == REACH.theta_max - 0.01
    assert float(v['motor_torque_margin_nm']) == 0.009 - state.input_torque / 500.0
    assert v['commands_received'] == '1' and v['commands_accepted'] == '1' and v['states_computed'] == '1'


def test_diagnostics_warn_on_rejected_and_clamped() -> None:
    counters = Counters()
    for cmd, policy in ((math.nan, Policy.REJECT), (0.5, Policy.CLAMP)):
        d = decide(cmd, LO, HI, policy, REACH)
        counters.record(d.outcome)
        s = summarize(CFG, d, cmd, CFG.linkage.state(HI, 3.5), counters, 1, 0)
        assert s.level is Level.WARN and s.message == d.reason
    v = _values(s.values)
    assert v['commands_rejected_not_finite'] == '1' and v['commands_clamped'] == '1'


def test_diagnostics_error_when_the_drive_cannot_hold() -> None:
    cfg = config_from_values({'motor_torque_limit': 0.005})  # 3.82 N m / 500 = 0.0076 N m at +7 deg
    d = decide(HI, LO, HI, Policy.REJECT, REACH)
    s = summarize(cfg, d, HI, cfg.linkage.state(HI, 3.5), Counters(), 1, 0)
    assert s.level is Level.ERROR and 'cannot hold' in s.message
    assert float(_values(s.values)['motor_torque_margin_nm']) < 0


def test_diagnostics_warn_on_poor_transmission() -> None:
    state = CFG.linkage.state(HI, 3.5)  # 147.6 deg transmission angle
    d = decide(HI, LO, HI, Policy.REJECT, REACH)
    assert summarize(CFG, d, HI, state, Counters(), 1, 0).level is Level.OK  # 30 deg band by default
    strict = config_from_values({'transmission_angle_min': math.radians(40.0)})
    s = summarize(strict, d, HI, state, Counters(), 1, 0)
    assert s.level is Level.WARN and 'transmission' in s.message


def test_sequence_gaps_count_skipped_numbers_and_a_late_first_number() -> None:
    gaps = SequenceGaps()
    # A publisher numbers from 1: its first message numbered 4 means 1 to 3 never came.
    assert [gaps.observe(n) for n in (4, 5, 7, 8)] == [3, 0, 1, 0]
    # A second publisher interleaved (a new track, below every track's last number): counted from its start.
    assert [gaps.observe(n) for n in (1, 9, 2)] == [0, 0, 0]
    assert gaps.observe(1) == 0  # a restarted publisher starts again at 1
