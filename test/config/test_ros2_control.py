"""What a ros2_control user gets: the URDF's <ros2_control> block and limits, and config/controllers.yaml.

ros2_control cannot be installed here, so nothing below loads them into a controller manager. What is checked:
the XML is well formed; the block names the URDF's driven joint with a position command interface and position,
velocity and effort state interfaces within the URDF's limits; its SimpleTransmission carries the reducer ratio;
the joint limits follow from the reach and the motor; the YAML's controllers, their types, joints, interfaces and
parameter types are those ros2_controllers (Jazzy) declares, and its names are the ones the simulated actuator
and fourbar_node use. What cannot be checked: that the controller manager accepts them at run time.
"""

from __future__ import annotations

import dataclasses
import math
import sys
import xml.etree.ElementTree as ET
from typing import Any

import numpy as np
import pytest
from support.cli_support import fourbar
from support.paths import REPO

from fourbar_ros.config.antenna_config import AntennaConfig, config_from_values, default_config, load_config
from fourbar_ros.config.controllers import forward_controller, trajectory_controller
from fourbar_ros.config.params import PARAMETERS_BY_NAME
from fourbar_ros.config.rcl_yaml import ConfigError, parse, read_text, values_from_yaml
from fourbar_ros.config.robot_model import (
    DEFAULT_HARDWARE_PLUGIN,
    driven_angle,
    joint_limits,
    robot_description,
)
from fourbar_ros.config.sim_actuator_params import sim_settings

CONTROLLERS = REPO / 'config' / 'controllers.yaml'
EPS = sys.float_info.epsilon
CONFIGS = {'gamma driven': default_config(), 'delta driven': config_from_values({'driven_rocker': 'delta'}),
           'renamed': config_from_values({'gamma_joint': 'tilt_motor_joint', 'hardware_id': 'mast<1>',
                                          'driven_joint_offset': -0.0123})}


def block(urdf: str) -> ET.Element:
    blocks = ET.fromstring(urdf).findall('ros2_control')
    assert len(blocks) == 1
    return blocks[0]


def urdf_joints(urdf: str) -> dict[str, ET.Element]:
    return {j.attrib['name']: j for j in ET.fromstring(urdf).findall('joint')}


@pytest.mark.parametrize('cfg', CONFIGS.values(), ids=CONFIGS.keys())
def test_ros2_control_block_is_the_driven_joint_with_the_reducer(cfg: AntennaConfig) -> None:
    urdf = robot_description(cfg)
    rc = block(urdf)
    assert rc.attrib == {'name': cfg.hardware_id, 'type': 'system'}
    assert [p.text for p in rc.findall('hardware/plugin')] == [DEFAULT_HARDWARE_PLUGIN]
    (joint,) = rc.findall('joint')
    name = joint.attrib['name']
    # The same name in the URDF's kinematics, the configuration and the simulated actuator's default.
    assert name == cfg.driven_joint == sim_settings({}, cfg).joint
    assert urdf_joints(urdf)[name].attrib['type'] == 'revolute'
    assert [c.attrib['name'] for c in joint.findall('command_interface')] == ['position']
    assert [s.attrib['name'] for s in joint.findall('state_interface')] == ['position', 'velocity', 'effort']
    limit = urdf_joints(urdf)[name].find('limit')
    assert limit is not None
    params = {p.attrib['name']: float(p.text or '') for p in joint.findall('command_interface/param')}
    assert params == {'min': float(limit.attrib['lower']), 'max': float(limit.attrib['upper'])}
    initial = float(joint.findall("state_interface/param[@name='initial_value']")[0].text or '')
    assert initial == driven_angle(cfg) and params['min'] <= initial <= params['max']
    (trans,) = rc.findall('transmission')
    assert [p.text for p in trans.findall('plugin')] == ['transmission_interface/SimpleTransmission']
    (tj,) = trans.findall('joint')
    assert tj.attrib == {'name': name, 'role': 'joint1'}
    assert float(tj.findtext('mechanical_reduction') or '') == cfg.reducer_ratio
    assert float(tj.findtext('offset') or '') == cfg.driven_joint_offset  # rad
    assert [a.attrib['role'] for a in trans.findall('actuator')] == ['actuator1']


