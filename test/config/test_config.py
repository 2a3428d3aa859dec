"""load_config / config_from_values: the shipped YAML, every rejection rule, rcl's scalar typing (no ROS)."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from support.paths import REPO

from fourbar_ros.config.antenna_config import (
    AntennaConfig,
    ConfigError,
    config_from_values,
    default_config,
    load_config,
    rcl_scalar,
    values_from_yaml,
)
from fourbar_ros.core.antenna import AntennaLinkage, Branch, Driven
from fourbar_ros.core.errors import FourBarError

YAML = REPO / 'config' / 'antenna.yaml'


def write(tmp_path: Path, body: str, name: str = 'p.yaml') -> Path:
    path = tmp_path / name
    path.write_text(body, encoding='utf-8')
    return path


def params_file(tmp_path: Path, **values: str) -> Path:
    """A /** params file with the given raw YAML scalars."""
    lines = ['/**:', '  ros__parameters:'] + [f'    {k}: {v}' for k, v in values.items()]
    return write(tmp_path, '\n'.join(lines) + '\n')


def test_shipped_yaml_is_turnantenna() -> None:
    cfg = load_config(YAML)
    assert isinstance(cfg, AntennaConfig)
    assert (cfg.frame_length, cfg.rocker_ab_length, cfg.coupler_length, cfg.rocker_cd_length) == (
        0.180, 0.060, 0.102, 0.060)
    assert cfg.linkage == AntennaLinkage(0.180, 0.060, 0.102, 0.060)
    assert math.degrees(cfg.theta_min) == pytest.approx(-6.0, abs=1e-12)
    assert math.degrees(cfg.theta_max) == pytest.approx(7.0, abs=1e-12)
    assert cfg.driven is Driven.GAMMA and cfg.branch is Branch.UPPER
    assert cfg.load_torque == 3.5 and cfg.antenna_mass == 0.0 and not cfg.has_gravity_load
    assert cfg.reducer_ratio == 500.0 and cfg.reducer_efficiency == 1.0
    assert cfg.motor_torque_limit == 0.009 and cfg.output_torque_limit == 5.0
    assert cfg.out_of_limits == 'reject'
    assert cfg.joint_names == ('rocker_ab_joint', 'rocker_cd_joint', 'coupler_joint')


def test_shipped_yaml_equals_parameter_defaults() -> None:
    """One source of defaults: the YAML repeats params.PARAMETERS exactly."""
    assert load_config(YAML) == default_config()


def test_as_values_round_trips() -> None:
    cfg = load_config(YAML)
    assert config_from_values(cfg.as_values()) == cfg


def test_node_name_section_and_later_sections_override(tmp_path: Path) -> None:
    path = write(tmp_path, (
        '/**:\n  ros__parameters:\n    load_torque: 1.0\n    out_of_limits: clamp\n'
        'other_node:\n  ros__parameters:\n    load_torque: 9.0\n'
        '/robot/fourbar_node:\n  ros__parameters:\n    load_torque: 2.0\n'))
    cfg = load_config(path)  # /fourbar_node: the namespaced section does not apply
    assert cfg.load_torque == 1.0 and cfg.out_of_limits == 'clamp'
    in_robot = load_config(path, namespace='/robot')
    assert in_robot.load_torque == 2.0 and in_robot.out_of_limits == 'clamp'
    assert load_config(path, node_name='other_node').load_torque == 9.0


@pytest.mark.parametrize(('key', 'namespace', 'applies'), [
    ('/**', '/', True), ('/**', '/a/b', True), ('fourbar_node', '/', True), ('fourbar_node', '/ns', False),
    ('/fourbar_node', '/', True), ('/ns/fourbar_node', '/ns', True), ('/ns/fourbar_node', '/', False),
    ('/*/fourbar_node', '/ns', True), ('/*/fourbar_node', '/', False), ('/**/fourbar_node', '/a/b', True),
    ('/**/fourbar_node', '/', True), ('/**/other', '/', False),
])
def test_section_keys_follow_rcl(key: str, namespace: str, applies: bool) -> None:
    text = f'{key}:\n  ros__parameters:\n    load_torque: 1.0\n'
    if applies:
        assert values_from_yaml(text, namespace=namespace) == {'load_torque': 1.0}
    else:
        with pytest.raises(ConfigError, match=r'no .* section'):
            values_from_yaml(text, namespace=namespace)


