"""The topics fourbar_node creates in each mode are exactly those of ``config.interface.endpoints`` (the table the
reference docs are generated from): names resolved in the node's namespace, message types, directions, keep-last
depths and reliability. rclpy's own endpoints (``/rosout``, ``/parameter_events``) are left out."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from rclpy.parameter import Parameter
from rclpy.qos import ReliabilityPolicy
from support.ros_support import RosSession

from fourbar_ros.config.interface import DIAGNOSTICS, Direction, Mode, endpoints
from fourbar_ros.node.fourbar_node import FourBarNode

pytestmark = pytest.mark.ros

RCLPY_OWN = {'/rosout', '/parameter_events'}

#: (resolved name, message type, direction, depth, reliability)
Row = tuple[str, str, Direction, int, str]


def _type_name(msg_type: type) -> str:
    """``std_msgs/msg/Float64`` for std_msgs.msg.Float64 (the interface module's spelling)."""
    package = msg_type.__module__.split('.')[0]
    return f'{package}/msg/{msg_type.__name__}'


@pytest.fixture(params=list(Mode), ids=lambda m: m.value)
def node(request: pytest.FixtureRequest, ros: RosSession) -> Iterator[FourBarNode]:
    mode: Mode = request.param
    created = FourBarNode(context=ros.context, namespace=f'/interface_{mode.value}',
                          parameter_overrides=[Parameter('mode', value=mode.value)])
    try:
        yield created
    finally:
        created.destroy_node()


def test_the_node_creates_exactly_the_documented_topics(node: FourBarNode) -> None:
    mode = Mode(node.get_parameter('mode').value)
    ns = node.get_namespace()
    want: set[Row] = set()
    for e in endpoints(mode):
        name = e.topic.name if e.topic.name.startswith('/') else f'{ns}/{e.topic.name}'
        want.add((name, e.topic.msgtype, e.direction, e.topic.depth, e.topic.reliability.value))
    got: set[Row] = set()
    for direction, entities in ((Direction.OUT, node.publishers), (Direction.IN, node.subscriptions)):
        for entity in entities:
            if entity.topic_name in RCLPY_OWN:
                continue
            qos = entity.qos_profile
            reliability = 'reliable' if qos.reliability == ReliabilityPolicy.RELIABLE else 'best_effort'
            got.add((entity.topic_name, _type_name(entity.msg_type), direction, qos.depth, reliability))
    assert got == want
    assert any(row[0] == DIAGNOSTICS.name for row in got)  # absolute: not moved by the namespace
