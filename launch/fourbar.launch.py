"""fourbar_node with its parameter file, and optionally robot_state_publisher (the URDF generated from the same
file), RViz and the simulated actuator (for users without the drive's hardware and ros2_control).

    ros2 launch fourbar_ros fourbar.launch.py [params_file:=FILE] [namespace:=NS] [use_sim_time:=true]
        [robot_state_publisher:=true|false] [rviz:=true|false] [sim_actuator:=true|false]
        [mode:=open_loop|trajectory|forward]

mode (fourbar_node's parameter, default: the parameter file's, else open_loop): trajectory or forward send the
motion to the drive's controllers; with sim_actuator:=true the simulated actuator follows it.

robot_state_publisher and RViz start only where they are installed; otherwise one log line says so and the
node runs alone. Ctrl-C (SIGINT) stops every process and `ros2 launch` exits 0.
"""

from __future__ import annotations

# ruff: noqa: I001 - `launch` is ROS's package; ruff takes it for this repository's launch/ folder

import atexit
import os
import tempfile
from pathlib import Path

from launch import LaunchContext, LaunchDescription
from launch.actions import DeclareLaunchArgument, LogInfo, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

from fourbar_ros.config.interface import NODE_NAME
from fourbar_ros.config.sim_actuator_params import NODE_NAME as SIM_NODE_NAME

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
    text = text.replace('Value: /linkage_markers', f'Value: {prefix}/linkage_markers')
    fd, path = tempfile.mkstemp(prefix='fourbar_', suffix='.rviz')
    with os.fdopen(fd, 'w', encoding='utf-8') as f:
        f.write(text)
    atexit.register(lambda: Path(path).unlink(missing_ok=True))  # ros2 launch runs this file in its own process
    return path


def _setup(context: LaunchContext) -> list[object]:
    from fourbar_ros.config.robot_model import robot_description_for

    params_file = LaunchConfiguration('params_file').perform(context)
    namespace = _namespace(LaunchConfiguration('namespace').perform(context))
    use_sim_time = _true(LaunchConfiguration('use_sim_time').perform(context))
    want_rsp = _true(LaunchConfiguration('robot_state_publisher').perform(context))
    want_rviz = _true(LaunchConfiguration('rviz').perform(context))
    want_sim = _true(LaunchConfiguration('sim_actuator').perform(context))
    mode = LaunchConfiguration('mode').perform(context)
    ros_namespace = '' if namespace == '/' else namespace
    node_overrides: dict[str, object] = {'use_sim_time': use_sim_time, **({'mode': mode} if mode else {})}
    actions: list[object] = [
        Node(package='fourbar_ros', executable='fourbar_node', name=NODE_NAME, namespace=ros_namespace,
             parameters=[params_file, node_overrides], output='screen', emulate_tty=False),
    ]
    if want_rsp or want_rviz or want_sim:
        cfg, urdf = robot_description_for(params_file, NODE_NAME, namespace)
    if want_sim:  # the linkage fourbar_node reads; its own parameters from a sim_actuator section of the file
        actions.append(Node(package='fourbar_ros', executable='fourbar_sim_actuator', name=SIM_NODE_NAME,
                            namespace=ros_namespace, output='screen', emulate_tty=False,
                            parameters=[params_file, cfg.as_values(), {'use_sim_time': use_sim_time}]))
    if want_rsp:
        if _installed_executable('robot_state_publisher', 'robot_state_publisher'):
            actions.append(Node(package='robot_state_publisher', executable='robot_state_publisher',
                                namespace=ros_namespace, output='screen',
                                parameters=[{'robot_description': urdf, 'use_sim_time': use_sim_time}]))
        else:
            actions.append(LogInfo(msg='fourbar.launch.py: robot_state_publisher is not installed; not starting it '
                                       '(no robot model in TF; install ros-jazzy-robot-state-publisher)'))
    if want_rviz:
        if _installed_executable('rviz2', 'rviz2'):
            config = _rviz_config(SHARE / 'rviz' / 'fourbar.rviz', cfg.frame_id, namespace)
            actions.append(Node(package='rviz2', executable='rviz2', namespace=ros_namespace, output='screen',
                                arguments=['-d', config], parameters=[{'use_sim_time': use_sim_time}]))
        else:
            actions.append(LogInfo(msg='fourbar.launch.py: rviz2 is not installed; not starting RViz '
                                       '(install ros-jazzy-rviz2)'))
    return actions


def generate_launch_description() -> LaunchDescription:
    """Arguments, then the nodes (resolved once the arguments are known)."""
    return LaunchDescription([
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
                                          'parameter file\'s, else open_loop)'),
        OpaqueFunction(function=_setup),
    ])
