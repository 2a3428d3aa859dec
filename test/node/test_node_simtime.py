"""fourbar_node on sim time (``-p use_sim_time:=true``), as with ``ros2 bag play --clock``.

A test node publishes rosgraph_msgs/Clock at 40 Hz of sim time (rosbag2's default ``--clock`` rate) and a
constant-rate ramp of commands at 100 Hz of sim time into the node process: commands then share stamps. The mean
velocity must be the true rate (a velocity anchor replaced on every command would divide one 10 ms step by a 25 ms
tick: 0.40x the rate). Without any /clock the node warns once.

Sim time runs at a quarter of the wall rate (``SLOW``), as in the bag test (test/live/test_bag_sim_time.py, which
explains why): scheduling delays in wall time bias the mean velocity by about (delay / clock period)^2, and slowing
both streams 4x divides that by 16 while the node sees the same sequence of shared stamps.
"""

from __future__ import annotations

import signal
import statistics
import time
from typing import Any

import pytest
from builtin_interfaces.msg import Time
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64
from support.paths import REPO
from support.ros_support import (
    ONE_JOINT_STATE_PER_COMMAND,
    Collector,
    NodeProcess,
    RosSession,
    Ticker,
    sync_probe,
    wait_for,
)

from fourbar_ros.config.antenna_config import load_config

pytestmark = [pytest.mark.ros, pytest.mark.slow]

YAML = REPO / 'config' / 'antenna.yaml'
CFG = load_config(YAML)
LO, HI = CFG.theta_min, CFG.theta_max
SLOW = 4.0  # wall seconds per sim second
CLOCK_HZ = 40.0  # of sim time
COMMAND_HZ = 100.0  # of sim time
RAMP_RATE = 0.04  # rad/s of theta, in sim seconds
RAMP_COMMANDS = 120  # 1.2 s of sim time (4.8 s of wall time) at 100 Hz: theta moves 0.048 rad, inside the range
SIM_T0_S = 1000  # sim time at the start: far from 0, so the first stamped answer has no velocity


def state(theta: float) -> Any:
    return CFG.linkage.state(theta, CFG.load_torque, CFG.driven, CFG.branch)


def test_sim_time_velocity_is_unbiased_with_a_40_hz_clock() -> None:
    with RosSession() as ros:
        mono0 = time.monotonic()
        clock_pub = ros.publisher(Clock, '/clock', 10)

        def publish_clock(now: float) -> None:
            ns = SIM_T0_S * 1_000_000_000 + int((now - mono0) / SLOW * 1e9)
            clock_pub.publish(Clock(clock=Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)))

        proc = NodeProcess(['--ros-args', '--params-file', str(YAML), '-r', '__ns:=/sim',
                            '-p', 'use_sim_time:=true', *ONE_JOINT_STATE_PER_COMMAND], ros.env())
        proc.start()
        try:
            with Ticker(CLOCK_HZ / SLOW, publish_clock):
                pub = ros.publisher(Float64, '/sim/antenna_angle_cmd')
                js: Collector[Any] = ros.collect(JointState, '/sim/joint_states')
                ros.wait_subscribers(pub)
                ros.wait_publishers(js)
                ros.wait_subscribers(clock_pub)
                probes = [LO + (HI - LO) * (i + 0.5) / 600 for i in range(600)]
                # /clock is best effort: answers count only once stamped on the test's clock (the node's clock
                # subscription matched), so the ramp starts with the node on sim time.
                sync_probe(lambda t: pub.publish(Float64(data=t)), [js], probes,
                           lambda col, msg, p: bool(msg.position[0] == state(p).gamma),
                           ready=lambda msg: msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
                           > SIM_T0_S * 1_000_000_000)
                thetas: list[float] = []
                theta0 = LO + 0.02
                ramp_t0 = time.monotonic()

                def publish_command(now: float) -> None:
                    if len(thetas) < RAMP_COMMANDS:
                        # theta follows the clock's time base, so the truth does not depend on pacing jitter
                        thetas.append(theta0 + RAMP_RATE * (now - ramp_t0) / SLOW)
                        pub.publish(Float64(data=thetas[-1]))

                with Ticker(COMMAND_HZ / SLOW, publish_command):
                    msgs = js.wait_count(RAMP_COMMANDS)
            assert_clean_stop(proc)
        finally:
            proc.kill()
    assert len(msgs) == RAMP_COMMANDS == len(thetas)
    stamps = [m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec for m in msgs]
    assert all(s > SIM_T0_S * 1_000_000_000 for s in stamps)  # the node really ran on the sim clock
    distinct = sorted(set(stamps))
    assert len(distinct) < 0.6 * RAMP_COMMANDS  # commands did share stamps (40 Hz clock, 100 Hz commands)
    # The first two ticks' velocities may start from a probe answer (before the ramp): skip them.
    ratios = []
    for i, (msg, stamp, theta) in enumerate(zip(msgs, stamps, thetas, strict=True)):
        if stamp <= distinct[1]:
            continue
        if stamps.index(stamp) != i:
            assert list(msg.velocity) == []  # the stamp did not advance: no velocity over a zero interval
            continue
        assert len(msg.velocity) == 3  # rockers AB, CD and the coupler joint
        # True gamma rate: dgamma/dtheta at this command times the ramp rate. Over one tick theta moves
        # 1e-3 rad, which changes dgamma/dtheta by ~0.1 %, far below the tolerance below.
        ratios.append(msg.velocity[0] / (state(theta).dgamma_dtheta * RAMP_RATE))
    assert len(ratios) > 0.5 * len(distinct)
    mean = statistics.fmean(ratios)
    print(f'sim-time velocity ratio: mean {mean:.4f} over {len(ratios)} velocities')
    # Each velocity spans first command of a tick to first command of the next; the spans telescope, so the
    # mean is off the truth by about one command interval over the run (10 ms / 1.2 s of sim time) plus the
    # delivery jitter's bias (the docstring).
    assert mean == pytest.approx(1.0, abs=0.05)


def assert_clean_stop(proc: NodeProcess) -> None:
    status = proc.stop(signal.SIGTERM)
    assert status == 0 and 'Traceback' not in proc.stderr, proc.stderr


def test_sim_time_without_clock_warns_once() -> None:
    with RosSession() as ros:  # its own domain id: no /clock from any other test
        proc = NodeProcess(['--ros-args', '--params-file', str(YAML), '-p', 'use_sim_time:=true'], ros.env())
        proc.start()
        try:
            wait_for(lambda: 'no /clock message arrived' in proc.stderr_now() or not proc.running(),
                     what='the no-/clock warning')
            assert_clean_stop(proc)
        finally:
            proc.kill()
    lines = [line for line in proc.stderr.splitlines() if 'no /clock message arrived' in line]
    assert len(lines) == 1 and lines[0].startswith('[WARN]'), proc.stderr
    assert 'use_sim_time is true' in lines[0]
