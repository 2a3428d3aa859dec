"""Parameter files shared by a whole robot, and rejections that name the parameters at fault (no ROS)."""

from __future__ import annotations

from pathlib import Path

import pytest
from support.cli_support import fourbar

from fourbar_ros.config.antenna_config import ConfigError, config_from_values, load_config, unknown_in_node_sections

SHARED = '''/**:
  ros__parameters:
    robot_description: "<robot/>"
    use_sim_time: true
    load_torque: 2.0
controller_manager:
  ros__parameters:
    update_rate: 100
fourbar_node:
  ros__parameters:
    theta_mx: 0.1
    out_of_limits: clamp
/robot/fourbar_node:
  ros__parameters:
    gains.p: 3.0
/*/fourbar_node:
  ros__parameters:
    typo_in_ns: 1.0
'''


@pytest.fixture
def shared(tmp_path: Path) -> Path:
    path = tmp_path / 'robot.yaml'
    path.write_text(SHARED, encoding='utf-8')
    return path


def test_other_nodes_parameters_in_a_wildcard_section_are_ignored(shared: Path) -> None:
    cfg = load_config(shared)
    assert cfg.load_torque == 2.0 and cfg.out_of_limits == 'clamp'


def test_unknown_names_in_sections_naming_this_node(shared: Path) -> None:
    # /** is a wildcard (robot_description is another node's); fourbar_node names this node.
    assert unknown_in_node_sections(shared) == ['theta_mx']
    # In /robot, 'fourbar_node' (= /fourbar_node) does not apply, as in rcl.
    assert unknown_in_node_sections(shared, namespace='/robot') == ['gains.p', 'typo_in_ns']
    assert unknown_in_node_sections(shared, node_name='controller_manager') == ['update_rate']


def test_check_and_solve_warn_naming_them(shared: Path) -> None:
    for args in (['check'], ['solve', '--theta', '0.05']):
        out = fourbar(*args, '--params', shared)
        assert out.returncode == 0, out.stderr
        lines = out.stderr.strip().splitlines()
        assert lines == [f'fourbar {args[0]}: warning: {shared}: not fourbar_node parameters, ignored: theta_mx']


@pytest.mark.parametrize(('values', 'changed', 'names'), [
    # A run-time change of theta_max that puts the gamma rocker's dead point inside the range: theta_max is named,
    # not driven_rocker (which did not change).
    ({'theta_max': 0.5}, {'theta_max'}, ('theta_max',)),
    ({'theta_max': 0.5}, None, ('theta_min', 'theta_max', 'driven_rocker')),
    ({'theta_max': 0.5, 'driven_rocker': 'gamma'}, {'driven_rocker'}, ('driven_rocker',)),
    ({'frame_length': 0.22}, {'frame_length'}, ('frame_length',)),           # moves a dead point into the range
    ({'frame_length': 0.22}, None, ('theta_min', 'theta_max', 'driven_rocker')),
    ({'theta_min': 0.2}, {'theta_min'}, ('theta_min',)),
    ({'theta_min': 0.2}, {'theta_min', 'use_sim_time'}, ('theta_min',)),
    ({'gamma_joint': 'rocker_cd_joint'}, {'gamma_joint'}, ('gamma_joint',)),
    ({'gamma_joint': 'rocker_cd_joint'}, None, ('gamma_joint', 'delta_joint')),
    ({'rocker_ab_length': 0.001, 'rocker_cd_length': 0.001}, {'rocker_ab_length', 'rocker_cd_length'},
     ('rocker_ab_length', 'rocker_cd_length')),
])
def test_rejection_names_the_parameters_at_fault(values: dict[str, object], changed: set[str] | None,
                                                 names: tuple[str, ...]) -> None:
    with pytest.raises(ConfigError) as err:
        config_from_values(values, changed=changed)
    assert err.value.names == names
    assert str(err.value).startswith(f"{', '.join(names)}: ") and '\n' not in str(err.value)


def test_single_parameter_rejections_name_it() -> None:
    with pytest.raises(ConfigError) as err:
        config_from_values({'reducer_ratio': 500})
    assert err.value.names == ('reducer_ratio',)
