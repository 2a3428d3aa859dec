"""The parameter spec: one source for the node's declarations, the loader, the YAML and the docs."""

from __future__ import annotations

import math
import re

import pytest
from support.paths import REPO

from fourbar_ros.config.antenna_config import ConfigError, check_value, default_config, values_from_yaml
from fourbar_ros.config.params import PARAMETERS, PARAMETERS_BY_NAME, ParamSpec, defaults, is_foreign


def test_names_unique_and_valid() -> None:
    names = [p.name for p in PARAMETERS]
    assert len(names) == len(set(names)) == len(PARAMETERS_BY_NAME)
    for name in names:
        assert re.fullmatch(r'[a-z][a-z0-9_]*', name), name


@pytest.mark.parametrize('spec', PARAMETERS, ids=lambda p: p.name)
def test_each_default_passes_its_own_check(spec: ParamSpec) -> None:
    assert check_value(spec, spec.default) == spec.default
    assert isinstance(spec.default, spec.type)
    assert spec.description.strip()


@pytest.mark.parametrize('spec', [p for p in PARAMETERS if p.type is float], ids=lambda p: p.name)
def test_doubles_are_bounded_and_reject_outside(spec: ParamSpec) -> None:
    assert spec.minimum is not None and spec.maximum is not None and spec.minimum < spec.maximum
    assert spec.minimum <= spec.default <= spec.maximum
    for bad in (spec.minimum - 1.0 - abs(spec.minimum), spec.maximum + 1.0 + abs(spec.maximum), math.nan):
        with pytest.raises(ConfigError, match=f'^{spec.name}: '):
            check_value(spec, bad)


@pytest.mark.parametrize('spec', [p for p in PARAMETERS if p.choices], ids=lambda p: p.name)
def test_enumerations(spec: ParamSpec) -> None:
    assert spec.default in spec.choices
    for choice in spec.choices:
        assert check_value(spec, choice) == choice
    with pytest.raises(ConfigError, match=f'^{spec.name}: '):
        check_value(spec, 'no-such-choice')


def test_units_are_stated_for_physical_quantities() -> None:
    units = {p.name: p.unit for p in PARAMETERS}
    for name in ('frame_length', 'rocker_ab_length', 'coupler_length', 'rocker_cd_length', 'com_offset_along',
                 'com_offset_normal'):
        assert units[name] == 'm'
    for name in ('theta_min', 'theta_max', 'transmission_angle_min'):
        assert units[name] == 'rad'
    for name in ('load_torque', 'motor_torque_limit', 'output_torque_limit'):
        assert units[name] == 'N m'
    assert units['antenna_mass'] == 'kg'
    for p in PARAMETERS:
        assert (f'[{p.unit}]' in p.describe()) == bool(p.unit)


def test_shipped_yaml_sets_every_parameter() -> None:
    values = values_from_yaml((REPO / 'config' / 'antenna.yaml').read_text(encoding='utf-8'))
    assert set(values) == set(PARAMETERS_BY_NAME)
    assert values == defaults()


def test_defaults_build_the_default_config() -> None:
    assert default_config().as_values() == defaults()


def test_foreign_parameters() -> None:
    assert is_foreign('use_sim_time') and is_foreign('qos_overrides./joint_states.publisher.depth')
    assert not any(is_foreign(p.name) for p in PARAMETERS)


def test_docs_table_lists_every_parameter() -> None:
    doc = (REPO / 'docs' / 'reference' / 'parameters.md').read_text(encoding='utf-8')
    for p in PARAMETERS:
        assert f'| `{p.name}` |' in doc, p.name


def test_configuration_fields_are_the_parameter_table() -> None:
    """AntennaConfig declares one field per PARAMETERS entry (its ``attribute``) and nothing else but the linkage,
    so a parameter added to the table without a field, or a field without a parameter, fails here."""
    import dataclasses

    from fourbar_ros.config.antenna_config import AntennaConfig

    fields = [f.name for f in dataclasses.fields(AntennaConfig) if f.name != 'linkage']
    assert fields == [spec.attribute for spec in PARAMETERS]


def test_values_round_trip_through_the_configuration() -> None:
    """config_from_values and as_values are inverses over the whole table (defaults and the non-default choices)."""
    from fourbar_ros.config.antenna_config import config_from_values, default_config

    values = default_config().as_values()
    assert values == {spec.name: spec.default for spec in PARAMETERS}
    changed = dict(values, driven_rocker='delta', branch='upper', out_of_limits='clamp', coupler_joint='c')
    assert config_from_values(changed).as_values() == changed


@pytest.mark.parametrize('spec', [p for p in PARAMETERS if p.type is int], ids=lambda p: p.name)
def test_integers_are_bounded_and_reject_outside_and_doubles(spec: ParamSpec) -> None:
    assert spec.minimum is not None and spec.maximum is not None and spec.minimum <= spec.default <= spec.maximum
    for bad in (int(spec.minimum) - 1, int(spec.maximum) + 1, float(spec.default), True):
        with pytest.raises(ConfigError, match=f'^{spec.name}: '):
            check_value(spec, bad)
