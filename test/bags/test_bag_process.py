"""`fourbar process`: the node's rules applied to a command bag without the middleware.

The oracle is the node's per-command logic written out in Python on the scalar path: rules.policy.decide,
loads.pose_solver (math module) and rules.velocity.velocity_step, one command at a time, stamped with the
command's log time. fourbar process must give the same messages: same count, stamps, names, velocity presence,
and values within bounds that follow from the two float paths (stated at each assertion).
"""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from support.bag_support import BAG_DIR, CONFIG, Tool, committed_bags, run_main
from support.ros_support import wait_for

from fourbar_ros.bags.process import process_bag
from fourbar_ros.bags.storage import (
    FLOAT64,
    AtomicBagWriter,
    BagError,
    read_commands,
    read_messages,
    recorded_qos,
    write_command_bag,
)
from fourbar_ros.config.antenna_config import AntennaConfig, config_from_values, default_config, load_config
from fourbar_ros.core.antenna import Driven
from fourbar_ros.core.loads import pose_solver
from fourbar_ros.interface.topics import Storage
from fourbar_ros.rules.policy import Policy, decide
from fourbar_ros.rules.velocity import Sample, VelocityState, velocities, velocity_step

T0 = 1_700_000_000 * 1_000_000_000
ULPS = 8  # positions: ulps of |q| + pi; torque: ulps of |tau| (1 + pi (|cot s| + |cot r|)) (see below)


def oracle(stamps: list[int], values: list[float], cfg: AntennaConfig) -> list[tuple[int, tuple[float, ...],
                                                                                    list[float], float]]:
    """(stamp, positions, velocity, torque) the node publishes per command, one command at a time."""
    policy, reach, solve = Policy(cfg.out_of_limits), cfg.linkage.reach(), pose_solver(cfg)
    anchor: Sample | None = None
    out = []
    for stamp, command in zip(stamps, values, strict=True):
        theta = decide(command, cfg.theta_min, cfg.theta_max, policy, reach).theta
        if theta is None:
            continue
        gamma, delta, torque = solve(theta)
        positions = (gamma, delta, gamma + theta)  # the coupler joint: gamma + theta
        velocity, anchor = velocity_step(anchor, Sample(stamp, positions), cfg.velocity_timeout)
        out.append((stamp, positions, velocity, torque))
    return out


def torque_condition(cfg: AntennaConfig, theta: float) -> float:
    """1 + pi (|cot s| + |cot r|): the torque's sensitivity to ulp-sized angle errors (s = gamma + delta,
    r = the driven rocker's angle to the coupler), from the scalar state."""
    st = cfg.linkage.state(theta, cfg.load_torque, cfg.driven, cfg.branch)
    s = st.gamma + st.delta
    r = st.delta - theta if cfg.driven is Driven.GAMMA else st.gamma + theta
    return 1.0 + math.pi * (abs(math.cos(s) / math.sin(s)) + abs(math.cos(r) / math.sin(r)))