def test_nested_namespace_levels() -> None:
    text = 'ns:\n  fourbar_node:\n    ros__parameters:\n      load_torque: 4.0\n'
    assert values_from_yaml(text, namespace='/ns') == {'load_torque': 4.0}


def test_nested_parameters_flatten_to_dotted_names() -> None:
    values = values_from_yaml('/**:\n  ros__parameters:\n    qos_overrides:\n      /x:\n        depth: 5\n')
    assert values == {'qos_overrides./x.depth': 5}
    config_from_values(values)  # rclpy's own qos_overrides.* are not ours and are ignored


BAD_VALUES = [
    # (parameter, raw YAML scalar, words the one-line message must contain)
    ('reducer_ratio', '500', ['reducer_ratio', 'double', '500.0']),
    ('frame_length', '-0.18', ['frame_length', 'minimum']),
    ('reducer_efficiency', '1.5', ['reducer_efficiency', 'maximum']),
    ('rocker_ab_length', '.nan', ['rocker_ab_length', 'finite']),
    ('load_torque', '.inf', ['load_torque', 'finite']),
    ('theta_max', '0.9', ['theta_max', 'reach']),
    ('theta_min', '0.2', ['theta_min', 'below theta_max']),
    ('driven_rocker', 'beta', ['driven_rocker', 'gamma', 'delta']),
    ('out_of_limits', 'ignore', ['out_of_limits', 'reject', 'clamp']),
    ('branch', "'UPPER'", ['branch', 'upper']),
    ('frame_id', "''", ['frame_id', 'empty']),
    ('frame_id', '7', ['frame_id', 'string', 'integer']),
    ('load_torque', "'3.5'", ['load_torque', 'double', 'string']),
    ('load_torque', 'true', ['load_torque', 'double', 'bool']),
    ('delta_joint', 'rocker_ab_joint', ['delta_joint', 'gamma_joint']),
    ('diagnostics_period', '0.0', ['diagnostics_period', 'minimum']),
]


@pytest.mark.parametrize(('name', 'raw', 'words'), BAD_VALUES)
def test_bad_value_is_one_line_naming_the_parameter(tmp_path: Path, name: str, raw: str,
                                                    words: list[str]) -> None:
    path = params_file(tmp_path, **{name: raw})
    with pytest.raises(ConfigError) as err:
        load_config(path)
    msg = str(err.value)
    assert '\n' not in msg
    assert name in err.value.names
    assert msg.startswith(f"{path}: {', '.join(err.value.names)}: ")
    for word in words:
        assert word in msg
    assert isinstance(err.value, FourBarError) and isinstance(err.value, ValueError)


def test_geometry_that_never_assembles(tmp_path: Path) -> None:
    path = params_file(tmp_path, frame_length='0.5', rocker_ab_length='0.01', rocker_cd_length='0.01')
    with pytest.raises(ConfigError, match=r'frame_length, rocker_ab_length, coupler_length, rocker_cd_length: '
                       r'.*never assembles'):
        load_config(path)


def test_range_across_the_unreachable_gap() -> None:
    # Rockers that differ a lot: reachable only for 79.5 deg <= |theta| <= 92 deg.
    base = dict(frame_length=0.18, rocker_ab_length=0.2, coupler_length=0.102, rocker_cd_length=0.01)
    with pytest.raises(ConfigError, match=r'theta_min: .*out of the linkage reach'):
        config_from_values({**base, 'theta_min': -0.1, 'theta_max': 0.1})
    with pytest.raises(ConfigError, match='unreachable band'):
        config_from_values({**base, 'theta_min': -1.5, 'theta_max': 1.5})
    ok = config_from_values({**base, 'theta_min': 1.46, 'theta_max': 1.6})
    assert ok.linkage.reach().theta_gap > 0