def _offset(urdf: str) -> float:
    (offset,) = block(urdf).findall('transmission/joint/offset')
    return float(offset.text or '')


def _reduction(urdf: str) -> float:
    (reduction,) = block(urdf).findall('transmission/joint/mechanical_reduction')
    return float(reduction.text or '')


def test_the_transmission_offset_is_the_driven_joint_offset_parameter(tmp_path: Any) -> None:
    """ros2_control's SimpleTransmission: joint = actuator / mechanical_reduction + offset (rad)."""
    assert PARAMETERS_BY_NAME['driven_joint_offset'].default == 0.0
    assert _offset(robot_description(default_config())) == 0.0
    params = tmp_path / 'antenna.yaml'
    params.write_text((REPO / 'config' / 'antenna.yaml').read_text(encoding='utf-8').replace(
        'driven_joint_offset: 0.0 ', 'driven_joint_offset: -0.2618', 1), encoding='utf-8')
    cfg = load_config(params)
    assert cfg.driven_joint_offset == -0.2618 and _offset(robot_description(cfg)) == -0.2618
    out = fourbar('urdf', '--params', params)  # what the launch file and `fourbar urdf` give robot_state_publisher
    assert out.returncode == 0, out.stderr
    assert _offset(out.stdout) == -0.2618
    # Beyond pi (a multi-turn absolute encoder: the motor's zero many turns away) and with a reversed motor
    # (negative reduction): SimpleTransmission takes both (it refuses a reduction of 0 only).
    turned = config_from_values({'driven_joint_offset': 4.0 * math.pi + 0.25, 'reducer_ratio': -500.0})
    assert _offset(robot_description(turned)) == 4.0 * math.pi + 0.25
    assert _reduction(robot_description(turned)) == -500.0
    with pytest.raises(ConfigError, match='reducer_ratio'):
        config_from_values({'reducer_ratio': 0.0})


def hardware_params(urdf: str) -> dict[str, str]:
    """The ``<param>`` entries of the ``<hardware>`` block, name -> text."""
    return {p.attrib['name']: p.text or '' for p in block(urdf).findall('hardware/param')}


def test_hardware_parameters_reach_the_hardware_block(tmp_path: Any) -> None:
    assert hardware_params(robot_description(default_config())) == {}
    params = tmp_path / 'antenna.yaml'
    params.write_text((REPO / 'config' / 'antenna.yaml').read_text(encoding='utf-8').replace(
        'hardware_parameters: []', "hardware_parameters: ['port=/dev/ttyUSB0', 'baud_rate=115200', 'note=a<b&c=d']",
        1), encoding='utf-8')
    out = fourbar('urdf', '--params', params)  # what the launch file and `fourbar urdf` give robot_state_publisher
    assert out.returncode == 0, out.stderr
    # The value is everything after the first '=', escaped for XML and read back as written.
    assert hardware_params(out.stdout) == {'port': '/dev/ttyUSB0', 'baud_rate': '115200', 'note': 'a<b&c=d'}
    assert [p.text for p in block(out.stdout).findall('hardware/plugin')] == ['mock_components/GenericSystem']
    for bad, why in ((['port'], 'not name=value'), (['a=1', 'a=2'], 'given twice'), (['a b=1'], 'not name=value')):
        with pytest.raises(ConfigError, match=f'hardware_parameters: .*{why}'):
            config_from_values({'hardware_parameters': bad})
    # rcl reads `[]` in a parameter file as a parameter not set: the node's startup value is then None.
    assert config_from_values({'hardware_parameters': None}).hardware_parameters == ()


