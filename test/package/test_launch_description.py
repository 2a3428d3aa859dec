"""launch/fourbar.launch.py evaluated in-process: the nodes it starts for each combination of arguments, their
packages, executables, parameters, remappings and the spawners' arguments, the mock hardware announced, and the
combinations and the undeclared arguments it refuses. Where ros2_control or robot_state_publisher is not installed
(here), the launch file's check for them is replaced, so what it would start with them is checked too; that the
processes run is test/package/test_launch.py's (through ``ros2 launch``).
"""

from __future__ import annotations

import importlib.util
import xml.etree.ElementTree as ET
from collections.abc import Callable
from types import ModuleType
from typing import Any

import pytest
import yaml
from support.colcon_support import launch_missing
from support.paths import REPO
from support.policy_rules import enclaves

if (_why := launch_missing()) is not None:
    pytest.skip(_why, allow_module_level=True)

from launch.actions import DeclareLaunchArgument, LogInfo, OpaqueFunction, RegisterEventHandler
from launch.event_handlers import OnProcessIO
from launch.events.process import ProcessIO
from launch.utilities import perform_substitutions
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterFile

from fourbar_ros.config.launch_arguments import UnknownLaunchArgumentError
from fourbar_ros.config.security import BRINGUP_ENCLAVES, POLICY_FILE, enclave
from fourbar_ros.drive.rules import activated_line
from fourbar_ros.interface.topics import BROADCASTER_JOINT_STATES, MEASURED_JOINT_STATES, NODE_NAME, Mode
from launch import LaunchContext

LAUNCH_FILE = REPO / 'launch' / 'fourbar.launch.py'
CONTROLLERS = REPO / 'config' / 'controllers.yaml'


def load_launch_file() -> ModuleType:
    spec = importlib.util.spec_from_file_location('fourbar_launch', LAUNCH_FILE)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


class Started:
    """What the launch file starts for some arguments: its Node actions as plain values, and its log lines."""

    def __init__(self, installed: Callable[[str, str], bool], **arguments: str) -> None:
        module = load_launch_file()
        module._installed_executable = installed
        description = module.generate_launch_description()
        # As `ros2 launch ... name:=value` runs it: the pairs are the context's argv and launch configurations before
        # the file's first entity (the check of the arguments), the declared defaults fill in the rest.
        self.context = LaunchContext(argv=[f'{name}:={value}' for name, value in arguments.items()])
        self.context.launch_configurations.update(arguments)
        check, setup = [e for e in description.entities if isinstance(e, OpaqueFunction)]
        assert description.entities[0] is check and check.execute(self.context) == []
        for entity in description.entities:
            if isinstance(entity, DeclareLaunchArgument) and entity.name not in arguments:
                default = entity.default_value
                self.context.launch_configurations[entity.name] = (
                    perform_substitutions(self.context, default) if default else '')
        actions = setup.execute(self.context) or []
        # What starts once another process has (the spawners, at each start of the controller manager, or on the
        # drive bridge's activation line): as the handler would start it the first time.
        self.handlers = [r.event_handler for r in actions if isinstance(r, RegisterEventHandler)]
        actions += [a for h in self.handlers for a in h.handle(self._event(h), self.context) or []]
        self.nodes = [a for a in actions if isinstance(a, Node)]
        self.logs = [self.text(a.msg) for a in actions if isinstance(a, LogInfo)]

    @staticmethod
    def _event(handler: Any) -> Any:
        """The event ``handler`` waits for: None for a process start, else the bridge's activation line."""
        if not isinstance(handler, OnProcessIO):
            return None
        line = f'[INFO] [0.0] [fourbar_drive_bridge]: {activated_line("c", "j", 0.0)}\n'.encode()
        return ProcessIO(text=line, fd=2, action=None, name='bridge', cmd=[], cwd=None, env=None, pid=0)

    def text(self, subs: Any) -> str:
        return subs if isinstance(subs, str) else perform_substitutions(self.context, list(subs))

    def value(self, v: Any) -> Any:
        """A parameter value as the node receives it (launch_ros passes a string as YAML text)."""
        if isinstance(v, (tuple, list)) and v and isinstance(v[0], (tuple, list)):  # a list of strings
            return [yaml.safe_load(self.text(item)) for item in v]
        if isinstance(v, (tuple, list)) and v and not isinstance(v[0], (bool, int, float, str)):
            return yaml.safe_load(self.text(v))
        return v

    def node(self, package: str, executable: str) -> list[Node]:
        return [n for n in self.nodes if n.node_package == package and n.node_executable == executable]

    def one(self, package: str, executable: str) -> Node:
        (found,) = self.node(package, executable)
        return found

    def remappings(self, node: Node) -> list[tuple[str, str]]:
        return [(self.text(a), self.text(b)) for a, b in node._Node__remappings or []]

    def parameters(self, node: Node) -> tuple[list[str], dict[str, Any]]:
        """(parameter files, the merged dict entries)."""
        files, values = [], {}
        for p in node._Node__parameters or []:
            if isinstance(p, ParameterFile):
                files.append(self.text(p.param_file))
            else:
                values.update({self.text(k): self.value(v) for k, v in p.items()})
        return files, values

    def arguments(self, node: Node) -> list[str]:
        return [self.text(a) for a in node._Node__arguments or []]