def test_dead_point_inside_the_range_is_rejected_for_that_rocker_only() -> None:
    geometry = dict(frame_length=0.26, rocker_ab_length=0.177, coupler_length=0.178, rocker_cd_length=0.238,
                    theta_min=0.0, theta_max=0.5)
    with pytest.raises(ConfigError, match=r'theta_min, theta_max, driven_rocker: the gamma rocker \(driven_rocker\) '
                       r'has a dead point near theta = 0\.25'):
        config_from_values(geometry)
    # The same range driven from the other rocker has no dead point.
    assert config_from_values({**geometry, 'driven_rocker': 'delta'}).driven is Driven.DELTA
    # Away from the dead point gamma is fine.
    assert config_from_values({**geometry, 'theta_max': 0.2}).driven is Driven.GAMMA


def test_range_edge_tolerance_matches_rclpy() -> None:
    """rclpy accepts a double within rel 1e-6 of a range edge; so does the loader."""
    assert config_from_values({'reducer_efficiency': 1.0 + 5e-7}).reducer_efficiency == 1.0 + 5e-7
    with pytest.raises(ConfigError):
        config_from_values({'reducer_efficiency': 1.0 + 5e-6})


@pytest.mark.parametrize('body', [
    '', 'just a string\n', '- 1\n- 2\n', 'fourbar_node:\n  params: {}\n', 'other:\n  ros__parameters: {a: 1}\n',
    '/**:\n  ros__parameters:\n    load_torque: [1.0\n', '/**:\n  ros__parameters:\n    load_torque:\n',
])
def test_malformed_files(tmp_path: Path, body: str) -> None:
    with pytest.raises(ConfigError) as err:
        load_config(write(tmp_path, body))
    assert '\n' not in str(err.value)


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match='cannot read'):
        load_config(tmp_path / 'missing.yaml')


@pytest.mark.parametrize(('text', 'quoted', 'expected'), [
    ('1', False, 1), ('-0', False, 0), ('010', False, 8), ('0x1F', False, 31), ('+5', False, 5),
    ('1e3', False, 1000.0), ('1.', False, 1.0), ('.5', False, 0.5), ('1.5', False, 1.5),
    ('inf', False, math.inf), ('-.inf', False, -math.inf), ('Infinity', False, math.inf),
    ('0x1p3', False, 8.0), ('yes', False, True), ('Off', False, False), ('y', False, True),
    ('1_000', False, '1_000'), ('~', False, '~'), ('null', False, 'null'), ('1e999', False, '1e999'),
    ('1e-400', False, '1e-400'), ('5e-324', False, '5e-324'), ('1.5\n', False, '1.5\n'),
    ('0.0e-400', False, 0.0), ('abc', False, 'abc'),
    ('1.5', True, '1.5'), ('true', True, 'true'), ('9223372036854775807', False, 9223372036854775807),
    ('9223372036854775808', False, 9.223372036854775808e18),
])
def test_rcl_scalar_typing(text: str, quoted: bool, expected: object) -> None:
    got = rcl_scalar(text, quoted)
    assert type(got) is type(expected)
    assert got == expected


def test_rcl_scalar_nan() -> None:
    for text in ('.nan', '.NaN', 'nan', 'NAN'):
        value = rcl_scalar(text, False)
        assert isinstance(value, float) and math.isnan(value)


def test_exponent_without_dot_is_a_double_as_in_rcl(tmp_path: Path) -> None:
    """PyYAML would read 5e0 as a string; rcl reads a double, and so does the loader."""
    assert load_config(params_file(tmp_path, output_torque_limit='5e0')).output_torque_limit == 5.0