@pytest.mark.parametrize('ratio', [500.0, -500.0, 37.5])
def test_the_models_limits_are_the_planners(ratio: float) -> None:
    # The driven joint's URDF limits and its command interface's min/max, which the controller manager enforces
    # (enforce_command_limits), against what the node plans with: the same parameters through the planner's own
    # code (JointLimits for speed and torque, driven_range for the range).
    from fourbar_ros.motion.limits import JointLimits
    from fourbar_ros.rules.motion_plan import driven_range

    cfg = config_from_values({'reducer_ratio': ratio, 'motor_speed_limit': 12.5, 'output_torque_limit': 4.25})
    planner = JointLimits.from_config(cfg)
    urdf = robot_description(cfg)
    el = urdf_joints(urdf)[cfg.driven_joint].find('limit')
    assert el is not None
    lower, upper, effort, velocity = (float(el.attrib[k]) for k in ('lower', 'upper', 'effort', 'velocity'))
    assert velocity == planner.at_rocker(1) == 12.5 / abs(ratio), (velocity, planner.at_rocker(1))
    assert effort == planner.output_torque == 4.25
    # The model solves the ends one angle at a time, the planner both at once: the same double up to the last
    # bits of the solve (a few ulps at 1 rad).
    assert (lower, upper) == pytest.approx(driven_range(cfg), abs=8 * EPS), (lower, upper, driven_range(cfg))
    command = {p.attrib['name']: float(p.text or '') for p in block(urdf).findall('joint/command_interface/param')}
    assert command == {'min': lower, 'max': upper}


def test_hardware_plugin_is_replaced_and_escaped() -> None:
    rc = block(robot_description(default_config(), hardware_plugin='my_drive/Stepper<&>'))
    assert [p.text for p in rc.findall('hardware/plugin')] == ['my_drive/Stepper<&>']


@pytest.mark.parametrize('cfg', CONFIGS.values(), ids=CONFIGS.keys())
def test_joint_limits_follow_from_the_reach_and_the_motor(cfg: AntennaConfig) -> None:
    cfg = dataclasses.replace(cfg, motor_speed_limit=2.5 * cfg.motor_speed_limit)
    speed = cfg.motor_speed_limit
    limits = joint_limits(cfg)
    urdf = urdf_joints(robot_description(cfg))
    for name, lim in limits.items():
        el = urdf[name].find('limit')
        assert el is not None
        assert [float(el.attrib[k]) for k in ('lower', 'upper', 'effort', 'velocity')] == list(lim)
    driven = limits[cfg.driven_joint]
    assert driven.velocity == speed / cfg.reducer_ratio and driven.effort == cfg.output_torque_limit
    # Independent of the generator: finite differences over a finer sweep of the tilt range. Every joint stays in
    # its range, and no joint moves faster than its limit while the driven one moves at its own.
    theta = np.linspace(cfg.theta_min, cfg.theta_max, 4001)
    g, d = (np.asarray(a, dtype=np.float64) for a in cfg.linkage.rocker_angles(theta, cfg.branch))
    paths = {cfg.gamma_joint: g, cfg.delta_joint: d, cfg.coupler_joint: g + theta}
    q = paths[cfg.driven_joint]
    for name, path in paths.items():
        lim = limits[name]
        # Sampled extremes: the generator's coarser samples include both ends, where these monotonic paths peak.
        assert lim.lower == pytest.approx(path.min(), abs=64 * EPS)
        assert lim.upper == pytest.approx(path.max(), abs=64 * EPS)
        ratio = np.abs(np.diff(path) / np.diff(q))
        # Chord slopes of a smooth path lie within its tangent slopes, and the tangent slope the generator samples
        # peaks at an end of the range (within the chord's first-order error, h^2 scale).
        assert driven.velocity * ratio.max() <= lim.velocity * (1 + 1e-5), name
        assert driven.velocity * ratio.max() >= lim.velocity * (1 - 1e-3), name
        if name != cfg.driven_joint:
            assert lim.effort == 0.0


# ----------------------------------------------------------------------------- controllers.yaml

#: Controller types this file may use and the parameters each declares in ros2_controllers (Jazzy), as far as
#: this file sets them: a key outside these sets is a typo the controller would ignore or refuse.
TYPES = {
    'joint_state_broadcaster/JointStateBroadcaster':
        {'joints', 'interfaces', 'use_local_topics', 'map_interface_to_joint_state', 'extra_joints',
         'use_urdf_to_filter'},
    'joint_trajectory_controller/JointTrajectoryController':
        {'joints', 'command_joints', 'command_interfaces', 'state_interfaces', 'allow_partial_joints_goal',
         'interpolate_from_desired_state', 'allow_integration_in_goal_trajectories', 'action_monitor_rate',
         'interpolation_method', 'allow_nonzero_velocity_at_trajectory_end', 'cmd_timeout', 'gains', 'constraints',
         'set_last_command_interface_value_as_state_on_activation'},
    'position_controllers/JointGroupPositionController': {'joints'},
}
INTERFACES = {'position', 'velocity', 'acceleration', 'effort'}
#: Keys the file must not set: ``open_loop_control`` is deprecated since joint_trajectory_controller 4.22, and
#: ``constraints.stopped_velocity_tolerance`` has no effect with a position-only command interface.
DEPRECATED = {'open_loop_control'}


