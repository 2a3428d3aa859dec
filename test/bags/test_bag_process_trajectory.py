"""`fourbar process` on a bag of antenna trajectories: each converted by the node's rule (exactly its floats) onto
`<trajectory_controller>/joint_trajectory` at the input's log time and stamp; refused trajectories counted by problem
and skipped; `fourbar compare` covering actuator trajectories. No ROS middleware (bags written with rosbags)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from fourbar_ros.bags.storage import AtomicBagWriter, jazzy_typestore, open_bag, read_messages
from fourbar_ros.commands import main
from fourbar_ros.config.antenna_config import default_config
from fourbar_ros.interface.stamps import from_ns, seconds_to_ns
from fourbar_ros.interface.topics import ANTENNA_JOINT, JOINT_TRAJECTORY, trajectory_topic
from fourbar_ros.rules.antenna_trajectory import convert

CFG = default_config()
STORE = jazzy_typestore()
OUT_TOPIC = '/' + trajectory_topic(CFG.trajectory_controller).name


def antenna_trajectory(times: list[float], theta: list[float], theta_dot: list[float] | None, sec: int,
                       joint: str = ANTENNA_JOINT) -> Any:
    t = STORE.types
    points = [t['trajectory_msgs/msg/JointTrajectoryPoint'](
        positions=np.array([th]), velocities=np.array([] if theta_dot is None else [theta_dot[i]]),
        accelerations=np.array([], dtype=np.float64), effort=np.array([], dtype=np.float64),
        time_from_start=t['builtin_interfaces/msg/Duration'](*from_ns(seconds_to_ns(s))))
        for i, (s, th) in enumerate(zip(times, theta, strict=True))]
    stamp = t['builtin_interfaces/msg/Time'](sec=sec, nanosec=7 if sec else 0)
    return t[JOINT_TRAJECTORY](header=t['std_msgs/msg/Header'](stamp=stamp, frame_id=''), joint_names=[joint],
                               points=points)


GOOD = [antenna_trajectory([0.0, 1.0, 2.0], [0.0, 0.02, 0.03], [0.0, 0.015, 0.0], 3),
        antenna_trajectory([0.0, 0.5, 1.5, 3.0], [0.03, 0.05, 0.01, -0.02], None, 0)]  # stamp 0: on arrival
BAD = [antenna_trajectory([0.0, 1.0], [0.0, math.nan], None, 4),  # not_finite
       antenna_trajectory([0.0, 1.0], [0.0, 0.01], None, 5, joint='elbow'),  # wrong_joint
       antenna_trajectory([1.0, 1.0], [0.0, 0.01], None, 6),  # time_not_increasing
       antenna_trajectory([0.0, 0.5], [0.0, 0.01], None, 1),  # ends_in_past: 1 s + 0.5 s, logged at 5 s
       antenna_trajectory([0.0, 1.0], [0.0, 0.01], [0.0, 0.004], 9)]  # end_moving: 0.004 rad/s at the end


def trajectory_bag(path: Path) -> Path:
    with AtomicBagWriter(path) as bag:
        conn = bag.add_topic('/antenna_trajectory', JOINT_TRAJECTORY)
        for k, msg in enumerate([GOOD[0], *BAD, GOOD[1]]):
            bag.write(conn, (k + 1) * 10**9, bytes(STORE.serialize_cdr(msg, JOINT_TRAJECTORY)))
    return path


def test_a_trajectory_bag_is_converted_by_the_node_rule(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(['process', str(trajectory_bag(tmp_path / 'in')), str(tmp_path / 'out')]) == 0
    line = capsys.readouterr().err
    assert '7 antenna trajectories -> 2 actuator trajectories' in line
    assert ('refused: 1 wrong_joint, 1 not_finite, 1 time_not_increasing, 1 end_moving, 1 ends_in_past'
            in line)
    out = read_messages(tmp_path / 'out')
    assert list(out) == [OUT_TOPIC]
    sent = out[OUT_TOPIC]
    assert [log for log, _ in sent] == [1 * 10**9, 7 * 10**9]
    assert [(m.header.stamp.sec, m.header.stamp.nanosec) for _, m in sent] == [(3, 7), (0, 0)]
    for (_, m), given in zip(sent, GOOD, strict=True):
        # The same rule on the same decoded message: the same operations, so the same floats.
        want = convert(CFG, given.joint_names, given.points).trajectory
        assert list(m.joint_names) == [CFG.driven_joint]
        assert [p.positions.tolist() for p in m.points] == [[p] for p in want.positions.tolist()]
        assert all(p.effort.size == 0 for p in m.points)  # no effort field: effort_feedforward is off
        vel = want.velocities
        assert [p.velocities.tolist() for p in m.points] == \
            ([[]] * len(want) if vel is None else [[v] for v in vel.tolist()])
        assert all(len(p.accelerations) == 0 for p in m.points) == (want.accelerations is None)
        assert [from_ns(seconds_to_ns(t)) for t in want.times.tolist()] == \
            [(p.time_from_start.sec, p.time_from_start.nanosec) for p in m.points]


def test_a_bag_of_only_refused_trajectories_writes_an_empty_topic(tmp_path: Path,
                                                                   capsys: pytest.CaptureFixture[str]) -> None:
    with AtomicBagWriter(tmp_path / 'in') as bag:
        conn = bag.add_topic('/ns/antenna_trajectory', JOINT_TRAJECTORY)
        bag.write(conn, 10**9, bytes(STORE.serialize_cdr(BAD[0], JOINT_TRAJECTORY)))
    assert main(['process', str(tmp_path / 'in'), str(tmp_path / 'out')]) == 0
    assert '1 antenna trajectories -> 0 actuator trajectories' in capsys.readouterr().err
    with open_bag(tmp_path / 'out') as reader:
        assert [c.topic for c in reader.connections] == ['/ns' + OUT_TOPIC]
        assert not list(reader.messages())


def test_compare_covers_actuator_trajectories(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = trajectory_bag(tmp_path / 'in')
    assert main(['process', str(src), str(tmp_path / 'a')]) == 0
    assert main(['process', str(src), str(tmp_path / 'a2')]) == 0
    capsys.readouterr()
    assert main(['compare', str(tmp_path / 'a'), str(tmp_path / 'a2')]) == 0
    # B: the same with the third position of the second trajectory off by 1e-6 rad.
    with AtomicBagWriter(tmp_path / 'b') as bag, open_bag(tmp_path / 'a') as reader:
        conns = {c.topic: bag.add_topic(c.topic, c.msgtype) for c in reader.connections}
        for c, log, data in reader.messages():
            raw = bytes(data)
            if log == 7 * 10**9:
                msg = STORE.deserialize_cdr(raw, c.msgtype)
                msg.points[2].positions = msg.points[2].positions + 1e-6
                raw = bytes(STORE.serialize_cdr(msg, c.msgtype))
            bag.write(conns[c.topic], log, raw)
    capsys.readouterr()
    assert main(['compare', str(tmp_path / 'a'), str(tmp_path / 'b')]) == 1
    assert f'{OUT_TOPIC} message 1: point position[2]' in capsys.readouterr().out
    assert main(['compare', str(tmp_path / 'a'), str(tmp_path / 'b'), '--ignore', 'positions']) == 0


def test_an_undecodable_trajectory_message_is_one_line_and_no_output(tmp_path: Path,
                                                                       capsys: pytest.CaptureFixture[str]) -> None:
    with AtomicBagWriter(tmp_path / 'in') as bag:
        conn = bag.add_topic('/antenna_trajectory', JOINT_TRAJECTORY)
        bag.write(conn, 10**9, bytes(STORE.serialize_cdr(GOOD[0], JOINT_TRAJECTORY)))
        bag.write(conn, 2 * 10**9, b'\x00\x01\x00\x00\x07')
    assert main(['process', str(tmp_path / 'in'), str(tmp_path / 'out')]) == 2
    err = capsys.readouterr().err.strip()
    assert 'unreadable bag after 2 messages' in err and len(err.splitlines()) == 1
    assert not (tmp_path / 'out').exists()