def check_against_oracle(out: Path, stamps: list[int], values: list[float], cfg: AntennaConfig) -> int:
    """The processed bag equals the oracle; returns the number of answers."""
    expected = oracle(stamps, values, cfg)
    got = read_messages(out)
    joints, torques = got['/joint_states'], got['/input_torque']
    assert len(joints) == len(torques) == len(expected)
    d = 0 if cfg.driven is Driven.GAMMA else 1
    thetas = [decide(v, cfg.theta_min, cfg.theta_max, Policy(cfg.out_of_limits), cfg.linkage.reach()).theta
              for v in values]
    served = [t for t in thetas if t is not None]
    for i, ((log_j, js), (log_t, tq), (stamp, q, vel, tau)) in enumerate(zip(joints, torques, expected,
                                                                               strict=True)):
        assert log_j == log_t == stamp, i
        assert js.header.stamp.sec * 1_000_000_000 + js.header.stamp.nanosec == stamp, i
        assert js.header.frame_id == '' and list(js.name) == list(cfg.joint_names), i
        # Positions: numpy's and libm's sin/cos/atan2 may differ by 1-2 ulps; gamma and delta are sums of
        # atan2 results in [-pi, pi], so the two paths agree to a few ulps of |q| + pi.
        for j in range(3):  # the coupler's gamma + theta: gamma's bound, the addition of theta exact or 1 ulp
            assert abs(js.position[j] - q[j]) <= ULPS * math.ulp(abs(q[j]) + math.pi), (i, j)
        # Velocity: same presence (the same rule on the same stamps); value: two position differences of
        # the bound above over dt, i.e. <= 2 ULPS ulps of (|q| + pi) / dt, taken as ulps of (|q| + pi) * 2 / dt.
        assert (len(js.velocity) == 0) == (len(vel) == 0), i
        if vel:
            dt = next(stamp - s for s, *_ in reversed(expected[:i]) if s != stamp) * 1e-9 \
                if i and any(s != stamp for s, *_ in expected[:i]) else math.inf
            for j in range(3):
                bound = 2 * ULPS * math.ulp((abs(q[j]) + math.pi) * 2.0 / dt) + ULPS * math.ulp(abs(vel[j]))
                assert abs(js.velocity[j] - vel[j]) <= bound, (i, j)
        # Torque: an angle error e moves tau by |tau| |cot| e (the sines' ratio) plus a few ulps of |tau| from
        # the product's association.
        bound = ULPS * math.ulp(abs(tau) * torque_condition(cfg, served[i]))
        assert abs(js.effort[d] - tau) <= bound and [js.effort[1 - d], js.effort[2]] == [0.0, 0.0], i
        assert abs(tq.data - tau) <= bound and tq.data == js.effort[d], i
    return len(expected)


@pytest.mark.parametrize('bag', committed_bags(), ids=[b.name for b in committed_bags()])
def test_every_committed_bag_matches_the_node_rules(bag: Path, tmp_path: Path) -> None:
    cfg = load_config(CONFIG)
    stream = read_commands(bag)
    process_bag(bag, tmp_path / 'out', cfg)
    assert check_against_oracle(tmp_path / 'out', list(stream.stamps_ns), list(stream.values), cfg) > 0


@pytest.mark.parametrize('policy', ['reject', 'clamp'])
def test_bad_commands_follow_the_policy(policy: str, tmp_path: Path) -> None:
    """NaN, inf, out of limits, out of reach and huge commands, under both policies, through small blocks."""
    cfg = config_from_values({**load_config(CONFIG).as_values(), 'out_of_limits': policy})
    values = [0.0, math.nan, 0.05, math.inf, -math.inf, cfg.theta_max, cfg.theta_max + 1e-3, cfg.theta_min,
              cfg.theta_min - 0.5, 1e308, 2 * math.pi + 0.05, -0.01, math.nextafter(cfg.theta_max, math.inf), 0.02]
    stamps = [T0 + k * 10_000_000 for k in range(len(values))]
    write_command_bag(tmp_path / 'in', stamps, values)
    for block in (3, 4096):
        out = tmp_path / f'out{block}'
        stats = process_bag(tmp_path / 'in', out, cfg, block=block)
        n = check_against_oracle(out, stamps, values, cfg)
        assert stats.published == n
        assert stats.rejected['rejected_not_finite'] == 3
        outside = 5  # theta_max + 1e-3, theta_min - 0.5, 1e308, 2 pi + 0.05, one ulp above theta_max
        if policy == 'clamp':
            assert stats.clamped == outside and n == len(values) - 3
        else:
            assert stats.clamped == 0 and n == len(values) - 3 - outside