#: The namespaces the file is checked in: the launch file's default (none) and the README's.
NAMESPACES = ('/', '/tilt')


def _nested(flat: dict[str, object]) -> dict[str, Any]:
    """rcl's dotted parameter names (``constraints.goal_time``) as the nested mappings the YAML writes."""
    out: dict[str, Any] = {}
    for name, value in flat.items():
        *parents, leaf = name.split('.')
        level = out
        for p in parents:
            level = level.setdefault(p, {})
        level[leaf] = value
    return out


def params_of(controller: str, namespace: str = '/') -> dict[str, Any]:
    """What the node ``namespace``/``controller`` receives from the file by rcl's rules (a controller runs in its
    controller manager's namespace)."""
    return _nested(values_from_yaml(read_text(CONTROLLERS), str(CONTROLLERS), controller, namespace))


def test_controller_manager_section() -> None:
    cm = params_of('controller_manager')
    assert type(cm['update_rate']) is int and cm['update_rate'] > 0  # an integer parameter: 100.0 is refused
    declared = {name: entry['type'] for name, entry in cm.items() if isinstance(entry, dict)}
    assert set(declared.values()) <= set(TYPES)
    # The names the simulated actuator (and so fourbar_node's actuator modes) address.
    assert declared['joint_trajectory_controller'] == 'joint_trajectory_controller/JointTrajectoryController'
    assert declared['forward_position_controller'] == 'position_controllers/JointGroupPositionController'
    assert declared['joint_state_broadcaster'] == 'joint_state_broadcaster/JointStateBroadcaster'
    assert PARAMETERS_BY_NAME['trajectory_controller'].default == 'joint_trajectory_controller'
    assert PARAMETERS_BY_NAME['forward_controller'].default == 'forward_position_controller'
    # Every controller configured, nothing else.
    sections = set(parse(read_text(CONTROLLERS), str(CONTROLLERS)))
    assert sections == {f'/**/{name}' for name in ('controller_manager', *declared)}
    for name, kind in declared.items():
        assert set(params_of(name)) <= TYPES[kind], name


def test_controllers_drive_the_urdf_joint_through_its_interfaces() -> None:
    cfg = default_config()
    rc = block(robot_description(cfg))
    (joint,) = rc.findall('joint')
    commands = {c.attrib['name'] for c in joint.findall('command_interface')}
    states = {s.attrib['name'] for s in joint.findall('state_interface')}
    for name in ('joint_state_broadcaster', 'joint_trajectory_controller', 'forward_position_controller'):
        assert params_of(name)['joints'] == [cfg.driven_joint] == [joint.attrib['name']], name
    jsb = params_of('joint_state_broadcaster')
    assert set(jsb['interfaces']) <= states
    jtc = params_of('joint_trajectory_controller')
    assert set(jtc['command_interfaces']) <= commands & INTERFACES
    assert set(jtc['state_interfaces']) <= states & INTERFACES
    assert jtc['state_interfaces'][0] == 'position'  # the controller needs the position state first
    for key in ('allow_partial_joints_goal', 'allow_nonzero_velocity_at_trajectory_end',
                'interpolate_from_desired_state'):
        assert jtc[key] is False, key  # one joint; trajectories end at rest; start from the measured state
    assert not set(jtc) & DEPRECATED
    assert jtc['interpolation_method'] in ('splines', 'none')
    constraints = jtc['constraints']
    assert type(constraints['goal_time']) is float and constraints['goal_time'] >= 0.0
    tolerances = constraints[cfg.driven_joint]
    assert set(tolerances) <= {'trajectory', 'goal'}
    assert all(type(v) is float and math.isfinite(v) and v >= 0.0 for v in tolerances.values())
    assert set(constraints) == {'goal_time', cfg.driven_joint}  # stopped_velocity_tolerance: no effect here
    # joint_state_broadcaster publishes on its local topic, where fourbar_node's measured_joint_states is remapped.
    assert jsb['use_local_topics'] is True


