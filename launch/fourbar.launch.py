"""fourbar_node with its parameter file, and optionally robot_state_publisher (the URDF generated from the same
file), RViz, the simulated actuator (for users without the drive's hardware) or the drive's ros2_control bringup.

    ros2 launch fourbar_ros fourbar.launch.py [params_file:=FILE] [namespace:=NS] [use_sim_time:=true]
        [robot_state_publisher:=true|false] [rviz:=true|false] [mode:=open_loop|trajectory|forward]
        [sim_actuator:=true|false]
        [use_ros2_control:=true|false] [hardware:=mock|bridge|mujoco] [drive_backend:=simulated|MODULE:CLASS]
        [hardware_plugin:=PLUGIN] [controllers_file:=FILE] [effort_feedforward:=true]
        [trajectory_interface:=topic|action] [enclaves:=true|false]

mode (fourbar_node's parameter, default: the parameter file's, else open_loop): trajectory or forward send the
motion to the drive's controllers. In an actuator mode the node reads the measured driven joint where
joint_state_broadcaster publishes it (measured_joint_states remapped to joint_state_broadcaster/joint_states).
sim_actuator:=true: the simulated actuator stands in for the controllers and the hardware. use_ros2_control:=true
(trajectory mode unless mode says forward): ros2_control_node with controllers_file (also the node's, so the node
sends what that controller accepts; respawned 2 s after it dies), the description from robot_state_publisher's
topic, spawners for joint_state_broadcaster and the mode's controller (at every start of the manager), and
hardware_plugin in the URDF's <ros2_control> tag (default
mock_components/GenericSystem, a mock that echoes commands: announced at startup). hardware:=bridge (or mujoco): the
plugin is JointStateTopicSystem on the namespace's drive_joint_commands / drive_joint_states, the other end
fourbar_drive_bridge with drive_backend (or fourbar_mujoco_drive, the MuJoCo plant); the manager starts the component
inactive (hardware_components_initial_state) and the bridge activates it after a reading of the drive inside the
driven range; the spawners start on the bridge's activation line, at each activation (a respawned manager's
included), not at the manager's start (docs/how-to/drive-bridge.md). effort_feedforward:=true adds the
effort command interface to the URDF and sets the node's parameter; the controllers file must then give
joint_trajectory_controller command_interfaces [position, effort]. trajectory_interface (the node's parameter,
default: the parameter file's): action sends trajectories as FollowJointTrajectory goals. enclaves:=true starts
every node but RViz in its SROS2 enclave of the package's policy (fourbar_ros.config.security; the security how-to).

robot_state_publisher, RViz and ros2_control start only where they are installed; otherwise one log line says so
(ros2_control's bringup then does not start). Ctrl-C (SIGINT) stops every process and `ros2 launch` exits 0. An
argument this file does not declare (a misspelled name) is refused before anything starts: one error line names it
and the arguments taken, and `ros2 launch` exits 1 (fourbar_ros.config.launch_arguments).
"""

from __future__ import annotations

# ruff: noqa: I001 - `launch` is ROS's package; ruff takes it for this repository's launch/ folder

import atexit
import os
import tempfile
from pathlib import Path

from launch import LaunchContext, LaunchDescription
from dataclasses import replace

from launch.actions import DeclareLaunchArgument, LogInfo, OpaqueFunction, RegisterEventHandler
from launch.event_handlers import OnProcessIO, OnProcessStart
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

from fourbar_ros.config.controllers import CONTROLLERS_FILE
from fourbar_ros.config.launch_arguments import refuse_undeclared
from fourbar_ros.config.security import BRINGUP_ENCLAVES, enclave
from fourbar_ros.interface.topics import (
    BROADCASTER_JOINT_STATES,
    MARKERS,
    MEASURED_JOINT_STATES,
    NODE_EXECUTABLE,
    NODE_NAME,
    SIM_EXECUTABLE,
    Mode,
)
from fourbar_ros.config.robot_model import DEFAULT_HARDWARE_PLUGIN as MOCK_PLUGIN  # ros2_control's mock
from fourbar_ros.config.sim_actuator_params import NODE_NAME as SIM_NODE_NAME
from fourbar_ros.drive.rules import ACTIVATED_MARK

