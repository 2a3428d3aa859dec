"""fourbar_node in-process (its own executor thread) over the real middleware; every output checked against the core.

Each test builds the node in its own namespace on this module's leased ROS domain id, proves the command
path is connected end to end (``sync_probe``), then counts messages exactly: answers arrive in order,
so a command that produced no output is proven silent by the answer to the next good command.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any

import pytest
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64
from support.paths import REPO
from support.ros_support import Collector, RosSession, sync_probe, wait_for, wait_future
from visualization_msgs.msg import MarkerArray

from fourbar_ros.config.antenna_config import AntennaConfig, load_config
from fourbar_ros.core.antenna import LinkageState
from fourbar_ros.core.transforms import antenna_joint_positions
from fourbar_ros.node.fourbar_node import FourBarNode
from fourbar_ros.rules.diagnostics import status_name

pytestmark = pytest.mark.ros

YAML = REPO / 'config' / 'antenna.yaml'
CFG = load_config(YAML)
LO, HI = CFG.theta_min, CFG.theta_max
#: Equality is used where the node and the test call the identical scalar functions on the same float: the
#: node's pose_solver and ``core()`` both call ``linkage.rocker_angles(theta, branch)`` and
#: ``linkage.torque_at(...)`` (constant load). TOL is for cross-path comparisons, each with its reason beside it.
TOL = 1e-12
_ns_counter = itertools.count()


def core(cfg: AntennaConfig, theta: float) -> LinkageState:
    """The expected state, straight from the core (no node code)."""
    return cfg.linkage.state(theta, cfg.load_torque, cfg.driven, cfg.branch)


def probes(cfg: AntennaConfig) -> list[float]:
    """Distinct accepted angles for sync_probe."""
    return [cfg.theta_min + (cfg.theta_max - cfg.theta_min) * (i + 0.5) / 600 for i in range(600)]


@dataclass
class Rig:
    """The node under test in namespace ``ns`` and the client's endpoints on its topics."""

    ros: RosSession
    node: FourBarNode
    ns: str
    pub: Any
    outputs: dict[str, Collector[Any]] = field(default_factory=dict)

    @property
    def cfg(self) -> AntennaConfig:
        return self.node.config

    def send(self, values: Sequence[float]) -> None:
        for v in values:
            self.pub.publish(Float64(data=float(v)))

    def matches(self, col: Collector[Any], msg: Any, probe: float) -> bool:
        s = core(self.cfg, probe)
        if col.topic.endswith('joint_states'):
            return bool(msg.position[0] == s.gamma)
        return bool(msg.data == s.input_torque)

    def sync(self) -> None:
        for col in self.outputs.values():
            self.ros.wait_publishers(col)
        self.ros.wait_subscribers(self.pub)
        sync_probe(lambda t: self.send([t]), list(self.outputs.values()), probes(self.cfg), self.matches)

    def received(self) -> int:
        return self.node.counters.commands_received


@pytest.fixture
def make_rig(ros: RosSession) -> Iterator[Any]:
    made: list[Rig] = []

    def make(outputs: Sequence[str] = ('joint_states', 'input_torque'), **overrides: Any) -> Rig:
        ns = f'/node_test_{next(_ns_counter)}'
        periods = {'diagnostics_period': 0.05, 'marker_period': 0.02, 'joint_state_rate': 0.0}
        params = [Parameter(k, value=v) for k, v in {**periods, **overrides}.items()]
        node = FourBarNode(context=ros.context, namespace=ns, parameter_overrides=params,
                           cli_args=['--ros-args', '--params-file', str(YAML)])
        ros.add_node(node)
        types = {'joint_states': JointState, 'input_torque': Float64, 'linkage_markers': MarkerArray}
        rig = Rig(ros, node, ns, ros.publisher(Float64, f'{ns}/antenna_angle_cmd'))
        for name in outputs:
            rig.outputs[name] = ros.collect(types[name], f'{ns}/{name}')
        made.append(rig)
        if outputs:
            rig.sync()
        return rig

    yield make
    for rig in made:
        for col in rig.outputs.values():
            ros.uncollect(col)
        ros.destroy(rig.pub)
        ros.remove_node(rig.node)