def test_effort_feedforward_adds_the_effort_command_interface() -> None:
    cfg = config_from_values({'effort_feedforward': True})
    (joint,) = block(robot_description(cfg)).findall('joint')
    assert [c.attrib['name'] for c in joint.findall('command_interface')] == ['position', 'effort']
    (plain,) = block(robot_description(default_config())).findall('joint')
    assert [c.attrib['name'] for c in plain.findall('command_interface')] == ['position']


@pytest.mark.parametrize('namespace', NAMESPACES)
def test_the_file_applies_in_any_namespace_by_rcls_rules(namespace: str) -> None:
    """With ``namespace:=tilt`` the launch file starts /tilt/controller_manager, which starts its controllers as
    /tilt/<name> with the same parameter file: each gets its section, as in the root namespace."""
    prefix = namespace.rstrip('/')
    cm = values_from_yaml(read_text(CONTROLLERS), str(CONTROLLERS), 'controller_manager', namespace)
    assert cm['update_rate'] == 100  # Hz
    assert {k: v for k, v in cm.items() if k.endswith('.type')} == {
        'joint_state_broadcaster.type': 'joint_state_broadcaster/JointStateBroadcaster',
        'joint_trajectory_controller.type': 'joint_trajectory_controller/JointTrajectoryController',
        'forward_position_controller.type': 'position_controllers/JointGroupPositionController'}
    joint = default_config().driven_joint
    jtc = values_from_yaml(read_text(CONTROLLERS), str(CONTROLLERS), 'joint_trajectory_controller', namespace)
    assert jtc['joints'] == [joint] and jtc['command_interfaces'] == ['position']
    assert jtc['constraints.goal_time'] == 0.5 and jtc[f'constraints.{joint}.goal'] == 0.001  # s, rad
    for name in ('joint_state_broadcaster', 'forward_position_controller'):
        assert params_of(name, namespace)['joints'] == [joint], f'{prefix}/{name}'
    # What fourbar_node reads for the controller it sends to, in the same namespace.
    settings = trajectory_controller('', 'joint_trajectory_controller', namespace)
    assert settings.joints == (joint,) and settings.goal_time == 0.5
    assert settings == trajectory_controller('', 'joint_trajectory_controller')
    assert forward_controller('', 'forward_position_controller', namespace).joints == (joint,)


def test_a_plain_section_key_does_not_apply_in_a_namespace(tmp_path: Any) -> None:
    # Why the shipped file writes /**/: rcl reads `jtc:` as /jtc, which a controller in /tilt does not receive.
    path = tmp_path / 'plain.yaml'
    path.write_text('jtc:\n  ros__parameters:\n    joints: [j]\n    command_interfaces: [position]\n'
                    '    state_interfaces: [position]\n'
                    '    set_last_command_interface_value_as_state_on_activation: false\n', encoding='utf-8')
    assert trajectory_controller(str(path), 'jtc').joints == ('j',)
    with pytest.raises(ConfigError, match="no '/\\*\\*:' or '/tilt/jtc' section"):
        trajectory_controller(str(path), 'jtc', '/tilt')


def test_the_path_tolerance_trips_above_the_nodes_replan_tolerance() -> None:
    # A drive the controller holds on its path tolerance is then that far off the node's motion: the node's next
    # command must see it (more than replan_tolerance off) and plan from the measured state, or the controller would
    # get a trajectory starting up to the path tolerance away from the drive (a step). Both as shipped.
    path = trajectory_controller('', 'joint_trajectory_controller').tolerance(default_config().driven_joint)
    replan = load_config(REPO / 'config' / 'antenna.yaml').replan_tolerance
    assert replan < path.trajectory <= math.radians(1.0), (replan, path)
    assert 0.0 < path.goal < path.trajectory, path