#: The ``hardware`` argument's values: ros2_control's mock (or hardware_plugin), the drive bridge, the MuJoCo plant.
HARDWARE = ('mock', 'bridge', 'mujoco')
#: The topic-based plugin of hardware:=bridge|mujoco, its topics (relative: in the launch's namespace).
TOPIC_PLUGIN = 'joint_state_topic_hardware_interface/JointStateTopicSystem'
DRIVE_COMMANDS, DRIVE_STATES = 'drive_joint_commands', 'drive_joint_states'
#: The executables at the plugin's other end: the bridge (a drive backend), the bridge on the MuJoCo plant.
BRIDGE_EXECUTABLE = {'bridge': 'fourbar_drive_bridge', 'mujoco': 'fourbar_mujoco_drive'}

#: This file lives in share/fourbar_ros/launch (installed) or launch/ (source tree); config/ and rviz/ are beside.
SHARE = Path(__file__).resolve().parent.parent


def _installed_executable(package: str, executable: str) -> bool:
    """True if ``ros2 run package executable`` would find it (ament index prefix, lib/<package>/)."""
    from ament_index_python.packages import PackageNotFoundError, get_package_prefix

    try:
        prefix = get_package_prefix(package)
    except PackageNotFoundError:
        return False
    return os.access(Path(prefix) / 'lib' / package / executable, os.X_OK)


def _true(text: str) -> bool:
    value = text.strip().lower()
    if value not in ('true', 'false', '1', '0', 'yes', 'no', 'on', 'off'):
        raise ValueError(f'expected true or false, got {text!r}')
    return value in ('true', '1', 'yes', 'on')


def _namespace(text: str) -> str:
    ns = text.strip().strip('/')
    return f'/{ns}' if ns else '/'


def _rviz_config(template: Path, frame_id: str, namespace: str) -> str:
    """The shipped RViz configuration with the fixed frame and the namespaced topics of this launch."""
    prefix = '' if namespace == '/' else namespace
    text = template.read_text(encoding='utf-8')
    text = text.replace('Fixed Frame: fourbar_base', f'Fixed Frame: {frame_id}')
    text = text.replace('Value: /robot_description', f'Value: {prefix}/robot_description')
    text = text.replace(f'Value: /{MARKERS.name}', f'Value: {prefix}/{MARKERS.name}')
    fd, path = tempfile.mkstemp(prefix='fourbar_', suffix='.rviz')
    with os.fdopen(fd, 'w', encoding='utf-8') as f:
        f.write(text)
    atexit.register(lambda: Path(path).unlink(missing_ok=True))  # ros2 launch runs this file in its own process
    return path


def _launch_values(values: dict[str, object]) -> dict[str, object]:
    """Parameter values as launch_ros passes them: an empty list has no type there (it refuses one), and a node
    that declares it reads it as empty when it is not set."""
    return {name: value for name, value in values.items() if value != []}