def everything(package: str, executable: str) -> bool:
    return True


def nothing_but_ours(package: str, executable: str) -> bool:
    return package == 'fourbar_ros'


MEASURED_REMAP = (MEASURED_JOINT_STATES.name, BROADCASTER_JOINT_STATES.name)


def test_open_loop_by_default_with_no_remapping() -> None:
    s = Started(everything)
    node = s.one('fourbar_ros', 'fourbar_node')
    files, values = s.parameters(node)
    assert files == [str(REPO / 'config' / 'antenna.yaml')] and values['mode'] == 'open_loop'
    assert s.remappings(node) == [] and 'controllers_file' not in values
    assert s.node('controller_manager', 'ros2_control_node') == []
    assert s.node('fourbar_ros', 'fourbar_sim_actuator') == []
    assert len(s.node('robot_state_publisher', 'robot_state_publisher')) == 1


def test_the_simulated_actuator_and_the_node_meet_on_the_broadcasters_topic() -> None:
    s = Started(everything, sim_actuator='true', mode='trajectory')
    node, sim = s.one('fourbar_ros', 'fourbar_node'), s.one('fourbar_ros', 'fourbar_sim_actuator')
    assert s.remappings(node) == [MEASURED_REMAP]
    assert s.remappings(sim) == []  # it publishes there itself
    _, node_values = s.parameters(node)
    _, sim_values = s.parameters(sim)
    assert node_values['mode'] == 'trajectory' and node_values['controllers_file'] == sim_values['controllers_file']
    assert node_values['effort_feedforward'] is False


def test_the_ros2_control_bringup() -> None:
    s = Started(everything, use_ros2_control='true', namespace='tilt')
    node = s.one('fourbar_ros', 'fourbar_node')
    assert s.parameters(node)[1]['mode'] == 'trajectory'  # the default actuator mode with ros2_control
    assert s.remappings(node) == [MEASURED_REMAP]
    assert s.parameters(node)[1]['controllers_file'] == str(CONTROLLERS)
    manager = s.one('controller_manager', 'ros2_control_node')
    files, values = s.parameters(manager)
    assert files == [str(CONTROLLERS)] and values == {'use_sim_time': False}
    # The description from robot_state_publisher's topic (the manager has no robot_description parameter on Jazzy).
    assert s.remappings(manager) == [('~/robot_description', 'robot_description')]
    rsp = s.one('robot_state_publisher', 'robot_state_publisher')
    urdf = s.parameters(rsp)[1]['robot_description']
    assert '<plugin>mock_components/GenericSystem</plugin>' in urdf and '<command_interface name="effort"' not in urdf
    spawned = [s.arguments(n) for n in s.node('controller_manager', 'spawner')]
    assert spawned == [['joint_state_broadcaster', '--controller-manager', 'controller_manager'],
                       ['joint_trajectory_controller', '--controller-manager', 'controller_manager']]
    assert any('a mock' in line and 'moves no motor' in line for line in s.logs)