def check_joint_states(cfg: AntennaConfig, msgs: list[JointState], served: list[float]) -> None:
    """Every JointState against the core: names, positions, effort, velocity from stamps."""
    assert len(msgs) == len(served)
    prev: JointState | None = None
    for msg, theta in zip(msgs, served, strict=True):
        s = core(cfg, theta)
        assert list(msg.name) == list(cfg.joint_names)
        # Identical scalar functions on the same theta (see TOL): equal.
        # The coupler joint is gamma + theta, the same addition in the node: equal too.
        assert list(msg.position) == [s.gamma, s.delta, s.gamma + theta]
        assert list(msg.effort) == [s.input_torque, 0.0, 0.0]
        assert all(math.isfinite(x) for x in [*msg.position, *msg.velocity, *msg.effort])
        stamp = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
        if prev is not None:
            prev_stamp = prev.header.stamp.sec * 10**9 + prev.header.stamp.nanosec
            dt = (stamp - prev_stamp) * 1e-9
            if 0.0 < dt <= cfg.velocity_timeout:
                want = [(msg.position[i] - prev.position[i]) / dt for i in range(3)]
                # The node's rule does the same operations (int ns difference * 1e-9, subtract, divide): equal.
                assert list(msg.velocity) == want
            else:
                assert list(msg.velocity) == []
        prev = msg


def check_markers(msg: MarkerArray, theta: float) -> None:
    s = core(CFG, theta)
    ref = antenna_joint_positions(0.18, 0.06, 0.102, 0.06, theta, s.gamma, s.delta)
    frame, rockers, coupler, joints, antenna = msg.markers
    # The linkage lies in the x-z plane of frame_id (REP-103: z up), as in the URDF: y is 0 everywhere.
    assert all(p.y == 0.0 for m in msg.markers for p in m.points)
    assert [(p.x, p.z) for p in frame.points] == [(0.0, 0.0), (0.18, 0.0)]
    assert len(rockers.points) == 4
    assert all(m.header.frame_id == 'fourbar_base' and m.ns == 'fourbar' for m in msg.markers)
    assert [m.id for m in msg.markers] == [0, 1, 2, 3, 4]
    # Two code paths (marker_geometry vs transforms): coordinates below 0.2 m from a few products of lengths
    # and sines/cosines of the solved angles, each ~1 ulp; C may come along another chain of the loop, which
    # adds the solve's closure residual (ulps times the pose's condition, modest away from dead points).
    # Both are many orders below TOL = 1e-12 m.
    for point, want in zip(joints.points, (ref.a, ref.b, ref.c, ref.d), strict=True):
        assert (point.x, point.y, point.z) == pytest.approx((want[0], 0.0, want[1]), abs=TOL)
    got = [c for p in coupler.points for c in (p.x, p.z)]
    assert got == pytest.approx([*ref.b, *ref.c], abs=TOL)
    tail, tip = antenna.points
    # tip - tail = coupler * (cos theta, -sin theta) up to the rounding of two sums of ~0.2 m (~3e-17 m each)
    # against a 0.102 m arrow: the angle is within ~1e-15 rad of theta.
    assert math.atan2(-(tip.z - tail.z), tip.x - tail.x) == pytest.approx(theta, abs=TOL)


def test_outputs_match_the_core(ros: RosSession, make_rig: Any) -> None:
    rig = make_rig()
    markers = ros.collect(MarkerArray, f'{rig.ns}/linkage_markers', 10)
    commands = [LO + (HI - LO) * i / 40 for i in range(41)] + [LO, HI, 0.0, 0.0, 0.0, 0.05]
    rig.send(commands)
    js = rig.outputs['joint_states'].wait_count(len(commands))
    tq = rig.outputs['input_torque'].wait_count(len(commands))
    check_joint_states(CFG, js, commands)
    for msg, theta in zip(tq, commands, strict=True):
        s = core(CFG, theta)
        assert msg.data == s.input_torque  # identical scalar function (see TOL)
        # The shipped YAML is a constant load: input torque times dq/dtheta is that load everywhere. Two
        # formulas (torque_at's dtheta/dq, rates_at's dq/dtheta), each a few ulps times its condition number,
        # which is modest here (no dead point in the range): rel TOL = 1e-12 (~4500 ulps) bounds it.
        assert msg.data * s.dgamma_dtheta == pytest.approx(3.5, rel=TOL)
    # Markers come from a timer: the latest pose is drawn, and every drawing is of a served pose.
    b_x = 0.06 * math.cos(core(CFG, 0.05).gamma)
    markers.wait_match(lambda m: m.markers[3].points[1].x == b_x)
    ros.uncollect(markers)
    served = commands + probes(CFG)  # the sync probes were served too
    for msg in markers.messages:
        tail, tip = msg.markers[4].points
        theta = math.atan2(-(tip.z - tail.z), tip.x - tail.x)
        nearest = min(served, key=lambda c: abs(c - theta))
        assert abs(nearest - theta) < 1e-12
        check_markers(msg, nearest)
    assert rig.node.counters.markers_published == len(markers.messages)
    stamps = [m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for m in js]
    assert stamps == sorted(stamps)