def _setup(context: LaunchContext) -> list[object]:
    from fourbar_ros.config.robot_model import robot_description, robot_description_for

    def arg(name: str) -> str:
        return LaunchConfiguration(name).perform(context)

    params_file = arg('params_file')
    namespace = _namespace(arg('namespace'))
    use_sim_time = _true(arg('use_sim_time'))
    want_rsp = _true(arg('robot_state_publisher'))
    want_rviz = _true(arg('rviz'))
    want_sim = _true(arg('sim_actuator'))
    want_control = _true(arg('use_ros2_control'))
    effort = _true(arg('effort_feedforward'))
    plugin = arg('hardware_plugin')
    hardware = arg('hardware')
    controllers = arg('controllers_file')
    enclaves = _true(arg('enclaves'))
    ros_namespace = '' if namespace == '/' else namespace
    if hardware not in HARDWARE:
        raise RuntimeError(f'fourbar.launch.py: hardware:={hardware}: expected one of {", ".join(HARDWARE)}')
    if hardware != 'mock':
        if not want_control:
            raise RuntimeError(f'fourbar.launch.py: hardware:={hardware} needs use_ros2_control:=true')
        if plugin != MOCK_PLUGIN:
            raise RuntimeError(f'fourbar.launch.py: hardware:={hardware} brings its own plugin ({TOPIC_PLUGIN}); '
                               'hardware_plugin:= is for hardware:=mock (a plugin of your own)')
        if enclaves:
            raise RuntimeError(f'fourbar.launch.py: hardware:={hardware} has no enclave in the package\'s policy; '
                               'start it with enclaves:=false')
        plugin = TOPIC_PLUGIN
    cfg, urdf = robot_description_for(params_file, NODE_NAME, namespace, hardware_plugin=plugin)
    if hardware != 'mock':  # the plugin's topics, relative: its node lives in the manager's namespace
        kept = tuple(e for e in cfg.hardware_parameters
                     if e.partition('=')[0] not in ('joint_commands_topic', 'joint_states_topic'))
        cfg = replace(cfg, hardware_parameters=(*kept, f'joint_commands_topic={DRIVE_COMMANDS}',
                                                 f'joint_states_topic={DRIVE_STATES}'))
        urdf = robot_description(cfg, hardware_plugin=plugin)
    mode = arg('mode') or cfg.mode
    if want_control and want_sim:
        raise RuntimeError('fourbar.launch.py: sim_actuator:=true and use_ros2_control:=true both drive the joint; '
                           'choose one')
    if want_control and mode == Mode.OPEN_LOOP.value:
        if arg('mode'):
            raise RuntimeError('fourbar.launch.py: use_ros2_control:=true needs mode:=trajectory or mode:=forward')
        mode = Mode.TRAJECTORY.value
    if effort:
        cfg = replace(cfg, effort_feedforward=True)
        urdf = robot_description(cfg, hardware_plugin=plugin)
    actuated = mode != Mode.OPEN_LOOP.value
    node_overrides: dict[str, object] = {'use_sim_time': use_sim_time, 'mode': mode}
    if actuated:
        node_overrides.update({'controllers_file': controllers, 'effort_feedforward': effort})
    if arg('trajectory_interface'):
        node_overrides['trajectory_interface'] = arg('trajectory_interface')
    actions: list[object] = [
        Node(package='fourbar_ros', executable=NODE_EXECUTABLE, name=NODE_NAME, namespace=ros_namespace,
             parameters=[params_file, node_overrides], output='screen', emulate_tty=False,
             remappings=[(MEASURED_JOINT_STATES.name, BROADCASTER_JOINT_STATES.name)] if actuated else [],
             **_in_enclave(enclaves, enclave(Mode(mode)) if enclaves else '')),
    ]
    if want_sim:  # the linkage fourbar_node reads; its own parameters from a sim_actuator section of the file
        actions.append(Node(package='fourbar_ros', executable=SIM_EXECUTABLE, name=SIM_NODE_NAME,
                            namespace=ros_namespace, output='screen', emulate_tty=False,
                            parameters=[params_file,
                                        {**_launch_values(cfg.as_values()), 'controllers_file': controllers},
                                        {'use_sim_time': use_sim_time}],
                            **_in_enclave(enclaves, enclave(None))))
    if want_rsp or want_control:
        if _installed_executable('robot_state_publisher', 'robot_state_publisher'):
            actions.append(Node(package='robot_state_publisher', executable='robot_state_publisher',
                                namespace=ros_namespace, output='screen',
                                parameters=[{'robot_description': urdf, 'use_sim_time': use_sim_time}],
                                **_in_enclave(enclaves, BRINGUP_ENCLAVES['robot_state_publisher'])))
        else:
            actions.append(LogInfo(msg='fourbar.launch.py: robot_state_publisher is not installed; not starting it '
                                       '(no robot model in TF; install ros-jazzy-robot-state-publisher)'))
    if want_control:
        bridge = None if hardware == 'mock' else _bridge(hardware, arg('drive_backend'), params_file, cfg.hardware_id,
                                                          ros_namespace, use_sim_time)
        actions += _ros2_control(cfg, mode, ros_namespace, controllers, plugin, use_sim_time, enclaves, bridge)
    if want_rviz:
        if _installed_executable('rviz2', 'rviz2'):
            config = _rviz_config(SHARE / 'rviz' / 'fourbar.rviz', cfg.frame_id, namespace)
            actions.append(Node(package='rviz2', executable='rviz2', namespace=ros_namespace, output='screen',
                                arguments=['-d', config], parameters=[{'use_sim_time': use_sim_time}]))
        else:
            actions.append(LogInfo(msg='fourbar.launch.py: rviz2 is not installed; not starting RViz '
                                       '(install ros-jazzy-rviz2)'))
    return actions


