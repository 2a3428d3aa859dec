"""A run-time change that would alter the robot model (the controller manager's joint limits, robot_state_publisher's
frames) is refused, naming the parameters at fault; every other change passes."""

from __future__ import annotations

import pytest

from fourbar_ros.config.antenna_config import AntennaConfig, config_from_values, default_config
from fourbar_ros.config.params import PARAMETERS
from fourbar_ros.config.rcl_yaml import ConfigError
from fourbar_ros.config.robot_model import check_robot_model_kept

CFG = default_config()
VALUES = CFG.as_values()
#: What the robot model holds, stated apart from the code: the lengths and the pose of the antenna's mount, the
#: branch and the driven rocker (the joints' limits), the tilt range, the speed and effort limits (motor speed over
#: the ratio, the output torque), the names of the joints and the root link, and the hardware component's name.
IN_THE_MODEL = {'rocker_ab_length', 'rocker_cd_length', 'coupler_length', 'frame_length', 'com_offset_along',
                'com_offset_normal', 'branch', 'driven_rocker', 'theta_min', 'theta_max', 'motor_speed_limit',
                'reducer_ratio', 'output_torque_limit', 'gamma_joint', 'delta_joint', 'coupler_joint', 'frame_id',
                'hardware_id'}


def _changed(name: str) -> object:
    """Another valid value of the parameter ``name``."""
    value = VALUES[name]
    spec = next(s for s in PARAMETERS if s.name == name)
    if isinstance(value, bool):
        return not value
    if spec.choices:
        return next(c for c in spec.choices if c != value)
    if isinstance(value, str):
        return value + '_2'
    if isinstance(value, int):
        return value + 1
    assert isinstance(value, float)
    if not value:
        return 0.001
    return value * (0.99 if spec.maximum is not None and value * 1.01 > spec.maximum else 1.01)


def _proposed(**changes: object) -> AntennaConfig:
    return config_from_values({**VALUES, **changes}, list(changes))


@pytest.mark.parametrize('name', [s.name for s in PARAMETERS if not s.read_only])
def test_a_change_is_refused_exactly_where_it_alters_the_robot_model(name: str) -> None:
    proposed = _proposed(**{name: _changed(name)})
    if name in IN_THE_MODEL:
        with pytest.raises(ConfigError) as raised:
            check_robot_model_kept(CFG, proposed, [name])
        assert list(raised.value.names) == [name], raised.value
        assert str(raised.value).startswith(f'{name}: feeds the robot model'), raised.value
        assert '\n' not in str(raised.value)
    else:
        check_robot_model_kept(CFG, proposed, [name])


def test_of_several_changes_only_those_that_alter_the_model_are_named() -> None:
    proposed = _proposed(load_torque=2.0, theta_max=0.1, replan_tolerance=0.01)
    with pytest.raises(ConfigError, match=r'^theta_max: feeds') as raised:
        check_robot_model_kept(CFG, proposed, ['load_torque', 'theta_max', 'replan_tolerance'])
    assert list(raised.value.names) == ['theta_max']


def test_a_range_moved_whole_names_both_ends() -> None:
    # Each end alone would pass the other: theta_min above the running theta_max is no configuration by itself.
    low, high = CFG.theta_max + 0.01, CFG.theta_max + 0.05
    proposed = _proposed(theta_min=low, theta_max=high)
    with pytest.raises(ConfigError, match=r'^theta_min, theta_max: feeds') as raised:
        check_robot_model_kept(CFG, proposed, ['theta_min', 'theta_max'])
    assert list(raised.value.names) == ['theta_min', 'theta_max']


def test_a_value_set_again_unchanged_passes() -> None:
    check_robot_model_kept(CFG, _proposed(theta_max=CFG.theta_max), ['theta_max'])
