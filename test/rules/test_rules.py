"""fourbar_ros.rules: the node's rules on one command and on a block.

The node's per-command path (``decide`` only for commands outside the limits, ``loads.pose_solver`` on Python
floats, ``JointStateRule.sample``) and the array path ``fourbar process`` takes (``serve``, ``outputs_block``,
numpy) must publish the same: the same commands answered, the same stamps and velocity presence, and values
within the bounds test/support/ulp_bounds.py states for two float paths (numpy's SIMD transcendentals against libm).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from support.paths import REPO
from support.ulp_bounds import CHAIN_ULPS, assert_close_ulps, pose_scales

from fourbar_ros.config.antenna_config import AntennaConfig, config_from_values, load_config
from fourbar_ros.core.loads import pose_solver
from fourbar_ros.rules.outputs import JOINTS, JointStateRule, driven_index, outputs_block
from fourbar_ros.rules.policy import Outcome, Policy, decide, serve
from fourbar_ros.rules.velocity import Sample, VelocityState, velocity_step

YAML = REPO / 'config' / 'antenna.yaml'
T0 = 1_700_000_000 * 1_000_000_000
#: Command spacing (ns) and the coarse clock tick (ns) of the sim-time part: several commands share a stamp.
STEP_NS, TICK_NS = 10_000_000, 25_000_000


def config(**changes: object) -> AntennaConfig:
    return config_from_values({**load_config(YAML).as_values(), **changes})


CONFIGS = {
    'reject': config(),
    'clamp': config(out_of_limits='clamp'),
    'clamp_delta_gravity': config(out_of_limits='clamp', driven_rocker='delta', antenna_mass=1.2,
                                  com_offset_along=0.01, com_offset_normal=0.02),
}


def bad_commands(cfg: AntennaConfig) -> list[float]:
    """Every kind of command the policy treats apart: exact limits, one ulp outside, out of limits, out of reach,
    huge, not finite."""
    lo, hi = cfg.theta_min, cfg.theta_max
    return [lo, hi, math.nextafter(hi, math.inf), math.nextafter(lo, -math.inf), hi + 1e-3, lo - 0.5, 1e308,
            -1e308, 2 * math.pi + 0.05, math.nan, math.inf, -math.inf]


def commands_and_stamps(cfg: AntennaConfig, n: int = 2000) -> tuple[np.ndarray, np.ndarray]:
    """``n`` commands (rad): a random walk inside the limits with the bad commands mixed in; stamps (ns): wall
    clock (every stamp differs), then a coarse sim clock (runs of equal stamps), a stamp going back, a pause
    beyond the velocity timeout."""
    rng = np.random.default_rng(17)
    lo, hi = cfg.theta_min, cfg.theta_max
    walk = np.clip(0.5 * (lo + hi) + np.cumsum(rng.normal(scale=0.01, size=n)), lo, hi)
    bad = bad_commands(cfg)
    at = rng.choice(n, size=4 * len(bad), replace=False)
    walk[at] = np.resize(np.array(bad), at.size)
    stamps = T0 + np.arange(n, dtype=np.int64) * STEP_NS + rng.integers(0, 1000, size=n)
    sim = slice(n // 2, n)
    stamps[sim] = T0 + (np.arange(n - n // 2, dtype=np.int64) * STEP_NS) // TICK_NS * TICK_NS
    stamps[3 * n // 4:] -= 10 * TICK_NS  # the sim clock restarted
    stamps[7 * n // 8:] += round(2e9 * cfg.velocity_timeout)  # a pause beyond the timeout
    return walk, stamps


#: One answered command of the node: (index, stamp ns, positions rad, velocities rad/s, efforts N m, torque N m).
Answer = tuple[int, int, list[float], list[float], list[float], float]


def node_path(cfg: AntennaConfig, commands: np.ndarray, stamps: np.ndarray) -> tuple[list[Outcome], list[Answer]]:
    """What the node publishes, one command at a time: outcomes, and (index, stamp, positions, velocities,
    efforts, torque) per answered command."""
    rule, solve = JointStateRule(cfg), pose_solver(cfg)
    policy, reach = Policy(cfg.out_of_limits), cfg.linkage.reach()
    outcomes: list[Outcome] = []
    answers: list[Answer] = []
    for i, (command, stamp) in enumerate(zip(commands.tolist(), stamps.tolist(), strict=True)):
        decision = decide(command, cfg.theta_min, cfg.theta_max, policy, reach)
        outcomes.append(decision.outcome)
        if decision.theta is None:
            continue
        pose = solve(decision.theta)
        positions, velocity, effort = rule.sample(decision.theta, pose, stamp)
        answers.append((i, stamp, positions, velocity, effort, pose.input_torque))
    return outcomes, answers


@pytest.mark.parametrize('name', list(CONFIGS))
def test_serve_decides_every_command_as_decide(name: str) -> None:
    """The array policy answers the same commands with the very same angles and outcome counts (bit for bit:
    comparisons and copies only)."""
    cfg = CONFIGS[name]
    commands, _ = commands_and_stamps(cfg)
    outcomes, answers = node_path(cfg, commands, _)
    served = serve(commands, cfg.theta_min, cfg.theta_max, Policy(cfg.out_of_limits), cfg.linkage.reach())
    assert served.index.tolist() == [a[0] for a in answers]
    want = [decide(float(commands[i]), cfg.theta_min, cfg.theta_max, Policy(cfg.out_of_limits),
                   cfg.linkage.reach()).theta for i in served.index.tolist()]
    assert served.theta.tolist() == want
    assert served.outcomes == {o: outcomes.count(o) for o in set(outcomes)}
    rejected = sum(n for o, n in served.outcomes.items() if o.rejected)
    if cfg.out_of_limits == 'clamp':
        assert served.outcomes[Outcome.CLAMPED] > 0 and rejected == served.outcomes[Outcome.REJECTED_NOT_FINITE]
    else:
        assert served.outcomes[Outcome.CLAMPED] == 0 and served.outcomes[Outcome.REJECTED_OUT_OF_REACH] > 0


@pytest.mark.parametrize('name', list(CONFIGS))
@pytest.mark.parametrize('block', [1, 7, 4096])
def test_scalar_and_array_paths_publish_the_same(name: str, block: int) -> None:
    """Per command (node) and per block (fourbar process), split anywhere: same answers, stamps and velocity
    presence (the same integer rule); values within the ulp bounds stated at each assertion."""
    cfg = CONFIGS[name]
    commands, stamps = commands_and_stamps(cfg)
    _, answers = node_path(cfg, commands, stamps)
    served = serve(commands, cfg.theta_min, cfg.theta_max, Policy(cfg.out_of_limits), cfg.linkage.reach())
    anchor = VelocityState()
    parts = [outputs_block(cfg, served.theta[k:k + block], stamps[served.index[k:k + block]], anchor)
             for k in range(0, served.theta.size, block)]
    assert sum(p.not_solved for p in parts) == 0
    got_stamps = np.concatenate([p.stamps_ns for p in parts])
    positions = np.concatenate([p.positions for p in parts])
    vel = np.concatenate([p.velocities for p in parts])
    have = np.concatenate([p.has_velocity for p in parts])
    efforts = np.concatenate([p.efforts for p in parts])
    torque = np.concatenate([p.input_torque for p in parts])

    assert got_stamps.tolist() == [a[1] for a in answers]
    assert have.tolist() == [bool(a[3]) for a in answers]
    assert 0 < np.count_nonzero(have) < have.size  # the rule's no-velocity cases all occur
    want_q = np.array([a[2] for a in answers])
    want_tau = np.array([a[5] for a in answers])
    theta = served.theta
    # Positions: each path's pose chain (about four transcendentals) is within CHAIN_ULPS of the angle's
    # condition-weighted scale; the coupler joint adds theta to gamma (one more rounding of its own size).
    g_scale, d_scale, tau_scale = pose_scales(cfg, theta, want_tau)
    q_scale = np.column_stack((g_scale, d_scale, g_scale + np.abs(theta) + np.abs(want_q[:, 2])))
    assert_close_ulps(positions, want_q, CHAIN_ULPS, q_scale, 'positions')
    # Velocities: (q - q_anchor) / dt with the same integer dt on both paths, so the position bounds of the
    # sample and its anchor over dt, plus the division's own rounding of |v|.
    rows = np.flatnonzero(have)
    anchor_row = np.array([_anchor_index(got_stamps, r) for r in rows.tolist()], dtype=np.intp)
    want_v = np.array([answers[r][3] for r in rows.tolist()])
    dt = ((got_stamps[rows] - got_stamps[anchor_row]) * 1e-9)[:, None]
    v_scale = (q_scale[rows] + q_scale[anchor_row]) / dt + np.abs(want_v)
    assert_close_ulps(vel[rows], want_v, CHAIN_ULPS, v_scale, 'velocities')
    # Torque and efforts: within the torque's condition-weighted scale (ulp_bounds.pose_scales).
    assert_close_ulps(torque, want_tau, CHAIN_ULPS, tau_scale, 'input_torque')
    d = driven_index(cfg)
    assert np.array_equal(efforts[:, d], torque)  # the effort layout: the torque in its column, 0.0 elsewhere
    assert not efforts[:, [j for j in range(JOINTS) if j != d]].any()
    assert [a[4][d] for a in answers] == want_tau.tolist()
    assert all(a[4][j] == 0.0 for a in answers for j in range(JOINTS) if j != d)


def _anchor_index(stamps: np.ndarray, row: int) -> int:
    """The row the velocity rule measures ``row`` from: the first of the run of equal stamps just before it."""
    k = row - 1
    while k > 0 and stamps[k - 1] == stamps[k]:
        k -= 1
    return k


def test_velocity_spans_clock_ticks_from_their_first_sample() -> None:
    """Sim time, 100 Hz commands on a 40 Hz clock, a constant-rate motion: the anchor is the first sample of a
    tick, so a velocity spans 30 or 20 ms of motion per 25 ms tick, alternately, and their mean is the true rate
    (measured from the last sample of a tick it would be 0.4x the rate)."""
    rate = 0.2  # rad/s
    t_ns = np.arange(400, dtype=np.int64) * STEP_NS
    stamps = (t_ns // TICK_NS * TICK_NS).tolist()
    anchor: Sample | None = None
    got = []
    for t, stamp in zip(t_ns.tolist(), stamps, strict=True):
        v, anchor = velocity_step(anchor, Sample(stamp, (rate * t * 1e-9,)), 1.0)
        got.extend(v)
    assert len(got) == len(set(stamps)) - 1  # one velocity per new tick
    # Each velocity: two positions (|q| <= 0.8 rad, a few ulps each) over 25 ms; a pair's mean spans 50 ms.
    pairs = np.array(got[:len(got) // 2 * 2]).reshape(-1, 2)
    assert_close_ulps(pairs, np.array([[1.2 * rate, 0.8 * rate]] * len(pairs)), CHAIN_ULPS, 1.0 + 0.8 / 0.025,
                      'velocity')
    assert_close_ulps(pairs.mean(axis=1), np.full(len(pairs), rate), CHAIN_ULPS, 1.0 + 0.8 / 0.025, 'mean velocity')


def test_held_pose_has_zero_velocity_and_is_not_a_sample() -> None:
    """A republished pose: the positions and efforts of the last sample, velocities 0.0; the next sample's
    velocity is measured from the last real sample, as if nothing had been republished."""
    cfg = CONFIGS['reject']
    solve = pose_solver(cfg)
    rule, reference = JointStateRule(cfg), JointStateRule(cfg)
    first = rule.sample(0.01, solve(0.01), T0)
    reference.sample(0.01, solve(0.01), T0)
    positions, velocity, effort = rule.held(0.01, solve(0.01))
    assert velocity == [0.0] * JOINTS and (positions, effort) == (first[0], first[2])
    after = rule.sample(0.02, solve(0.02), T0 + STEP_NS)
    assert after == reference.sample(0.02, solve(0.02), T0 + STEP_NS) and len(after[1]) == JOINTS


@pytest.mark.parametrize('driven, column', [('gamma', 0), ('delta', 1)])
def test_driven_index_names_the_effort_column(driven: str, column: int) -> None:
    cfg = config(driven_rocker=driven)
    assert driven_index(cfg) == column
    effort = JointStateRule(cfg).effort(pose_solver(cfg)(0.01))
    assert [j for j, e in enumerate(effort) if e != 0.0] == [column]