#: Seconds before a controller manager that died is started again (and its controllers spawned again).
CONTROLLER_MANAGER_RESPAWN_S = 2.0


def _in_enclave(enclaves: bool, name: str) -> dict[str, list[str]]:
    """A Node's arguments that start it in SROS2 enclave ``name`` when ``enclaves`` (rcl ignores the enclave while
    ROS_SECURITY_ENABLE is not true)."""
    return {'ros_arguments': ['--enclave', name]} if enclaves else {}


def _bridge(hardware: str, backend: str, params_file: str, component: str, ros_namespace: str,
            use_sim_time: bool) -> Node:
    """The plugin's other end for hardware:=bridge|mujoco: it activates ``component`` after a reading in range."""
    executable = BRIDGE_EXECUTABLE[hardware]
    if not _installed_executable('fourbar_ros', executable):
        raise RuntimeError(f'fourbar.launch.py: hardware:={hardware} needs fourbar_ros\'s {executable}, which is not '
                           'installed')
    params: dict[str, object] = {'config_file': params_file, 'joint_commands_topic': DRIVE_COMMANDS,
                                 'joint_states_topic': DRIVE_STATES, 'hardware_component': component,
                                 'controller_manager': 'controller_manager', 'use_sim_time': use_sim_time}
    if hardware == 'bridge':
        params['backend'] = backend
    return Node(package='fourbar_ros', executable=executable, namespace=ros_namespace, output='screen',
                emulate_tty=False, parameters=[params])


def _ros2_control(cfg: object, mode: str, ros_namespace: str, controllers: str, plugin: str,
                  use_sim_time: bool, enclaves: bool, bridge: Node | None = None) -> list[object]:
    """ros2_control_node with ``controllers`` (the description from robot_state_publisher's topic) and the
    spawners of joint_state_broadcaster and the mode's controller, as the ros2_control_demos jazzy bringups do.
    With ``bridge``: the component starts inactive, the spawners start on each of the bridge's activation lines."""
    from fourbar_ros.config.antenna_config import AntennaConfig

    assert isinstance(cfg, AntennaConfig)
    actions: list[object] = []
    if plugin == MOCK_PLUGIN:
        actions.append(LogInfo(msg=f'fourbar.launch.py: hardware_plugin is {MOCK_PLUGIN}, a mock: it echoes the '
                                   'commands as states and moves no motor (hardware_plugin:=YOUR/Plugin for the '
                                   'drive)'))
    if not (_installed_executable('controller_manager', 'ros2_control_node')
            and _installed_executable('controller_manager', 'spawner')):
        actions.append(LogInfo(msg='fourbar.launch.py: ros2_control is not installed; not starting the controller '
                                   'manager or its controllers (install ros-jazzy-ros2-control and '
                                   'ros-jazzy-ros2-controllers)'))
        return actions
    controller = cfg.trajectory_controller if mode == Mode.TRAJECTORY.value else cfg.forward_controller
    overrides: dict[str, object] = {'use_sim_time': use_sim_time}
    if bridge is not None:
        overrides['hardware_components_initial_state.inactive'] = [cfg.hardware_id]
    manager = Node(package='controller_manager', executable='ros2_control_node', namespace=ros_namespace,
                   output='screen', parameters=[controllers, overrides],
                   remappings=[('~/robot_description', 'robot_description')],
                   respawn=True, respawn_delay=CONTROLLER_MANAGER_RESPAWN_S,
                   **_in_enclave(enclaves, BRINGUP_ENCLAVES['controller_manager']))

    def spawners(*_: object) -> list[Node]:
        return [Node(package='controller_manager', executable='spawner', namespace=ros_namespace, output='screen',
                     arguments=[name, '--controller-manager', 'controller_manager'],
                     **_in_enclave(enclaves, BRINGUP_ENCLAVES['spawner']))
                for name in ('joint_state_broadcaster', controller)]

    if bridge is None:  # at every start of the manager, its respawns included, new spawners bring them up again
        return [*actions, manager, RegisterEventHandler(OnProcessStart(target_action=manager, on_start=spawners))]

    def on_bridge_output(event: object) -> list[Node]:  # each activation, a respawned manager's included
        text: bytes = getattr(event, 'text', b'')
        return spawners() if ACTIVATED_MARK.encode() in text else []
    watch = OnProcessIO(target_action=bridge, on_stdout=on_bridge_output, on_stderr=on_bridge_output)
    return [*actions, RegisterEventHandler(watch), bridge, manager]


