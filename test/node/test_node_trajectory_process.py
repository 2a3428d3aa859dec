"""fourbar_node in trajectory mode over the real middleware against `fourbar process` of the same antenna trajectories:
the antenna trajectories sent to the node and the actuator trajectories it sends on
`<trajectory_controller>/joint_trajectory` are recorded (fourbar_ros.live.record, raw as received), `fourbar process`
converts the recorded input bag, and `fourbar compare` finds the node's output and process's equal, bit for bit.

Positions only, with velocities, with accelerations, one that needs refinement points, one refused for a limit
(limit_policy reject) and, after a run-time change of limit_policy, the same one retimed. The node runs in-process
for the module (the process boundary is not what is tested); each check waits for counts with a deadline.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from builtin_interfaces.msg import Duration, Time
from rclpy.parameter import Parameter
from support.cli_support import fourbar
from support.paths import REPO
from support.ros_support import RosSession, wait_for
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from fourbar_ros.bags.process_trajectory import TrajectoryStats
from fourbar_ros.bags.storage import read_messages
from fourbar_ros.config.antenna_config import default_config
from fourbar_ros.interface.stamps import from_ns, seconds_to_ns
from fourbar_ros.interface.topics import ANTENNA_JOINT, ANTENNA_TRAJECTORY, trajectory_topic
from fourbar_ros.live.record import Recorder, discover
from fourbar_ros.node.fourbar_node import FourBarNode
from fourbar_ros.rules.antenna_trajectory import TrajectoryProblem
from fourbar_ros.rules.controller_contract import ContractRule
from fourbar_ros.rules.serve import ActuationCounters

pytestmark = pytest.mark.ros

YAML = REPO / 'config' / 'antenna.yaml'
CFG = default_config()
#: Stamps count from here (system clock, s): hours ahead, so no trajectory ends in the past on arrival.
START_SEC = int(time.time()) + 3600
NS = '/trajectory_process'
INPUT = f'{NS}/{ANTENNA_TRAJECTORY.name}'
OUTPUT = f'{NS}/{trajectory_topic(CFG.trajectory_controller).name}'


def duration(t: float) -> Duration:
    sec, nanosec = from_ns(seconds_to_ns(t))
    return Duration(sec=sec, nanosec=nanosec)


def antenna_msg(times: list[float], theta: list[float], theta_dot: list[float] | None = None,
                theta_ddot: list[float] | None = None, sec: int = 1) -> JointTrajectory:
    """An antenna trajectory stamped ``sec`` s + 7 ns (a stamp the node keeps, so both sides carry it)."""
    pts = [JointTrajectoryPoint(positions=[th], velocities=[] if theta_dot is None else [theta_dot[i]],
                                accelerations=[] if theta_ddot is None else [theta_ddot[i]],
                                time_from_start=duration(t))
           for i, (t, th) in enumerate(zip(times, theta, strict=True))]
    msg = JointTrajectory(joint_names=[ANTENNA_JOINT], points=pts)
    if sec:
        msg.header.stamp = Time(sec=START_SEC + sec, nanosec=7)
    return msg


#: The whole tilt range in 10 ms: far over the motor's speed (refused under reject, retimed under retime).
TOO_FAST = antenna_msg([0.0, 0.01], [CFG.theta_min, CFG.theta_max], sec=6)
TRAJECTORIES = [
    antenna_msg([0.5, 1.5, 2.5], [0.0, 0.01, 0.015]),  # positions only, stamp 0
    antenna_msg([0.0, 1.0, 2.0, 3.0], [0.0, 0.01, 0.02, 0.025], [0.0, 0.01, 0.008, 0.0], sec=2),  # velocities
    antenna_msg([0.0, 1.0, 2.0], [0.0, 0.02, 0.03], [0.0, 0.015, 0.0], [0.0, 0.0, -0.01], sec=3),  # accelerations
    antenna_msg([0.0, 6.0], [CFG.theta_min, CFG.theta_max], sec=4),  # one segment far over trajectory_tolerance
    TOO_FAST,
    antenna_msg([0.0, 1.0], [0.0, 0.01], [0.0, 0.0], sec=7),
]


class Rig:
    """The node in trajectory mode and the client's publisher of antenna trajectories."""

    def __init__(self, ros: RosSession) -> None:
        self.ros = ros
        self.node = FourBarNode(context=ros.context, namespace=NS, cli_args=['--ros-args', '--params-file', str(YAML)],
                                parameter_overrides=[Parameter('mode', value='trajectory')])
        ros.add_node(self.node)
        self.antenna = ros.publisher(JointTrajectory, INPUT, 10)
        wait_for(lambda: all(ros.node.get_publishers_info_by_topic(t) for t in (INPUT, OUTPUT)),
                 what='publishers on both topics')
        self.plans = {p.name: p for p in discover(ros.node, ros.executor, [INPUT, OUTPUT], 0.0)}

    @property
    def counters(self) -> ActuationCounters:
        counters: ActuationCounters = self.node.actuation.counters
        return counters

    def set_policy(self, policy: str) -> None:
        result = self.node.set_parameters([Parameter('limit_policy', value=policy)])
        assert result[0].successful, result[0].reason

    def run(self, tmp: Path, messages: list[JointTrajectory]) -> ActuationCounters:
        """Record the input and the node's output of ``messages`` into ``tmp/input`` and ``tmp/node``; return what
        the node counted for them."""
        recorders = [Recorder(self.ros.node, tmp / name, [self.plans[topic]])
                     for name, topic in (('input', INPUT), ('node', OUTPUT))]
        self.ros.executor.wake()
        try:
            self.ros.wait_subscribers(self.antenna, 2)  # the node's and the recorder's
            wait_for(lambda: self.node.actuation._trajectory_pub.get_subscription_count() >= 1,
                     what='the recorder matched by the node')
            wait_for(lambda: all(r.matched() for r in recorders), what='the recorder matched with both publishers')
            before = self.counters.as_dict()
            for msg in messages:
                self.antenna.publish(msg)
            counters = self.counters

            def handled() -> int:  # sent or refused: the callback's last step either way
                return (counters.trajectories_sent - before['trajectories_sent']
                        + sum(n - before[f'trajectories_rejected_{p.value}'] for p, n in counters.rejected.items()))
            wait_for(lambda: handled() == len(messages), what='every antenna trajectory handled by the node')
            sent = counters.trajectories_sent - before['trajectories_sent']
            wait_for(lambda: recorders[0].counts[INPUT] == len(messages) and recorders[1].counts[OUTPUT] == sent,
                     what='every message recorded')
        except BaseException:
            for r in recorders:
                r.abort()
            raise
        for r in recorders:
            r.close()
        # Unmatched before the next run counts its own recorder's matches.
        wait_for(lambda: self.antenna.get_subscription_count() == 1
                 and self.node.actuation._trajectory_pub.get_subscription_count() == 0, what='the recorder gone')
        delta = ActuationCounters(**{k: v - before[k] for k, v in counters.as_dict().items()
                                     if not k.startswith(('trajectories_rejected_', 'contract_refused_'))})
        delta.rejected = {p: counters.rejected[p] - before[f'trajectories_rejected_{p.value}']
                          for p in TrajectoryProblem}
        delta.refused = {r: counters.refused[r] - before[f'contract_refused_{r.value}'] for r in ContractRule}
        return delta

    def close(self) -> None:
        self.ros.destroy(self.antenna)
        self.ros.remove_node(self.node)