def test_repeated_command_is_not_recomputed(make_rig: Any) -> None:
    rig = make_rig()
    computed, reused = rig.node.cache.computed, rig.node.cache.reused
    rig.send([0.03] * 5 + [0.04])
    msgs = rig.outputs['joint_states'].wait_count(6)
    assert rig.node.cache.computed - computed == 2
    assert rig.node.cache.reused - reused == 4
    check_joint_states(CFG, msgs, [0.03] * 5 + [0.04])
    for msg in msgs[1:5]:
        assert list(msg.velocity) in ([0.0, 0.0, 0.0], [])  # same pose: zero velocity (or none if stale)


BAD = [math.nan, math.inf, -math.inf, math.nextafter(HI, 1.0), math.nextafter(LO, -1.0), 0.5, 1.0, -3.0, 1e300]


def test_bad_commands_rejected(make_rig: Any) -> None:
    rig = make_rig()
    before = dict(rig.node.counters.as_dict())
    sequence = [0.01, *BAD, HI, *BAD, LO, 0.02]
    rig.send(sequence)
    served = [0.01, HI, LO, 0.02]
    check_joint_states(CFG, rig.outputs['joint_states'].wait_count(len(served)), served)
    tq = rig.outputs['input_torque'].wait_count(len(served))
    assert [m.data for m in tq] == [core(CFG, t).input_torque for t in served]  # identical function (see TOL)
    rig.ros.wait_for(lambda: rig.received() - before['commands_received'] == len(sequence), what='all commands counted')
    after = rig.node.counters.as_dict()
    delta = {k: after[k] - before[k] for k in after}
    assert delta['commands_rejected_not_finite'] == 6
    assert delta['commands_rejected_out_of_limits'] == 6     # nextafter(HI), nextafter(LO), 0.5 twice each
    assert delta['commands_rejected_out_of_reach'] == 6      # 1.0, -3.0, 1e300 twice each
    assert delta['commands_accepted'] == 4 and delta['commands_clamped'] == 0
    assert delta['joint_states_published'] == 4
    # The node is still up and serving.
    rig.send([0.03])
    check_joint_states(CFG, rig.outputs['joint_states'].wait_count(5)[4:], [0.03])


def test_bad_commands_clamped(make_rig: Any) -> None:
    rig = make_rig(out_of_limits='clamp')
    sequence = [0.01, *BAD, 0.02]
    rig.send(sequence)
    # NaN and +-inf are rejected; finite commands go to the nearer limit.
    served = [0.01, HI, LO, HI, HI, LO, HI, 0.02]
    msgs = rig.outputs['joint_states'].wait_count(len(served))
    check_joint_states(CFG, msgs, served)
    assert len(rig.outputs['input_torque'].wait_count(len(served))) == len(served)
    rig.ros.wait_for(lambda: rig.node.counters.commands_clamped == 6, what='6 clamped commands')
    assert rig.node.counters.commands_rejected_not_finite == 3


def set_params(ros: RosSession, rig: Rig, params: list[Parameter], atomically: bool = False) -> list[Any]:
    client = AsyncParameterClient(ros.node, f'{rig.ns}/fourbar_node')
    assert client.wait_for_services(timeout_sec=30.0)
    future = client.set_parameters_atomically(params) if atomically else client.set_parameters(params)
    response = wait_future(future)
    return [response.result] if atomically else list(response.results)


