"""The QoS override parameters the topics reference lists are exactly those rclpy declares on fourbar_node started in
that namespace, and the documented example, on the command line and in a parameter file, changes the command
subscription's depth."""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path

import pytest
from support.paths import REPO
from support.ros_support import RosSession

from fourbar_ros.interface.topics import COMMAND
from fourbar_ros.node.fourbar_node import FourBarNode

pytestmark = pytest.mark.ros

TOPICS_MD = REPO / 'docs' / 'reference' / 'topics.md'
SECTION = re.compile(r'<!-- generated: qos_overrides -->\n(?P<body>.*?)<!-- end generated -->', re.DOTALL)


def _documented() -> tuple[str, set[str]]:
    """(the namespace the table is written for, the parameter names it lists)."""
    text = TOPICS_MD.read_text(encoding='utf-8')
    found = SECTION.search(text)
    assert found, f'{TOPICS_MD}: no generated qos_overrides section'
    body = found.group('body')
    namespace = re.findall(r'a node in `([^`]+)`', body)
    assert len(namespace) == 1, body
    return namespace[0], set(re.findall(r'`(qos_overrides\.[^`]+)`', body))


@pytest.fixture
def started(ros: RosSession) -> Iterator[list[FourBarNode]]:
    nodes: list[FourBarNode] = []
    try:
        yield nodes
    finally:
        for node in nodes:
            node.destroy_node()


def test_the_documented_override_parameters_are_the_ones_rclpy_declares(ros: RosSession,
                                                                        started: list[FourBarNode]) -> None:
    namespace, documented = _documented()
    node = FourBarNode(context=ros.context, namespace=namespace)
    started.append(node)
    declared = {name for name in node._parameters if name.startswith('qos_overrides.')}
    assert declared == documented, (f'declared by rclpy on {node.get_fully_qualified_name()}, not documented: '
                                    f'{sorted(declared - documented)}; documented, not declared: '
                                    f'{sorted(documented - declared)}')


def _command_depth(node: FourBarNode) -> int:
    subs = [s for s in node.subscriptions if s.topic_name == node.resolve_topic_name(COMMAND.name)]
    assert len(subs) == 1, [s.topic_name for s in node.subscriptions]
    return int(subs[0].qos_profile.depth)


def test_the_documented_example_sets_the_command_depth(ros: RosSession, started: list[FourBarNode],
                                                       tmp_path: Path) -> None:
    namespace, _ = _documented()
    name = f'qos_overrides.{namespace}/{COMMAND.name}.subscription.depth'
    text = ' '.join(TOPICS_MD.read_text(encoding='utf-8').split())  # as Markdown joins the lines
    assert f'`-p {name}:=5000`' in text  # the command-line example
    assert f'`qos_overrides:` / `{namespace}/{COMMAND.name}:` / `subscription:` / `depth: 5000`' in text
    params = tmp_path / 'qos.yaml'
    params.write_text(f'/**:\n  ros__parameters:\n    qos_overrides:\n      {namespace}/{COMMAND.name}:\n'
                      '        subscription:\n          depth: 5000\n', encoding='utf-8')
    for args in (['-p', f'{name}:=5000'], ['--params-file', str(params)]):
        node = FourBarNode(context=ros.context, namespace=namespace, cli_args=['--ros-args', *args])
        started.append(node)
        assert (_command_depth(node), node.get_parameter(name).value) == (5000, 5000), args
    default = FourBarNode(context=ros.context, namespace=namespace)
    started.append(default)
    assert _command_depth(default) == COMMAND.depth
