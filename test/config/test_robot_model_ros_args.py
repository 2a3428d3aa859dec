"""The URDF as a command-line parameter value, as the hand bringup passes it to robot_state_publisher
(``--ros-args -p robot_description:="$(fourbar urdf ...)"``): rcl parses such a value as YAML, so the text must come
through as one string holding the same XML. Checked with rcl's own argument parser (rclpy's context), in process.
Skipped where rclpy is not installed."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import pytest

from fourbar_ros.config.antenna_config import config_from_values
from fourbar_ros.config.robot_model import robot_description

rclpy = pytest.importorskip('rclpy', reason='rclpy (ROS 2) is not installed')


def _tree(text: str) -> list[tuple[str, dict[str, str], str]]:
    """Every element in document order: tag, attributes and stripped text (YAML folds the lines of a plain value)."""
    return [(e.tag, dict(e.attrib), ' '.join((e.text or '').split())) for e in ET.fromstring(text).iter()]


@pytest.mark.parametrize('feedforward', [False, True])
def test_the_urdf_is_one_string_parameter_on_the_command_line(feedforward: bool) -> None:
    urdf = robot_description(config_from_values({'effort_feedforward': feedforward}))
    context = rclpy.Context()
    rclpy.init(context=context, args=['--ros-args', '-p', f'robot_description:={urdf}'])
    try:
        node = rclpy.create_node('urdf_parameter_check', context=context,
                                 automatically_declare_parameters_from_overrides=True)
        try:
            value = node.get_parameter('robot_description').value
        finally:
            node.destroy_node()
    finally:
        rclpy.shutdown(context=context)
    assert isinstance(value, str), f'rcl parsed the URDF as {type(value).__name__}: {value!r:.200}'
    assert _tree(value) == _tree(urdf)