def test_runtime_parameter_changes_validated_as_a_whole(ros: RosSession, make_rig: Any) -> None:
    rig = make_rig()
    before = rig.node.config
    rejected = [
        ([Parameter('theta_max', value=0.9)], False, 'theta_max: '),                    # out of reach
        ([Parameter('coupler_length', value=0.5)], False, 'coupler_length: '),         # never assembles
        ([Parameter('theta_min', value=0.05), Parameter('theta_max', value=0.01)], True, 'theta_min, theta_max: '),
        ([Parameter('driven_rocker', value='beta')], False, 'driven_rocker: '),
        ([Parameter('gamma_joint', value='rocker_cd_joint')], False, 'gamma_joint: '),
        ([Parameter('reducer_ratio', value=500)], False, 'Wrong parameter type'),        # rclpy's own check
        ([Parameter('load_torque', value=math.nan)], False, 'load_torque'),             # rclpy's range check
        ([Parameter('diagnostics_period', value=2.0)], False, 'read-only'),             # rclpy's read-only check
        ([Parameter('diagnostics_period', value=2.0)], True, 'read-only'),
        ([Parameter('robot_description', value='<robot/>')], False, 'undeclared'),       # rclpy: not declared
        ([Parameter('robot_description', value='<robot/>')], True, 'undeclared'),
        ([Parameter('reducer_ratio', value='fast')], True, 'Wrong parameter type'),
    ]
    for count, (params, atomic, reason) in enumerate(rejected, start=1):
        results = set_params(ros, rig, params, atomic)
        assert not results[0].successful, params
        assert reason in results[0].reason and '\n' not in results[0].reason
        # Every refusal is counted, rclpy's own (before our callback) as well as ours.
        assert rig.node.counters.parameter_changes_rejected == count, (params, results[0].reason)
        assert rig.node.config == before
        assert rig.node.get_parameter('theta_max').value == HI
        assert rig.node.get_parameter('coupler_length').value == 0.102
    # Still serving with the old configuration.
    rig.send([0.06])
    check_joint_states(CFG, rig.outputs['joint_states'].wait_count(1), [0.06])
    # A valid change applies, as a whole, to the next command.
    results = set_params(ros, rig, [Parameter('load_torque', value=2.0), Parameter('out_of_limits', value='clamp'),
                                    Parameter('theta_max', value=0.3)], atomically=True)
    assert results[0].successful
    assert rig.node.config.load_torque == 2.0 and rig.node.config.theta_max == 0.3
    rig.send([0.25, 0.7])
    tq = rig.outputs['input_torque'].wait_count(3)[1:]
    for msg, theta in zip(tq, [0.25, 0.3], strict=True):
        assert msg.data * core(CFG, theta).dgamma_dtheta == pytest.approx(2.0, rel=TOL)  # two formulas: see above


def test_outputs_nobody_subscribes_to_are_not_computed(ros: RosSession, make_rig: Any) -> None:
    rig = make_rig(outputs=('joint_states',))
    node = rig.node
    c0 = dict(node.counters.as_dict())
    rig.send([0.01, 0.02, 0.03])
    rig.outputs['joint_states'].wait_count(3)
    c1 = node.counters.as_dict()
    assert c1['input_torque_skipped'] - c0['input_torque_skipped'] == 3 and c1['input_torque_published'] == 0
    assert c1['markers_published'] == 0
    ros.wait_for(lambda: node.counters.markers_skipped > c1['markers_skipped'], what='skipped marker ticks')
    # Nobody listens at all: commands are still checked and counted but nothing is solved.
    ros.uncollect(rig.outputs.pop('joint_states'))
    wait_for(lambda: node._joint_pub.get_subscription_count() == 0, what='the node to see no subscriber')
    computed = node.cache.computed
    received = rig.received()
    rig.send([0.04, 0.05, math.nan, 0.06])
    rig.ros.wait_for(lambda: rig.received() - received == 4, what='4 commands counted')
    assert node.cache.computed == computed
    assert node.counters.commands_not_solved - c1['commands_not_solved'] == 3
    assert node.counters.commands_rejected_not_finite == 1
    # Diagnostics: nobody on /diagnostics, so the timer skips building them.
    skipped = node.counters.diagnostics_skipped
    ros.wait_for(lambda: node.counters.diagnostics_skipped >= skipped + 2, what='skipped diagnostics')
    assert node.counters.diagnostics_published == 0


@pytest.mark.parametrize(('namespace', 'expected'), [('/', 'fourbar_node: task'), ('/tilt', 'tilt/fourbar_node: task'),
                                                     ('/robot/tilt', 'robot/tilt/fourbar_node: task')])
def test_a_status_name_is_diagnostic_updaters_with_the_namespace_before_it(ros: RosSession, namespace: str,
                                                                             expected: str) -> None:
    node = Node('fourbar_node', namespace=namespace, context=ros.context)
    try:
        assert status_name(node.get_fully_qualified_name(), 'task') == expected
    finally:
        node.destroy_node()


