"""The YAML loader against rcl itself: the values an rclpy node receives from a params file, and the verdict.

rcl's C parser (through rclpy) is the reference for scalar typing and section matching; ``load_config`` must
accept exactly the files ``fourbar_node`` accepts, with the same one-line reason.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pytest
from rclpy.node import Node
from support.ros_support import RosSession

from fourbar_ros.config.antenna_config import ConfigError, load_config, values_from_yaml
from fourbar_ros.node.fourbar_node import FourBarNode

pytestmark = pytest.mark.ros


def rcl_values(ros: RosSession, path: Path, namespace: str) -> dict[str, Any]:
    node = Node('fourbar_node', namespace=namespace, context=ros.context, start_parameter_services=False,
                cli_args=['--ros-args', '--params-file', str(path)])
    try:
        return {name: p.value for name, p in node._parameter_overrides.items()}
    finally:
        node.destroy_node()


def same(a: object, b: object) -> bool:
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return type(a) is type(b) and a == b


SCALARS = ['1', '-7', '010', '0x1F', '+5', '1e3', '2.5e+0', '1.', '.5', '1.5', '-0.0', 'inf', '-.inf', '.INF',
           'Infinity', 'nan', '.nan', '0x1p3', '1e999', '1e-400', '5e-324', '2.2250738585072014e-308',
           '1_000', '~', 'null', 'yes', 'No', 'on', 'y', 'true', "'1.5'", '"2"', 'abc', '9223372036854775807',
           '9223372036854775808', '-9223372036854775809', '|\n      1.5', '1.5 # comment',
           '0x1p99999', '1' * 30, '0' * 30 + '17', '1' * 400, '-' + '9' * 5000, '0x' + 'f' * 20, '&anchor 2.5']


def test_scalar_typing_matches_rcl(ros: RosSession, tmp_path: Path) -> None:
    lines = ['/**:', '  ros__parameters:'] + [f'    p{i}: {text}' for i, text in enumerate(SCALARS)]
    path = tmp_path / 'scalars.yaml'
    path.write_text('\n'.join(lines) + '\n', encoding='utf-8')
    ours = values_from_yaml(path.read_text(encoding='utf-8'))
    theirs = rcl_values(ros, path, '/')
    assert set(ours) == set(theirs)
    mismatches = {SCALARS[int(k[1:])]: (ours[k], theirs[k]) for k in ours if not same(ours[k], theirs[k])}
    assert mismatches == {}


SECTIONS = [
    ('/**', '/'), ('/**', '/a/b'), ('fourbar_node', '/'), ('fourbar_node', '/ns'), ('/fourbar_node', '/'),
    ('/ns/fourbar_node', '/ns'), ('/ns/fourbar_node', '/'), ('/*/fourbar_node', '/ns'), ('/*/fourbar_node', '/'),
    ('/**/fourbar_node', '/a/b'), ('/**/fourbar_node', '/'), ('other_node', '/'),
]


@pytest.mark.parametrize(('key', 'namespace'), SECTIONS)
def test_section_matching_matches_rcl(ros: RosSession, tmp_path: Path, key: str, namespace: str) -> None:
    path = tmp_path / 'p.yaml'
    path.write_text(f'{key}:\n  ros__parameters:\n    load_torque: 1.5\n', encoding='utf-8')
    theirs = rcl_values(ros, path, namespace)
    try:
        ours = values_from_yaml(path.read_text(encoding='utf-8'), namespace=namespace)
    except ConfigError:
        ours = {}
    assert ours == theirs


def test_file_order_and_nesting_match_rcl(ros: RosSession, tmp_path: Path) -> None:
    text = ('fourbar_node:\n  ros__parameters:\n    a: 1\n    b: 1\n'
            '/**:\n  ros__parameters:\n    a: 2\n'
            'ns:\n  fourbar_node:\n    ros__parameters:\n      b: 3\n')
    path = tmp_path / 'order.yaml'
    path.write_text(text, encoding='utf-8')
    for namespace in ('/', '/ns'):
        assert values_from_yaml(text, namespace=namespace) == rcl_values(ros, path, namespace)


VERDICT_CASES = [
    'load_torque: 3.5',
    'load_torque: 3',                          # integer for a double
    'load_torque: 35e-1',                      # rcl reads a double
    'load_torque: "3.5"',                      # a string
    'theta_max: 0.9',                          # out of reach
    'theta_max: 0.12217304763960307\n    theta_min: 0.2',
    'reducer_efficiency: 1.0000005',           # inside rclpy's edge tolerance
    'reducer_efficiency: 1.1',
    'out_of_limits: clamp',
    'out_of_limits: Clamp',
    'frame_id: ""',
    'rocker_cd_length: .nan',
    'gamma_joint: rocker_cd_joint',
    'coupler_length: 0.5',
    'thta_max: 0.1',                           # unknown (typo)
    'use_sim_time: true',                      # rclpy's own
    'driven_rocker: delta',
]


@pytest.mark.parametrize('body', VERDICT_CASES)
def test_node_and_loader_agree(ros: RosSession, tmp_path: Path, body: str) -> None:
    path = tmp_path / 'verdict.yaml'
    path.write_text(f'/**:\n  ros__parameters:\n    {body}\n', encoding='utf-8')
    try:
        load_config(path)
        loader_error = None
    except ConfigError as exc:
        loader_error = str(exc)
    try:
        node = FourBarNode(context=ros.context, namespace='/verdict',
                           cli_args=['--ros-args', '--params-file', str(path)])
    except ConfigError as exc:
        assert loader_error == f'{path}: {exc}'
    else:
        node.destroy_node()
        assert loader_error is None


def test_alias_refused_by_rcl_and_the_loader(ros: RosSession, tmp_path: Path) -> None:
    path = tmp_path / 'alias.yaml'
    path.write_text('/**:\n  ros__parameters:\n    load_torque: &x 1.5\n    antenna_mass: *x\n', encoding='utf-8')
    with pytest.raises(Exception, match='aliasing'):  # rclpy's RCLError: "Will not support aliasing at line 4"
        rcl_values(ros, path, '/')
    with pytest.raises(ConfigError, match=r'line 4: YAML aliases'):
        load_config(path)