def test_gravity_load_matches_the_scalar_path(tmp_path: Path) -> None:
    cfg = config_from_values({**load_config(CONFIG).as_values(), 'antenna_mass': 1.2, 'com_offset_along': 0.01,
                              'com_offset_normal': 0.02, 'driven_rocker': 'delta'})
    values = list(np.linspace(cfg.theta_min, cfg.theta_max, 301))
    stamps = [T0 + k * 10_000_000 for k in range(len(values))]
    write_command_bag(tmp_path / 'in', stamps, values)
    process_bag(tmp_path / 'in', tmp_path / 'out', cfg, block=64)
    expected = oracle(stamps, values, cfg)
    got = read_messages(tmp_path / 'out')['/input_torque']
    for (_, tq), (_, _, _, tau), theta in zip(got, expected, values, strict=True):
        # The load itself is computed with np.cos/np.sin here and math.cos/math.sin in the node: a few ulps of
        # each term; the terms are of the size of the total torque's scale at most.
        st = cfg.linkage.state(theta, 0.0, cfg.driven, cfg.branch)
        s, r = st.gamma + st.delta, st.gamma + theta
        cond = 1.0 + math.pi * (abs(math.cos(s) / math.sin(s)) + abs(math.cos(r) / math.sin(r)))
        assert abs(tq.data - tau) <= ULPS * math.ulp((abs(tau) + cfg.antenna_mass * cfg.gravity * 0.2) * cond)


def test_velocity_rule_equals_velocity_step_across_blocks() -> None:
    """Coarse stamps (sim time: several commands per clock tick), a stamp going back, a pause beyond the
    timeout; split into blocks anywhere: the same velocities and presence as velocity_step, bit for bit
    (the same integer difference, the same two float operations)."""
    rng = np.random.default_rng(3)
    ticks = np.repeat(np.arange(60), rng.integers(1, 4, size=60))
    stamps = T0 + ticks.astype(np.int64) * 25_000_000
    stamps[40:] -= 200_000_000  # goes back
    stamps[70:] += 2_000_000_000  # pause > timeout
    q = np.column_stack((np.cumsum(rng.normal(size=stamps.size)), rng.normal(size=stamps.size)))
    timeout = 0.5
    anchor: Sample | None = None
    want_v, want_have = [], []
    for t, row in zip(stamps.tolist(), q.tolist(), strict=True):
        v, anchor = velocity_step(anchor, Sample(t, tuple(row)), timeout)
        want_have.append(bool(v))
        want_v.append(v if v else [0.0, 0.0])
    assert 0 < sum(want_have) < len(want_have)
    for cuts in ([], [1], [5, 6, 7], [39, 40, 41], list(range(0, stamps.size, 9))):
        state = VelocityState()
        got_v, got_have = [], []
        for part in np.split(np.arange(stamps.size), cuts):
            if part.size == 0:
                continue
            v, have = velocities(stamps[part], q[part], timeout, state)
            got_v.append(np.where(have[:, None], v, 0.0))
            got_have.append(have)
        assert np.concatenate(got_have).tolist() == want_have, cuts
        assert np.array_equal(np.concatenate(got_v), np.array(want_v)), cuts