@pytest.fixture(scope='module')
def rig(ros: RosSession) -> Iterator[Rig]:
    r = Rig(ros)
    yield r
    r.close()


def params_file(tmp: Path, policy: str) -> Path:
    """The shipped parameter file with ``limit_policy: policy``."""
    text = YAML.read_text()
    assert text.count('limit_policy: reject') == 1
    path = tmp / f'{policy}.yaml'
    path.write_text(text.replace('limit_policy: reject', f'limit_policy: {policy}'))
    return path


def assert_process_equals_the_node(tmp: Path, params: Path, counted: ActuationCounters) -> None:
    processed = fourbar('process', tmp / 'input', tmp / 'process', '--params', params)
    assert processed.returncode == 0, processed.stderr
    # process counts what the node counted for the same messages (its summary line, without the seconds).
    assert TrajectoryStats(counted).summary().rsplit(' in ', 1)[0] in processed.stderr
    # Both serve them with rules.serve.serve_antenna_trajectory on the same floats (the recorded CDR decoded by
    # rosbags or rclpy) and build the message with interface.joint_trajectory: identical operations, so every float
    # and every time_from_start is compared bit for bit (0 ulps). Log times differ (process writes at the input's log
    # time, the recorder at its arrival); the header stamps are checked exactly below.
    compared = fourbar('compare', tmp / 'node', tmp / 'process', '--params', params, '--ulps', '0',
                       '--ignore', 'stamps')
    assert compared.returncode == 0, compared.stdout
    assert f'messages compared: {OUTPUT} {counted.trajectories_sent};' in compared.stdout
    live, offline = read_messages(tmp / 'node')[OUTPUT], read_messages(tmp / 'process')[OUTPUT]
    assert [(m.header.stamp.sec, m.header.stamp.nanosec) for _, m in live] == \
        [(m.header.stamp.sec, m.header.stamp.nanosec) for _, m in offline]


def test_the_node_sends_what_process_makes_of_the_same_antenna_trajectories(rig: Rig, tmp_path: Path) -> None:
    rig.set_policy('reject')
    counted = rig.run(tmp_path, TRAJECTORIES)
    assert counted.trajectories_sent == len(TRAJECTORIES) - 1
    assert counted.rejected[TrajectoryProblem.OVER_LIMITS] == 1
    assert counted.trajectory_points_inserted > 0 and counted.trajectories_retimed == 0
    assert_process_equals_the_node(tmp_path, YAML, counted)


def test_retimed_trajectories_equal_process_under_the_same_policy(rig: Rig, tmp_path: Path) -> None:
    rig.set_policy('retime')
    try:
        counted = rig.run(tmp_path, [TOO_FAST, TRAJECTORIES[1]])
    finally:
        rig.set_policy('reject')
    assert counted.trajectories_sent == 2 and counted.trajectories_retimed == 1
    assert_process_equals_the_node(tmp_path, params_file(tmp_path, 'retime'), counted)