def test_forward_mode_spawns_the_forward_controller_and_a_real_plugin_is_not_called_a_mock() -> None:
    s = Started(everything, use_ros2_control='true', mode='forward', hardware_plugin='acme/TiltDrive')
    spawned = [s.arguments(n)[0] for n in s.node('controller_manager', 'spawner')]
    assert spawned == ['joint_state_broadcaster', 'forward_position_controller']
    urdf = s.parameters(s.one('robot_state_publisher', 'robot_state_publisher'))[1]['robot_description']
    assert '<plugin>acme/TiltDrive</plugin>' in urdf
    assert not any('mock' in line for line in s.logs)


@pytest.mark.parametrize(('hardware', 'executable'), [('bridge', 'fourbar_drive_bridge'),
                                                      ('mujoco', 'fourbar_mujoco_drive')])
def test_the_bridge_bringup_starts_the_component_inactive_and_spawns_on_the_bridges_activation(
        hardware: str, executable: str) -> None:
    s = Started(everything, use_ros2_control='true', namespace='tilt', hardware=hardware,
                drive_backend='acme.drive:Tilt')
    rsp = s.one('robot_state_publisher', 'robot_state_publisher')
    hardware_block = ET.fromstring(s.parameters(rsp)[1]['robot_description']).find('ros2_control/hardware')
    assert hardware_block is not None
    assert hardware_block.findtext('plugin') == 'joint_state_topic_hardware_interface/JointStateTopicSystem'
    params = {p.get('name'): p.text for p in hardware_block.iter('param')}
    assert params == {'joint_commands_topic': 'drive_joint_commands', 'joint_states_topic': 'drive_joint_states'}
    manager = s.one('controller_manager', 'ros2_control_node')
    assert s.parameters(manager)[1]['hardware_components_initial_state.inactive'] == ['fourbar_antenna_tilt']
    bridge = s.one('fourbar_ros', executable)
    assert s.text(bridge._Node__node_namespace) == '/tilt'
    values = s.parameters(bridge)[1]
    assert {k: values[k] for k in ('joint_commands_topic', 'joint_states_topic', 'hardware_component',
                                   'controller_manager')} == {
        'joint_commands_topic': 'drive_joint_commands', 'joint_states_topic': 'drive_joint_states',
        'hardware_component': 'fourbar_antenna_tilt', 'controller_manager': 'controller_manager'}
    assert values.get('backend') == ('acme.drive:Tilt' if hardware == 'bridge' else None)
    # The spawners start on the bridge's activation line, not on the manager's start.
    assert [type(h).__name__ for h in s.handlers] == ['OnProcessIO']
    spawned = [s.arguments(n)[0] for n in s.node('controller_manager', 'spawner')]
    assert spawned == ['joint_state_broadcaster', 'joint_trajectory_controller']
    assert not any('a mock' in line for line in s.logs)


def test_the_hardware_parameters_reach_the_launched_robot_description(tmp_path: Any) -> None:
    params = tmp_path / 'antenna.yaml'
    params.write_text((REPO / 'config' / 'antenna.yaml').read_text(encoding='utf-8').replace(
        'hardware_parameters: []', "hardware_parameters: ['port=/dev/ttyUSB0', 'baud_rate=115200']", 1),
        encoding='utf-8')
    for effort in ('false', 'true'):  # effort_feedforward rebuilds the description: the parameters stay
        s = Started(everything, use_ros2_control='true', hardware_plugin='acme/TiltDrive', params_file=str(params),
                    effort_feedforward=effort)
        urdf = s.parameters(s.one('robot_state_publisher', 'robot_state_publisher'))[1]['robot_description']
        hardware = ET.fromstring(urdf).find('ros2_control/hardware')
        assert hardware is not None, urdf
        assert [(p.attrib['name'], p.text) for p in hardware.findall('param')] == [
            ('port', '/dev/ttyUSB0'), ('baud_rate', '115200')], urdf


