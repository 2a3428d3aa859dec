"""The demo's analysis (fourbar_ros.analysis.demo) on a synthetic closed-loop recording: message objects shaped as
rosbags decodes them, with known tracking errors, speeds, torques and completions."""

from __future__ import annotations

import itertools
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest
from support.bag_support import CONFIG

from fourbar_ros.analysis.demo import (
    PACE_FRACTION,
    DemoError,
    _planned,
    demo_topics,
    pace,
    plot,
    recording,
    rocker_branch,
    summarize,
    summary_lines,
)
from fourbar_ros.config.antenna_config import AntennaConfig, load_config
from fourbar_ros.core.completion import complete
from fourbar_ros.core.loads import pose
from fourbar_ros.rules.completion import completed_names
from fourbar_ros.rules.simulated_drive import effort_at

Msg = SimpleNamespace  # a decoded message's stand-in: fields as rosbags gives them
T0 = 1_700_000_000_000_000_000  # ns, the first command's receive time
MS = 1_000_000


@pytest.fixture(scope='module')
def cfg() -> AntennaConfig:
    return load_config(CONFIG)


def _header(ns: int) -> Msg:
    return Msg(stamp=Msg(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000))


def _duration(s: float) -> Msg:
    ns = round(s * 1e9)
    return Msg(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def _driven(cfg: AntennaConfig, theta: float) -> float:
    p = pose(cfg, theta)
    return float(p.gamma)  # the shipped configuration drives gamma


def _recording(cfg: AntennaConfig, lag: float = 0.0, bad_coupler: float = 0.0) -> dict[str, list[tuple[int, Any]]]:
    """Two commands (at 0 and 1 s), a measurement every 10 ms moving linearly from the first to the second command
    over 0.5..1.5 s, delayed by ``lag`` rad of antenna angle at the end; its completion (the core's) with the
    coupler off by ``bad_coupler`` rad; one trajectory replaced by a second before its last point."""
    topics = demo_topics(cfg.trajectory_controller)
    a, b = -0.05, 0.05
    commands = [(T0, Msg(data=a)), (T0 + 1000 * MS, Msg(data=b))]
    measured: list[tuple[int, Any]] = []
    joint_states: list[tuple[int, Any]] = []
    angles: list[tuple[int, Any]] = []
    branch = rocker_branch(cfg)
    other, coupler = completed_names(cfg)
    for k in range(201):  # 0 .. 2 s
        stamp = T0 + k * 10 * MS
        s = min(max((k * 0.01 - 0.5) / 1.0, 0.0), 1.0)
        theta = a + (b - a) * s - (lag if k == 200 else 0.0)
        q = _driven(cfg, theta)
        q_rate = 0.01 if 0.0 < s < 1.0 else 0.0
        measured.append((stamp + MS, Msg(header=_header(stamp), name=[cfg.driven_joint], position=[q],
                                         velocity=[q_rate], effort=[2.0 + s])))
        c = complete(cfg.linkage, q, cfg.driven, branch, q_rate=q_rate)
        joint_states.append((stamp + 2 * MS, Msg(
            header=_header(stamp), name=[cfg.driven_joint, other, coupler],
            position=[q, float(c.other), float(c.coupler_joint) + (bad_coupler if k == 100 else 0.0)],
            velocity=[q_rate, float(c.other_rate), float(c.coupler_joint_rate)], effort=[2.0 + s, 0.0, 0.0])))
        angles.append((stamp + 2 * MS, Msg(data=float(c.theta))))

    def point(t: float, q: float, v: float) -> Msg:
        return Msg(positions=[q], velocities=[v], accelerations=[0.0], effort=[2.5], time_from_start=_duration(t))
    first = Msg(header=_header(T0 + 10 * MS), joint_names=[cfg.driven_joint],
               points=[point(0.0, 0.70, 0.0), point(0.5, 0.71, 0.02), point(1.5, 0.72, 0.0)])
    second = Msg(header=_header(T0 + 1010 * MS), joint_names=[cfg.driven_joint],
                points=[point(0.0, 0.72, -0.03), point(0.5, 0.73, 0.0)])
    return {topics.command: commands, topics.measured: measured, topics.joint_states: joint_states,
            topics.antenna_angle: angles,
            topics.input_torque: [(T0 + 2 * MS, Msg(data=3.0)), (T0 + 1002 * MS, Msg(data=-4.0))],
            topics.trajectory: [(T0 + 10 * MS, first), (T0 + 1010 * MS, second)],
            topics.diagnostics: [(T0 + 500 * MS, Msg(status=[]))]}


def test_series_split_and_planned_motion(cfg: AntennaConfig) -> None:
    rec = recording(_recording(cfg), demo_topics(cfg.trajectory_controller), cfg)
    assert rec.command.value.tolist() == [-0.05, 0.05] and rec.command.t.tolist() == [0.0, 1.0]
    assert rec.measured.position.t.size == rec.completed.stamp_ns.size == rec.antenna.t.size == 201
    assert rec.measured.position.t[0] == 0.0  # measured series timed by their stamps, not by arrival (+1 ms)
    # The first trajectory is followed until the second starts (its 1.5 s point comes after that), then the second.
    assert rec.planned.t.tolist() == pytest.approx([0.01, 0.51, 1.01, 1.51], abs=1e-9)
    assert rec.planned.value.tolist() == [0.70, 0.71, 0.72, 0.73]
    assert rec.planned_velocity.tolist() == [0.0, 0.02, -0.03, 0.0]
    assert rec.trajectories == 2 and rec.diagnostics == 1 and rec.rejected == 0
    # antenna_angle (no stamp) is timed by the measurement whose completion it equals, not by its arrival (+2 ms).
    assert rec.antenna_matched == 201 and rec.antenna.t.tolist() == rec.measured.position.t.tolist()


def test_antenna_angle_no_measurement_gives_keeps_its_arrival(cfg: AntennaConfig) -> None:
    messages = _recording(cfg)
    topics = demo_topics(cfg.trajectory_controller)
    messages[topics.antenna_angle][50] = (T0 + 502 * MS, Msg(data=1e-3 + messages[topics.antenna_angle][50][1].data))
    rec = recording(messages, topics, cfg)
    assert rec.antenna_matched == 200 and rec.antenna.t.size == 201
    assert rec.antenna.t[50] == pytest.approx(0.502, abs=1e-9)
    messages[topics.antenna_angle][0] = (T0, Msg(data=0.5))  # before the first found: left out
    rec = recording(messages, topics, cfg)
    assert rec.antenna_matched == 199 and rec.antenna.t.size == 200


def test_antenna_angle_of_a_measurement_the_recording_missed_at_rest(cfg: AntennaConfig) -> None:
    # The recording matched the actuator's measured joint after the node's antenna_angle: the first measurement is
    # missing (and its complete joint_states), but its antenna_angle is there. The antenna sits still until 0.5 s,
    # so the next 50 measurements give the same value: that one is left out (received before any of them was
    # stamped), and every later message is found, the one where the value first changes too.
    messages = _recording(cfg)
    topics = demo_topics(cfg.trajectory_controller)
    messages[topics.measured] = messages[topics.measured][1:]
    messages[topics.joint_states] = messages[topics.joint_states][1:]
    rec = recording(messages, topics, cfg)
    assert rec.antenna_matched == rec.antenna.t.size == 200
    assert rec.antenna.t.tolist() == rec.measured.position.t.tolist()


def test_summary_figures(cfg: AntennaConfig) -> None:
    lag = 1e-3
    rec = recording(_recording(cfg, lag=lag), demo_topics(cfg.trajectory_controller), cfg)
    s = summarize(rec, cfg)
    assert s.final_error == pytest.approx(lag, rel=1e-9)
    # Worst: just after the second command (1.0 s), the measurement still half-way (s = 0.5): 0.05 rad behind.
    assert s.worst_error == pytest.approx(0.05, abs=1e-12) and s.worst_error_t == pytest.approx(1.0, abs=1e-9)
    assert s.speed_limit == cfg.motor_speed_limit / cfg.reducer_ratio
    assert s.peak_speed_measured == 0.01 and s.peak_speed_planned == 0.03
    assert s.speed_margin == pytest.approx(1.0 - 0.03 / s.speed_limit, rel=1e-12)
    # Torque: the largest |.| of input_torque (4), the feed-forward (2.5) and the effort (up to 3), at the motor.
    assert s.peak_motor_torque == pytest.approx(4.0 / (cfg.reducer_ratio * cfg.reducer_efficiency), rel=1e-15)
    assert s.torque_margin == pytest.approx(1.0 - s.peak_motor_torque / cfg.motor_torque_limit, rel=1e-12)
    # The completion was built with the identical scalar core calls: exactly 0.
    assert (s.completion_position, s.completion_velocity, s.completed_paired, s.completed_unpaired) == (0, 0, 201, 0)
    # Effort - input_torque (3 N m from 2 ms, -4 N m from 1.002 s): the first measurement (0 s) precedes any
    # input_torque. At rest at a command (speed 0, the antenna angle on it): 0.01..0.5 s, effort 2 against 3, and
    # 1.5..1.99 s, effort 3 against -4. The rest moves, or (2 s) stands 1e-3 rad off the command, beyond
    # trajectory_tolerance: its effort 3 against -4 is the largest.
    assert (s.effort_rest, s.effort_rest_count) == (7.0, 100)
    assert (s.effort_motion, s.effort_motion_count) == (7.0, 100)
    # Off the load model at the measured angle, over the same measurements in motion (0.51..1.49 s, and 2 s).
    measured = [m for _, m in _recording(cfg, lag=lag)[demo_topics(cfg.trajectory_controller).measured]]
    moving = measured[51:150] + measured[200:]
    assert s.effort_motion_model == max(abs(m.effort[0] - effort_at(cfg, m.position[0])) for m in moving)
    lines = summary_lines(rec, s, cfg, {'commands_received': '2'}, 'mujoco')
    assert [line.split()[0] for line in lines] == ['command', 'tracking', 'speed', 'torque', 'margin', 'effort',
                                                   'counts', 'check']
    assert lines[5] == ('effort   measured - input_torque at the driven rocker: max |d| at rest 7 N m over 100 '
                        f'measurements, in motion 7 N m over 100 ({s.effort_motion_model:.3g} N m off the load model '
                        "at the measured angle; drive mujoco: the MuJoCo plant's reducer torque)")


def test_completion_check_sees_a_wrong_coupler(cfg: AntennaConfig) -> None:
    rec = recording(_recording(cfg, bad_coupler=1e-6), demo_topics(cfg.trajectory_controller), cfg)
    assert summarize(rec, cfg).completion_position == pytest.approx(1e-6, rel=1e-6)  # 1e-6 + one rounding


def test_unpaired_completions_are_counted(cfg: AntennaConfig) -> None:
    topics = demo_topics(cfg.trajectory_controller)

    def without_measurements(first: int, last: int) -> dict[str, list[tuple[int, Any]]]:
        messages = _recording(cfg)
        messages[topics.measured] = [
            r for r in messages[topics.measured]
            if not T0 + first * 10 * MS <= r[1].header.stamp.sec * 10**9 + r[1].header.stamp.nanosec
            <= T0 + last * 10 * MS]
        return messages
    s = summarize(recording(without_measurements(50, 59), topics, cfg), cfg)
    assert (s.completed_paired, s.completed_unpaired) == (191, 10)
    # Completions of measurements before the first recorded one, or after the last: the recording started after
    # them, or ended before it took them; left out.
    s = summarize(recording(without_measurements(0, 9), topics, cfg), cfg)
    assert (s.completed_paired, s.completed_unpaired) == (191, 0)
    s = summarize(recording(without_measurements(191, 200), topics, cfg), cfg)
    assert (s.completed_paired, s.completed_unpaired) == (191, 0)
    s = summarize(recording(without_measurements(190, 199), topics, cfg), cfg)  # the last one (200) is recorded
    assert (s.completed_paired, s.completed_unpaired) == (191, 10)
    with pytest.raises(DemoError, match='no measured'):
        recording(without_measurements(0, 200), topics, cfg)


def test_no_command_is_an_error(cfg: AntennaConfig) -> None:
    with pytest.raises(DemoError, match='no command'):
        recording({}, demo_topics(cfg.trajectory_controller), cfg)


def test_pace_follows_the_largest_step(cfg: AntennaConfig) -> None:
    steps = [-0.05, -0.04, -0.02, -0.01]  # the largest step: -0.04 -> -0.02
    q = [_driven(cfg, t) for t in steps]
    largest = max(abs(b - a) for a, b in itertools.pairwise(q))
    assert largest == abs(q[2] - q[1])
    period = pace(steps, cfg)
    assert period * PACE_FRACTION * cfg.motor_speed_limit / cfg.reducer_ratio == pytest.approx(largest, rel=1e-12)
    assert pace([0.0], cfg) == pace([0.0, 0.0], cfg) > 0.0  # nothing to move: the shortest period
    assert pace([-0.05, 1.0, -0.04], cfg) == pytest.approx(pace([-0.05, -0.04], cfg), rel=1e-12)  # 1.0: rejected


def test_plot_writes_a_png(cfg: AntennaConfig, tmp_path: Path) -> None:
    rec = recording(_recording(cfg, lag=1e-3), demo_topics(cfg.trajectory_controller), cfg)
    png = plot(rec, summarize(rec, cfg), cfg, tmp_path / 'demo.png', 'synthetic')
    assert png.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n' and not list(tmp_path.glob('.*'))


def test_a_continuing_trajectory_takes_over_at_its_arrival_not_at_its_stamp() -> None:
    """A replan repeats the running trajectory's points under its stamp: the planned series follows the first up to
    the second's arrival, then the second from its point at or before that arrival (not nothing, as when the
    second's stamp, the same as the first's, was taken for its start)."""
    def traj(stamp_ns: int, points: list[tuple[float, float]]) -> Msg:
        return Msg(header=_header(stamp_ns), joint_names=['j'],
                   points=[Msg(positions=[q], velocities=[], effort=[], time_from_start=_duration(t))
                           for t, q in points])

    stamp = 10**9
    first = traj(stamp, [(0.0, 0.0), (0.1, 0.1), (0.2, 0.2), (0.3, 0.3)])
    second = traj(stamp, [(0.1, 0.1), (0.2, 0.2), (0.3, 0.25), (0.4, 0.2)])  # continues, then turns
    series, _, _ = _planned([(stamp + 5_000_000, first), (stamp + 150_000_000, second)], 'j', stamp)
    assert series.t.tolist() == pytest.approx([0.0, 0.1, 0.1, 0.2, 0.3, 0.4])
    assert series.value.tolist() == [0.0, 0.1, 0.1, 0.2, 0.25, 0.2]