def test_diagnostics(ros: RosSession, make_rig: Any) -> None:
    rig = make_rig(outputs=('joint_states',))
    diag = ros.collect(DiagnosticArray, '/diagnostics', 10)
    try:
        name = f'{rig.ns[1:]}/fourbar_node: antenna tilt linkage'  # the node's full name, no leading slash
        received = rig.received()
        rig.send([0.02, 0.5])

        def status_after(count: int) -> Any:
            def ok(msg: DiagnosticArray) -> bool:
                return any(s.name == name and dict((kv.key, kv.value) for kv in s.values).get(
                    'commands_received') == str(count) for s in msg.status)
            msg = diag.wait_match(ok)
            return next(s for s in msg.status if s.name == name)

        st = status_after(received + 2)
        values = {kv.key: kv.value for kv in st.values}
        assert st.level == b'\x01' and 'rejected' in st.message   # last command 0.5 rad was rejected
        assert values['last_command_outcome'] == 'rejected_out_of_limits'
        s = core(CFG, 0.02)
        assert float(values['theta_rad']) == 0.02
        assert float(values['gamma_rad']) == s.gamma and float(values['delta_rad']) == s.delta
        assert float(values['input_torque_nm']) == s.input_torque
        assert float(values['mechanical_advantage']) == s.dgamma_dtheta
        assert float(values['transmission_angle_deg']) == math.degrees(s.transmission_angle)
        assert float(values['motor_torque_margin_nm']) == 0.009 - s.input_torque / 500.0
        assert float(values['output_torque_margin_nm']) == 5.0 - s.input_torque
        assert values['input_torque_skipped'] == str(rig.node.counters.input_torque_skipped)
        rig.send([0.03])
        st = status_after(received + 3)
        assert st.level == b'\x00' and st.message == 'ok'
        assert rig.node.counters.diagnostics_published > 0
    finally:
        ros.uncollect(diag)


def test_invalid_startup_parameters_raise(ros: RosSession) -> None:
    from fourbar_ros.config.antenna_config import ConfigError

    with pytest.raises(ConfigError, match=r'^theta_max: .*reach'):
        FourBarNode(context=ros.context, namespace='/bad_start', parameter_overrides=[
            Parameter('theta_max', value=0.9)])
    with pytest.raises(ConfigError, match=r'^load_torque: expected a double'):
        FourBarNode(context=ros.context, namespace='/bad_start', parameter_overrides=[
            Parameter('load_torque', value=3)])


def test_last_pose_is_republished_to_late_subscribers(ros: RosSession, make_rig: Any) -> None:
    """joint_state_rate: a subscriber that arrives after the command still gets the pose, freshly stamped, with
    zero velocities; the counters and the velocity rule do not see the repeats."""
    rig = make_rig(outputs=('input_torque',), joint_state_rate=50.0)  # no joint_states subscriber yet
    theta = 0.02
    rig.send([theta])
    rig.outputs['input_torque'].wait_match(lambda m: bool(m.data == core(rig.cfg, theta).input_torque))
    per_command = ('commands_', 'joint_states_', 'input_torque_')  # the timers' own skip counters tick on

    def command_counters() -> dict[str, int]:
        return {k: v for k, v in rig.node.counters.as_dict().items() if k.startswith(per_command)}

    counters = command_counters()
    computed, reused = rig.node.cache.computed, rig.node.cache.reused
    late = ros.collect(JointState, f'{rig.ns}/joint_states')
    try:
        first, second = late.wait_count(2)[:2]
        s = core(rig.cfg, theta)
        for msg in (first, second):
            assert list(msg.name) == list(rig.cfg.joint_names)
            assert list(msg.position) == [s.gamma, s.delta, s.gamma + theta]  # the same floats (see check_joint_states)
            assert list(msg.effort) == [s.input_torque, 0.0, 0.0]
            assert list(msg.velocity) == [0.0, 0.0, 0.0]  # the antenna is not moving
        stamps = [m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for m in (first, second)]
        assert 0 < stamps[0] < stamps[1]
        assert command_counters() == counters  # not counted as published per command
        assert (rig.node.cache.computed, rig.node.cache.reused) == (computed, reused)
        # No per-command JointState went out before (nobody listened), so the next one has no velocity anchor:
        # an empty velocity. Had a repeat been taken as a sample, it would have one.
        start = len(late)
        rig.send([theta + 0.01])
        answer = late.wait_match(lambda m: list(m.velocity) != [0.0, 0.0, 0.0], start=start)
        assert list(answer.velocity) == []
        assert answer.position[0] == core(rig.cfg, theta + 0.01).gamma
    finally:
        ros.uncollect(late)