def test_effort_feedforward_reaches_the_node_and_the_urdf() -> None:
    s = Started(everything, use_ros2_control='true', effort_feedforward='true')
    assert s.parameters(s.one('fourbar_ros', 'fourbar_node'))[1]['effort_feedforward'] is True
    urdf = s.parameters(s.one('robot_state_publisher', 'robot_state_publisher'))[1]['robot_description']
    assert '<command_interface name="effort"/>' in urdf


def test_trajectory_interface_reaches_the_node_only_when_given() -> None:
    s = Started(everything, use_ros2_control='true', trajectory_interface='action')
    assert s.parameters(s.one('fourbar_ros', 'fourbar_node'))[1]['trajectory_interface'] == 'action'
    s = Started(everything, use_ros2_control='true')
    assert 'trajectory_interface' not in s.parameters(s.one('fourbar_ros', 'fourbar_node'))[1]  # the file's


#: The enclave each node of the launch file starts in with ``enclaves:=true`` (fourbar_node's by its mode).
EXPECTED_ENCLAVES = {('controller_manager', 'ros2_control_node'): BRINGUP_ENCLAVES['controller_manager'],
                     ('controller_manager', 'spawner'): BRINGUP_ENCLAVES['spawner'],
                     ('robot_state_publisher', 'robot_state_publisher'): BRINGUP_ENCLAVES['robot_state_publisher'],
                     ('fourbar_ros', 'fourbar_sim_actuator'): enclave(None)}


@pytest.mark.parametrize('arguments', [{'use_ros2_control': 'true', 'rviz': 'true', 'namespace': 'tilt'},
                                       {'use_ros2_control': 'true', 'mode': 'forward'},
                                       {'sim_actuator': 'true', 'mode': 'trajectory'}, {}],
                         ids=['ros2_control', 'forward', 'sim', 'open_loop'])
def test_enclaves_start_every_node_but_rviz_in_its_enclave_of_the_policy(arguments: dict[str, str]) -> None:
    policy = enclaves((REPO / POLICY_FILE).read_text(encoding='utf-8'))
    plain = Started(everything, **arguments)
    assert all(n._Node__ros_arguments is None for n in plain.nodes)  # not unless asked
    s = Started(everything, enclaves='true', **arguments)
    mode = Mode(s.parameters(s.one('fourbar_ros', 'fourbar_node'))[1]['mode'])
    checked = 0
    for node in s.nodes:
        key = (node.node_package, node.node_executable)
        given = [s.text(a) for a in node._Node__ros_arguments or []]
        if key == ('rviz2', 'rviz2'):  # its topics are whatever its displays show: no policy of the package's
            assert given == []
            continue
        want = enclave(mode) if key == ('fourbar_ros', 'fourbar_node') else EXPECTED_ENCLAVES[key]
        assert given == ['--enclave', want] and want in policy, (key, given)
        checked += 1
    assert checked == len(s.nodes) - len(s.node('rviz2', 'rviz2')) >= 2


def test_every_launch_argument_is_in_the_cli_reference() -> None:
    declared = [e.name for e in load_launch_file().generate_launch_description().entities
                if isinstance(e, DeclareLaunchArgument)]
    text = (REPO / 'docs' / 'reference' / 'cli.md').read_text(encoding='utf-8')
    table = text[text.index('## `ros2 launch fourbar_ros fourbar.launch.py`'):text.index('## Installed files')]
    rows = {line.split('|')[1].strip().strip('`') for line in table.splitlines() if line.startswith('| `')}
    assert rows == set(declared)


def test_without_ros2_control_installed_one_line_says_so() -> None:
    s = Started(nothing_but_ours, use_ros2_control='true')
    assert s.node('controller_manager', 'ros2_control_node') == [] and s.node('controller_manager', 'spawner') == []
    assert any('ros2_control is not installed' in line and 'ros-jazzy-ros2-control' in line for line in s.logs)
    assert len(s.nodes) == 1  # the node alone (no robot_state_publisher either)


