"""The topics fourbar_node creates in each mode are exactly those of ``interface.topics.endpoints`` (the table the
reference docs are generated from): names resolved in the node's namespace, message types, directions, keep-last
depths and reliability. rclpy's own endpoints (``/rosout``, ``/parameter_events``) are left out.

The keys of its diagnostics status, in every mode (and with an antenna sensor), are exactly those the diagnostics
reference lists."""

from __future__ import annotations

import re
from collections.abc import Iterator

import pytest
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, ReliabilityPolicy
from rclpy.serialization import serialize_message
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64
from support.paths import REPO
from support.ros_support import RosSession

from fourbar_ros.config.antenna_config import default_config
from fourbar_ros.interface.topics import DIAGNOSTICS, SENSOR_NONE, Direction, Mode, endpoints
from fourbar_ros.node.controller_watch import activity_type
from fourbar_ros.node.fourbar_node import FourBarNode
from fourbar_ros.rules.diagnostics import Counters, summarize
from fourbar_ros.rules.goal_outcomes import GoalCounters
from fourbar_ros.rules.policy import decide

pytestmark = pytest.mark.ros

RCLPY_OWN = {'/rosout', '/parameter_events'}

#: (resolved name, message type, direction, depth, reliability)
Row = tuple[str, str, Direction, int, str, bool]


def _type_name(msg_type: type) -> str:
    """``std_msgs/msg/Float64`` for std_msgs.msg.Float64 (the interface module's spelling)."""
    package = msg_type.__module__.split('.')[0]
    return f'{package}/msg/{msg_type.__name__}'


#: (mode, antenna_sensor_type): every mode without the optional sensor, and each sensor form in an actuator mode.
CASES = [*((m, SENSOR_NONE) for m in Mode), (Mode.TRAJECTORY, 'float64'), (Mode.FORWARD, 'imu')]


@pytest.fixture(params=CASES, ids=lambda c: f'{c[0].value}-{c[1]}')
def node(request: pytest.FixtureRequest, ros: RosSession) -> Iterator[FourBarNode]:
    mode, sensor = request.param
    created = FourBarNode(context=ros.context, namespace=f'/interface_{mode.value}_{sensor}',
                          parameter_overrides=[Parameter('mode', value=mode.value),
                                               Parameter('antenna_sensor_type', value=sensor)])
    try:
        yield created
    finally:
        created.destroy_node()


def test_the_node_creates_exactly_the_documented_topics(node: FourBarNode) -> None:
    mode = Mode(node.get_parameter('mode').value)
    want: set[Row] = set()
    watched = node.get_parameter('controller_manager').value if activity_type()[0] is not None else ''
    for e in endpoints(mode, antenna_sensor_type=node.get_parameter('antenna_sensor_type').value,
                       controller_manager=watched):
        name = node.resolve_topic_name(e.topic.name)  # in the namespace; `~/` in the node's own
        want.add((name, e.topic.msgtype, e.direction, e.topic.depth, e.topic.reliability.value,
                  e.topic.transient_local))
    got: set[Row] = set()
    for direction, entities in ((Direction.OUT, node.publishers), (Direction.IN, node.subscriptions)):
        for entity in entities:
            if entity.topic_name in RCLPY_OWN:
                continue
            qos = entity.qos_profile
            reliability = 'reliable' if qos.reliability == ReliabilityPolicy.RELIABLE else 'best_effort'
            got.add((entity.topic_name, _type_name(entity.msg_type), direction, qos.depth, reliability,
                     qos.durability == DurabilityPolicy.TRANSIENT_LOCAL))
    assert got == want
    assert any(row[0] == DIAGNOSTICS.name for row in got)  # absolute: not moved by the namespace


def _documented_keys() -> tuple[set[str], tuple[str, ...]]:
    """(keys, prefixes of the ``name_<part>`` patterns) named in the first column of the diagnostics reference's
    key tables."""
    text = (REPO / 'docs' / 'reference' / 'diagnostics.md').read_text(encoding='utf-8')
    keys: set[str] = set()
    prefixes: list[str] = []
    for line in text.splitlines():
        if line.startswith('| `'):
            for key in re.findall(r'`([^`]+)`', line.split('|')[1]):
                if '<' in key:
                    prefixes.append(key[:key.index('<')])
                else:
                    keys.add(key)
    return keys, tuple(prefixes)


def test_the_status_keys_are_exactly_the_documented_ones(ros: RosSession) -> None:
    """In each mode, the keys of a status after a served command (and, in the actuator modes, a measurement) are
    all in the reference; and every key the reference lists is in some mode's status."""
    cfg = default_config()
    theta = 0.05
    decision = decide(theta, cfg.theta_min, cfg.theta_max, cfg.out_of_limits, cfg.linkage.reach())
    served = summarize(cfg, decision, theta, cfg.linkage.state(theta, cfg.load_torque), Counters(), 1, 0)
    gamma, delta = cfg.linkage.rocker_angles(theta, cfg.branch)
    measurement = serialize_message(JointState(name=[cfg.driven_joint],
                                               position=[gamma if cfg.driven_joint == cfg.gamma_joint else delta]))
    documented, prefixes = _documented_keys()
    given: set[str] = {k for k, _ in served.values}  # what only a served command adds (node-independent)
    for mode, sensor in CASES:
        # with a sensor, a calibrated noise: the live check's bias and scatter keys
        node = FourBarNode(context=ros.context, namespace=f'/status_{mode.value}_{sensor}',
                           parameter_overrides=[Parameter('mode', value=mode.value),
                                                Parameter('antenna_sensor_type', value=sensor),
                                                Parameter('antenna_sensor_noise',
                                                          value=0.0 if sensor == SENSOR_NONE else 1e-3)])
        try:
            if node.completion is not None:
                node.completion.on_measurement(measurement)
                node.completion.set_commanded(theta)
            if node.actuation is not None:  # a command's fate
                node.actuation.command(theta)
            if node.model_check is not None:
                node.model_check.on_float64(Float64(data=theta))  # a reading, timed by its arrival
            node.guard.wrap('probe', lambda: 1 / 0)()  # a callback that raises: counted under its name
            keys = {kv.key for kv in node.diagnostic_status().values}
        finally:
            node.destroy_node()
        undocumented = {k for k in keys if k not in documented and not k.startswith(prefixes)}
        assert not undocumented, f'{mode.value}: keys missing from docs/reference/diagnostics.md: {undocumented}'
        given |= keys
    # trajectory_interface action adds its goal counters as they are (control_msgs cannot be imported here; the
    # real controller's tests, test/package/test_real_goals.py, read them from the node's status)
    given |= {k for k, _ in GoalCounters().as_pairs()}
    assert documented <= given, f'documented keys no status has: {documented - given}'
    assert all(any(k.startswith(p) for k in given) for p in prefixes), prefixes