def generate_launch_description() -> LaunchDescription:
    """The check of the command line's arguments, the arguments, then the nodes (resolved once the arguments are
    known)."""
    arguments = [
        DeclareLaunchArgument('params_file', default_value=str(SHARE / 'config' / 'antenna.yaml'),
                              description='ROS 2 parameter file of fourbar_node (also the source of the URDF)'),
        DeclareLaunchArgument('namespace', default_value='',
                              description='namespace of every node started here (topics are relative)'),
        DeclareLaunchArgument('use_sim_time', default_value='false',
                              description='take time from /clock (e.g. ros2 bag play --clock)'),
        DeclareLaunchArgument('robot_state_publisher', default_value='true',
                              description='start robot_state_publisher with the URDF (where installed)'),
        DeclareLaunchArgument('rviz', default_value='false',
                              description='start RViz with rviz/fourbar.rviz (where installed)'),
        DeclareLaunchArgument('sim_actuator', default_value='false',
                              description='start the simulated actuator (fourbar_sim_actuator) in place of the '
                                          'drive\'s ros2_control hardware and controllers'),
        DeclareLaunchArgument('mode', default_value='',
                              description='fourbar_node\'s mode: open_loop, trajectory or forward (default: the '
                                          'parameter file\'s, else open_loop; trajectory with use_ros2_control)'),
        DeclareLaunchArgument('use_ros2_control', default_value='false',
                              description='start ros2_control_node, joint_state_broadcaster and the mode\'s '
                                          'controller for the drive (where ros2_control is installed)'),
        DeclareLaunchArgument('hardware', default_value='mock', choices=list(HARDWARE),
                              description='the drive under ros2_control: mock (hardware_plugin), bridge '
                                          '(fourbar_drive_bridge with drive_backend, on the topic-based plugin) or '
                                          'mujoco (the MuJoCo plant on it)'),
        DeclareLaunchArgument('drive_backend', default_value='simulated',
                              description='with hardware:=bridge: the bridge\'s backend (simulated, or '
                                          'MODULE:CLASS, your DriveBackend)'),
        DeclareLaunchArgument('hardware_plugin', default_value=MOCK_PLUGIN,
                              description='the hardware plugin of the URDF\'s <ros2_control> block (the default is '
                                          'a mock that moves no motor)'),
        DeclareLaunchArgument('controllers_file', default_value=str(SHARE / CONTROLLERS_FILE),
                              description='the ros2_control controllers YAML (also fourbar_node\'s controllers_file)'),
        DeclareLaunchArgument('effort_feedforward', default_value='false',
                              description='trajectory points carry the static torque as effort (the controller '
                                          'needs command_interfaces [position, effort])'),
        DeclareLaunchArgument('trajectory_interface', default_value='',
                              description='fourbar_node\'s trajectory_interface (topic, or action: '
                                          'FollowJointTrajectory goals); empty: the parameter file\'s'),
        DeclareLaunchArgument('enclaves', default_value='false',
                              description='start each node (not RViz) in its SROS2 enclave of the package\'s policy '
                                          '(with ROS_SECURITY_ENABLE=true and a keystore that has them)'),
    ]
    return LaunchDescription([OpaqueFunction(function=refuse_undeclared(Path(__file__).name, arguments)), *arguments,
                              OpaqueFunction(function=_setup)])