def test_no_rclpy_is_imported(tmp_path: Path) -> None:
    code = ('import sys; from fourbar_ros.commands import main; rc = main(sys.argv[1:]); '
            'assert not [m for m in sys.modules if m.split(".")[0] in ("rclpy", "rosidl_runtime_py")], '
            '"rclpy imported"; sys.exit(rc)')
    done = subprocess.run([sys.executable, '-c', code, 'process', str(BAG_DIR / 'sweep_mcap'),
                           str(tmp_path / 'out')], check=False, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert (tmp_path / 'out' / 'metadata.yaml').is_file()


def test_command_line_and_bad_input(tmp_path: Path) -> None:
    rc, lines, _ = run_main(['process', BAG_DIR / 'bad_values_sqlite3', tmp_path / 'out', '--params', CONFIG])
    assert rc == 0 and any('wrote' in line for line in lines), lines
    assert sorted(p.suffix for p in (tmp_path / 'out').iterdir()) == ['.db3', '.yaml']  # the input's storage
    # Existing output, missing input, a bag without the topic, a bad parameter file: one line, status 2.
    (tmp_path / 'params.yaml').write_text('/**:\n  ros__parameters:\n    theta_max: 2.0\n')
    write_command_bag(tmp_path / 'other_topic', [T0], [0.0], topic='/tilt_cmd')
    cases = [
        ['process', BAG_DIR / 'sweep_mcap', tmp_path / 'out'],
        ['process', tmp_path / 'missing', tmp_path / 'o1'],
        ['process', tmp_path / 'other_topic', tmp_path / 'o2'],
        ['process', BAG_DIR / 'sweep_mcap', tmp_path / 'o3', '--params', tmp_path / 'params.yaml'],
        ['process', BAG_DIR / 'sweep_mcap', tmp_path / 'o4', '--topic', '/nothing'],
    ]
    for args in cases:
        rc, lines, out = run_main(args)
        assert rc == 2 and len(lines) == 1 and lines[0].startswith('fourbar process: error: '), (args, lines)
        assert 'Traceback' not in out
    assert sorted(p.name for p in tmp_path.iterdir()) == ['other_topic', 'out', 'params.yaml']
    # A command topic recorded under another name: --topic; the outputs go next to it.
    rc, lines, _ = run_main(['process', tmp_path / 'other_topic', tmp_path / 'o5', '--topic', '/tilt_cmd'])
    assert rc == 0, lines
    assert set(read_messages(tmp_path / 'o5')) == {'/joint_states', '/input_torque'}


def test_undecodable_message_leaves_nothing(tmp_path: Path) -> None:
    good = read_commands(BAG_DIR / 'sweep_mcap').raw[0]
    with AtomicBagWriter(tmp_path / 'in') as bag:
        conn = bag.add_topic('/antenna_angle_cmd', FLOAT64, [recorded_qos()])
        for k, raw in enumerate([good, good, b'\x00\x01\x00\x00\x01']):
            bag.write(conn, T0 + k, raw)
    with pytest.raises(BagError, match='message 2 on /antenna_angle_cmd is not a valid'):
        process_bag(tmp_path / 'in', tmp_path / 'out', default_config())
    assert sorted(p.name for p in tmp_path.iterdir()) == ['in']


def test_big_endian_commands_are_decoded(tmp_path: Path) -> None:
    """A command serialized big-endian (legal CDR, not what rclpy writes) takes the full deserializer."""
    import struct
    values = [0.01, -0.02]
    with AtomicBagWriter(tmp_path / 'in') as bag:
        conn = bag.add_topic('/antenna_angle_cmd', FLOAT64, [recorded_qos()])
        bag.write(conn, T0, b'\x00\x00\x00\x00' + struct.pack('>d', values[0]))
        bag.write(conn, T0 + 10_000_000, b'\x00\x01\x00\x00' + struct.pack('<d', values[1]))
    cfg = load_config(CONFIG)
    process_bag(tmp_path / 'in', tmp_path / 'out', cfg)
    check_against_oracle(tmp_path / 'out', [T0, T0 + 10_000_000], values, cfg)




@pytest.mark.slow
@pytest.mark.parametrize('sig', [signal.SIGTERM, signal.SIGINT])
def test_stopped_run_leaves_nothing(sig: int, tmp_path: Path) -> None:
    """SIGTERM or Ctrl-C while writing: status 130 (interrupted, like `fourbar replay`), no traceback, neither the
    output nor its temporary directory left."""
    from benchmarks.process_bench import make_bag

    make_bag(tmp_path / 'in', 400_000, Storage.MCAP)  # long enough to be mid-write when the signal arrives
    out = tmp_path / 'outputs'
    with Tool(['process', tmp_path / 'in', out], dict(os.environ)) as tool:
        wait_for(lambda: any(p.name.endswith('.partial') for p in tmp_path.iterdir()), what='the partial bag')
        tool.signal(sig)
        rc = tool.wait()
    assert rc == 130 and not any('Traceback' in line for line in tool.lines), tool.lines
    assert sorted(p.name for p in tmp_path.iterdir()) == ['in']