@pytest.mark.parametrize('arguments', [{'use_ros2_control': 'true', 'sim_actuator': 'true'},
                                       {'use_ros2_control': 'true', 'mode': 'open_loop'},
                                       {'hardware': 'bridge'},
                                       {'use_ros2_control': 'true', 'hardware': 'bridge', 'hardware_plugin': 'a/B'},
                                       {'use_ros2_control': 'true', 'hardware': 'bridge', 'enclaves': 'true'},
                                       {'use_ros2_control': 'true', 'hardware': 'real'}],
                         ids=['sim and ros2_control', 'open_loop with ros2_control', 'bridge without ros2_control',
                              'bridge and a plugin', 'bridge in enclaves', 'unknown hardware'])
def test_combinations_that_cannot_work_are_refused_in_one_line(arguments: dict[str, str]) -> None:
    with pytest.raises(RuntimeError) as err:
        Started(everything, **arguments)
    assert '\n' not in str(err.value) and str(err.value).startswith('fourbar.launch.py: ')


def test_an_argument_the_launch_does_not_declare_is_refused_first_in_one_line() -> None:
    declared = sorted(e.name for e in load_launch_file().generate_launch_description().entities
                      if isinstance(e, DeclareLaunchArgument))
    with pytest.raises(UnknownLaunchArgumentError) as err:
        Started(everything, use_ros2_control='true', hardwre='mujoco')  # the check runs before anything else
    assert str(err.value) == f'fourbar.launch.py: unknown launch argument hardwre; it takes: {", ".join(declared)}'


def test_the_node_name_is_the_interfaces() -> None:
    s = Started(everything)
    node = s.one('fourbar_ros', 'fourbar_node')
    assert s.text(node._Node__node_name) == NODE_NAME


#: pluginlib library namespaces whose package has another name: ros2_control's mock hardware is in hardware_interface.
PLUGIN_PACKAGES = {'mock_components': 'hardware_interface'}


def _plugin_package(plugin: str) -> str:
    prefix = plugin.split('/', maxsplit=1)[0]
    return PLUGIN_PACKAGES.get(prefix, prefix)


@pytest.mark.parametrize('arguments', [{'mode': 'trajectory', 'namespace': 'tilt'}, {'mode': 'forward'},
                                       {'effort_feedforward': 'true'}],
                         ids=['trajectory in tilt', 'forward', 'effort feed-forward'])
def test_every_package_the_ros2_control_bringup_uses_is_an_exec_depend(arguments: dict[str, str]) -> None:
    """What ``use_ros2_control:=true`` needs installed: the executables' packages, the URDF's hardware and
    transmission plugins, and the controller types the controller manager reads from the controllers file in the
    launch's namespace (rcl's rules). Each must be an exec_depend, so rosdep installs it (test_rosdep_keys checks
    that every key resolves for Jazzy)."""
    from catkin_pkg.package import parse_package

    from fourbar_ros.config.rcl_yaml import read_text, values_from_yaml

    s = Started(everything, use_ros2_control='true', **arguments)
    needed = {n.node_package for n in s.nodes} - {'fourbar_ros'}
    assert {'controller_manager', 'robot_state_publisher'} <= needed
    urdf = s.parameters(s.one('robot_state_publisher', 'robot_state_publisher'))[1]['robot_description']
    plugins = [p.text or '' for p in ET.fromstring(urdf).iter('plugin')]
    assert 'mock_components/GenericSystem' in plugins and 'transmission_interface/SimpleTransmission' in plugins
    needed |= {_plugin_package(p) for p in plugins}
    manager = s.one('controller_manager', 'ros2_control_node')
    (controllers,) = s.parameters(manager)[0]
    namespace = '/' + arguments.get('namespace', '')
    values = values_from_yaml(read_text(controllers), controllers, 'controller_manager', namespace)
    types = {str(v) for k, v in values.items() if k.endswith('.type')}
    assert len(types) == 3  # the broadcaster and both controllers: the section applies in this namespace
    needed |= {_plugin_package(t) for t in types}
    spawned = {s.arguments(n)[0] for n in s.node('controller_manager', 'spawner')}
    assert spawned <= {k.removesuffix('.type') for k in values if k.endswith('.type')}
    declared = {d.name for d in parse_package(str(REPO / 'package.xml')).exec_depends}
    assert not needed - declared, f'add <exec_depend> for {sorted(needed - declared)} to package.xml'
