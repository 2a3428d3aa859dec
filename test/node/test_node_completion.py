"""fourbar_node's completion over the real middleware (actuator modes): the measured driven joint in on
measured_joint_states (the simulated actuator's, remapped to where it publishes, or the test's), one complete
JointState of every joint, antenna angle and rate and load torque out, equal to the completion rule's values (the
rule is the core's exact solution, test_rules_completion); with measured_joint_states remapped onto joint_states,
its own output skipped; each kind of bad measurement counted; ERROR for an angle out of range; WARN without
measurements; the tracking error; and no commanded pose on joint_states in the actuator modes.

Nodes run in-process (the process boundary is not what is tested): each test's nodes in their own namespace.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64
from support.paths import REPO
from support.ros_support import Collector, RosSession, wait_for
from support.ulp_bounds import CHAIN_ULPS, assert_close_ulps, completion_scales

from fourbar_ros.config.antenna_config import default_config
from fourbar_ros.interface.topics import BROADCASTER_JOINT_STATES, JOINT_STATES, MEASURED_JOINT_STATES
from fourbar_ros.node.fourbar_node import FourBarNode
from fourbar_ros.node.sim_actuator import SimActuator
from fourbar_ros.rules.completion import CompletionRule
from fourbar_ros.rules.diagnostics import Level

pytestmark = pytest.mark.ros

YAML = REPO / 'config' / 'antenna.yaml'
CFG = default_config()
RULE = CompletionRule(CFG)
DRIVEN = CFG.driven_joint
_ns = itertools.count()


class Rig:
    """fourbar_node in an actuator mode in its own namespace, with collectors of its outputs and a publisher of
    measurements (standing in for joint_state_broadcaster)."""

    def __init__(self, ros: RosSession, mode: str = 'trajectory', measured_on: str = MEASURED_JOINT_STATES.name,
                 **overrides: Any) -> None:
        self.ros = ros
        self.ns = f'/completion_test_{next(_ns)}'
        params = [Parameter('mode', value=mode), Parameter('joint_state_rate', value=0.0),
                  *(Parameter(k, value=v) for k, v in overrides.items())]
        self.node = FourBarNode(context=ros.context, namespace=self.ns, parameter_overrides=params,
                                cli_args=['--ros-args', '--params-file', str(YAML),
                                          '-r', f'{MEASURED_JOINT_STATES.name}:={measured_on}'])
        ros.add_node(self.node)
        self.states: Collector[JointState] = ros.collect(JointState, f'{self.ns}/joint_states')
        self.angle: Collector[Float64] = ros.collect(Float64, f'{self.ns}/antenna_angle')
        self.rate: Collector[Float64] = ros.collect(Float64, f'{self.ns}/antenna_rate')
        self.load: Collector[Float64] = ros.collect(Float64, f'{self.ns}/load_torque')
        self.measured = ros.publisher(JointState, f'{self.ns}/{measured_on}')
        for c in (self.states, self.angle, self.rate, self.load):
            ros.wait_publishers(c)
        ros.wait_subscribers(self.measured, 1 + (measured_on == JOINT_STATES.name))  # the node (and the collector)
        self.sims: list[SimActuator] = []

    @property
    def completion(self) -> Any:
        assert self.node.completion is not None
        return self.node.completion

    def completed(self) -> list[JointState]:
        return [m for m in self.states.messages if list(m.name) == RULE.names]

    def measure(self, names: list[str], position: list[float], velocity: list[float] = [],  # noqa: B006
                effort: list[float] = [], sec: int = 7) -> None:  # noqa: B006
        msg = JointState(name=names, position=position, velocity=velocity, effort=effort)
        msg.header.stamp.sec, msg.header.stamp.nanosec = sec, 123
        self.measured.publish(msg)

    def status(self) -> tuple[Level, str, dict[str, str]]:
        with self.ros.paused():  # not halfway through a callback
            s = self.node.diagnostic_status()
        return Level(s.level[0]), s.message, {kv.key: kv.value for kv in s.values}

    def close(self) -> None:
        for c in (self.states, self.angle, self.rate, self.load):
            self.ros.uncollect(c)
        self.ros.destroy(self.measured)
        for sim in self.sims:
            self.ros.remove_node(sim)
        self.ros.remove_node(self.node)


@pytest.fixture
def rig(ros: RosSession) -> Iterator[Any]:
    made: list[Rig] = []

    def make(**kwargs: Any) -> Rig:
        made.append(Rig(ros, **kwargs))
        return made[-1]

    yield make
    for r in made:
        r.close()


def test_the_simulated_actuator_is_completed_exactly_and_stamped_with_its_measurement(rig: Any) -> None:
    r = rig(mode='forward', measured_on=BROADCASTER_JOINT_STATES.name)
    measured_in: Collector[JointState] = r.ros.collect(JointState, f'{r.ns}/{BROADCASTER_JOINT_STATES.name}')
    sim = SimActuator(context=r.ros.context, namespace=r.ns, cli_args=['--ros-args', '--params-file', str(YAML)],
                      parameter_overrides=[Parameter('publish_rate', value=200.0),
                                           Parameter('velocity_noise', value=0.0)])
    r.sims.append(sim)
    r.ros.add_node(sim)
    commands = r.ros.publisher(Float64, f'{r.ns}/antenna_angle_cmd', 10)
    r.ros.wait_subscribers(commands)
    commands.publish(Float64(data=CFG.theta_max))  # the drive moves to the end of the range (and near its reach)
    wait_for(lambda: len(r.completed()) >= 40, what='40 completed joint states')
    measured = [m for m in measured_in.messages if list(m.name) == [DRIVEN]]
    by_stamp = {(m.header.stamp.sec, m.header.stamp.nanosec): m for m in measured}
    checked = 0
    for out in r.completed():
        assert list(out.name) == RULE.names == [DRIVEN, CFG.delta_joint, CFG.coupler_joint]
        source = by_stamp.get((out.header.stamp.sec, out.header.stamp.nanosec))
        if source is None:  # measured before the test's collector matched the simulated actuator
            continue
        expected = RULE.one(source.position[0], source.velocity[0], source.effort[0])
        assert list(out.position) == expected.positions  # the same floats: the node runs the rule
        assert list(out.velocity) == expected.velocities
        assert list(out.effort) == expected.efforts == [source.effort[0], 0.0, 0.0]
        checked += 1
    assert checked >= 40
    # Every antenna angle is the rule's angle of a measurement. Its measurement may reach measured_in after the
    # snapshot above, or after the angle itself (two subscriptions): waited for.
    thetas = {RULE.one(m.position[0]).theta for m in measured}
    for angle in [a.data for a in r.angle.messages]:
        if angle not in thetas:
            measured_in.wait_match(lambda m, a=angle: list(m.name) == [DRIVEN] and RULE.one(m.position[0]).theta == a)
    assert all(math.isfinite(x.data) for x in (*r.rate.messages, *r.load.messages))
    # The load the measured effort implies is the configured one (the sim's effort is the statics' torque).
    assert r.load.messages and all(x.data == pytest.approx(CFG.load_torque, rel=1e-9) for x in r.load.messages)
    r.ros.destroy(commands)
    r.ros.uncollect(measured_in)


def test_no_echo_and_no_commanded_pose_on_joint_states(rig: Any) -> None:
    # measured_joint_states remapped onto joint_states, where the node publishes: it skips its own messages.
    r = rig(measured_on=JOINT_STATES.name)
    commands = r.ros.publisher(Float64, f'{r.ns}/antenna_angle_cmd', 10)
    r.ros.wait_subscribers(commands)
    commands.publish(Float64(data=0.05))  # served (the command path), but not published as a pose here
    n = 25
    for i in range(n):
        r.measure([DRIVEN], [0.3 + 0.01 * i], [0.1], [0.02], sec=100 + i)
    counters = r.completion.counters
    wait_for(lambda: counters.measurements_own_skipped >= n, what='the node to see its own outputs')
    wait_for(lambda: len(r.completed()) >= n and counters.measurements_completed >= n, what='completed states')
    assert counters.measurements_completed == n
    assert len(r.completed()) == n  # measured in == completed out: the node never completes its own output
    assert counters.measurements_own_skipped == n and counters.measurements_ignored_no_driven_joint == 0
    assert all(list(m.name) in ([DRIVEN], RULE.names) for m in r.states.messages)  # no commanded [gamma, delta, ..]
    assert [m.header.stamp.sec for m in r.completed()] == list(range(100, 100 + n))
    r.ros.destroy(commands)


def test_bad_measurements_are_counted_and_publish_nothing(rig: Any) -> None:
    r = rig()
    c = r.completion.counters
    r.measure(['elbow'], [0.3])
    r.measure([DRIVEN, 'other'], [0.3])
    r.measure([DRIVEN], [0.3], [0.1, 0.2])
    r.measure([DRIVEN], [math.nan])
    r.measure([DRIVEN], [0.3], [math.inf])
    r.measure([DRIVEN], [0.3], [], [-math.inf])
    bad = 3.0
    r.measure([DRIVEN], [bad])
    wait_for(lambda: c.measurements_out_of_range == 1, what='the out-of-range measurement')
    assert c.measurements_ignored_no_driven_joint == 1
    assert c.measurements_ignored_mismatched_lengths == 2
    assert c.measurements_refused_not_finite == 3
    level, message, values = r.status()
    assert level is Level.ERROR and '3.0 rad' in message and RULE.reach.describe() in message
    assert values['measurements_out_of_range'] == '1'
    r.measure([DRIVEN, 'other'], [0.3, 1.0], [0.1, 0.0], [0.0, 0.0], sec=9)  # a good one clears the error
    wait_for(lambda: c.measurements_completed == 1 and len(r.completed()) == 1, what=f'the good one completed ({c})')
    assert r.status()[0] is not Level.ERROR
    assert not [m for m in r.angle.messages if not math.isfinite(m.data)]


def test_a_malformed_payload_is_counted_and_the_next_measurement_completed(rig: Any) -> None:
    from rclpy.serialization import serialize_message
    r = rig()
    c = r.completion.counters
    good = serialize_message(JointState(name=[DRIVEN], position=[0.3]))
    r.measured.publish(good[:20])  # truncated before the name count
    r.measured.publish(good[:1] + b'\x00' + good[2:])  # big-endian encapsulation
    r.measure([DRIVEN], [0.3], sec=11)
    wait_for(lambda: c.measurements_completed == 1 and len(r.completed()) == 1, what=f'the good one completed ({c})')
    assert c.measurements_ignored_malformed == 2
    assert r.completed()[0].header.stamp.sec == 11
    assert r.status()[2]['measurements_ignored_malformed'] == '2'


def test_a_nan_velocity_or_effort_is_not_measured(rig: Any) -> None:
    # joint_state_broadcaster's NaN for a state interface the joint lacks: positions and angle, no rate or no load.
    r = rig(mode='trajectory')
    c = r.completion.counters
    nan, inf = math.nan, math.inf
    sent = [(0.30, nan, 0.02), (0.31, 0.1, nan), (0.32, nan, nan), (0.33, 0.2, 0.03)]
    for k, (q, v, e) in enumerate(sent):
        r.measure([DRIVEN, 'other'], [q, 1.0], [v, 0.0], [e, 0.0], sec=20 + k)
    r.measure([DRIVEN], [0.34], [inf], [0.0], sec=30)  # an infinite one is still refused
    r.measure([DRIVEN], [0.35], [0.0], [-inf], sec=31)
    wait_for(lambda: c.measurements_completed == 4 and len(r.completed()) == 4 and len(r.angle.messages) == 4
             and len(r.rate.messages) == 2 and len(r.load.messages) == 2 and c.measurements_refused_not_finite == 2,
             what=f'four completed, two refused ({c})')
    out = r.completed()
    assert [m.header.stamp.sec for m in out] == [20, 21, 22, 23]
    for m, (q, v, e) in zip(out, sent, strict=True):
        expected = RULE.one(q, None if math.isnan(v) else v, None if math.isnan(e) else e)
        assert list(m.position) == expected.positions  # the same floats: the node runs the rule
        assert list(m.velocity) == expected.velocities and (len(m.velocity) == 0) == math.isnan(v)
    assert [a.data for a in r.angle.messages] == [RULE.one(q).theta for q, _, _ in sent]
    assert [x.data for x in r.rate.messages] == [RULE.one(q, v).theta_rate for q, v, _ in sent if not math.isnan(v)]
    assert [x.data for x in r.load.messages] == [RULE.one(q, None, e).load_torque for q, _, e in sent
                                                 if not math.isnan(e)]
    assert c.measurements_out_of_range == c.measurements_not_completed == 0


def test_no_measurement_warns_and_tracking_is_reported(rig: Any) -> None:
    r = rig(measurement_timeout=0.05, tracking_window=1000.0)
    wait_for(lambda: r.status()[0] is Level.WARN, what='the WARN without measurements')
    assert 'measurement_timeout' in r.status()[1]
    r.completion.set_commanded(0.02)
    theta_far, theta_near = RULE.one(0.25).theta, RULE.one(0.2).theta
    r.measure([DRIVEN], [0.25])
    r.measure([DRIVEN], [0.2])
    r.ros.wait_for(lambda: r.completion.counters.measurements_completed == 2, what='two measurements')
    values = r.status()[2]
    assert float(values['tracking_error_rad']) == 0.02 - theta_near
    assert float(values['tracking_error_worst_rad']) == max(abs(0.02 - theta_far), abs(0.02 - theta_near))
    assert float(values['measured_theta_rad']) == theta_near


def test_the_live_completion_equals_process_of_the_same_measured_bag(rig: Any, tmp_path: Path) -> None:
    from rclpy.serialization import serialize_message

    from fourbar_ros.bags.storage import AtomicBagWriter, jazzy_typestore, open_bag
    from fourbar_ros.commands import main

    r = rig()
    measured = []
    for i in range(30):
        q = RULE.reach.theta_max * (-0.95 + 1.9 * i / 29) if i < 29 else RULE.reach.theta_max * (1 - 1e-12)
        msg = JointState(name=[DRIVEN], position=[q], velocity=[0.2 - 0.01 * i], effort=[0.001 * i])
        msg.header.stamp.sec, msg.header.stamp.nanosec = 50 + i, 999
        measured.append(msg)
        r.measured.publish(msg)
    counters = r.completion.counters
    wait_for(lambda: counters.measurements_completed == 30 and len(r.completed()) == 30, what='30 completed')
    bag = tmp_path / 'measured'
    with AtomicBagWriter(bag) as writer:
        conn = writer.add_topic(f'/{MEASURED_JOINT_STATES.name}', 'sensor_msgs/msg/JointState')
        for msg in measured:
            writer.write(conn, msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec, serialize_message(msg))
    assert main(['process', str(bag), str(tmp_path / 'out'), '--params', str(YAML)]) == 0
    with open_bag(tmp_path / 'out') as reader:
        store = jazzy_typestore()
        out: dict[str, list[Any]] = {}
        for c, log, data in reader.messages():
            out.setdefault(c.topic, []).append((log, store.deserialize_cdr(bytes(data), c.msgtype)))
    live = r.completed()
    offline = [m for _, m in out['/joint_states']]
    assert len(offline) == len(live) == 30
    assert [(m.header.stamp.sec, m.header.stamp.nanosec) for m in offline] == \
        [(m.header.stamp.sec, m.header.stamp.nanosec) for m in live]
    assert [log for log, _ in out['/joint_states']] == [m.header.stamp.sec * 10**9 + 999 for m in live]
    q = np.array([m.position[0] for m in measured])
    theta = np.array([RULE.one(float(x)).theta for x in q])
    a_pos, b_pos = np.array([list(m.position) for m in live]), np.array([m.position for m in offline])
    theta_s, other_s, x_s, rate_s, other_rate_s, load_s = completion_scales(CFG.linkage, CFG.driven, q, theta,
                                                                            a_pos[:, 1])
    n = 2 * CHAIN_ULPS  # per-message (libm) against block (numpy) path, each within CHAIN_ULPS of the scale
    assert np.array_equal(b_pos[:, 0], a_pos[:, 0]) and np.array_equal(a_pos[:, 0], q)  # the measurement itself
    assert_close_ulps(b_pos[:, 1], a_pos[:, 1], n, other_s, 'other rocker')
    assert_close_ulps(b_pos[:, 2], a_pos[:, 2], n, x_s, 'coupler joint')
    q_dot = np.array([m.velocity[0] for m in measured])
    for i, (a, b) in enumerate(zip(live, offline, strict=True)):
        assert len(a.velocity) == len(b.velocity)
        if len(a.velocity):
            assert b.velocity[0] == a.velocity[0] == q_dot[i]
            assert_close_ulps(b.velocity[1], a.velocity[1], n, abs(q_dot[i]) * other_rate_s[i], f'velocity {i}')
        assert list(a.effort) == list(b.effort) == [measured[i].effort[0], 0.0, 0.0]
    angles = [m.data for _, m in out['/antenna_angle']]
    assert_close_ulps(np.array(angles), theta, n, theta_s, 'antenna angle')
    live_rate, live_load = [m.data for m in r.rate.messages], [m.data for m in r.load.messages]
    assert len(live_rate) == len(out['/antenna_rate']) == 30 and len(live_load) == len(out['/load_torque']) == 30
    assert_close_ulps(np.array([m.data for _, m in out['/antenna_rate']]), np.array(live_rate), n,
                      np.abs(q_dot) * rate_s, 'antenna rate')
    effort = np.array([m.effort[0] for m in measured])
    assert_close_ulps(np.array([m.data for _, m in out['/load_torque']]), np.array(live_load), n,
                      np.abs(effort) * load_s, 'load torque')
