"""Packaging: package.xml is a valid format-3 ament_python manifest, and a colcon build installs a fourbar_node
into lib/fourbar_ros that, started the way ``ros2 run`` starts it, serves commands over ROS."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64
from support.colcon_support import sourced_env as colcon_env
from support.paths import REPO
from support.ros_support import ONE_JOINT_STATE_PER_COMMAND, NodeProcess, RosSession, sync_probe

from fourbar_ros.config.antenna_config import load_config
from fourbar_ros.interface.topics import NODE_EXECUTABLE, SIM_EXECUTABLE


def test_package_xml_validates_with_catkin_pkg() -> None:
    from catkin_pkg.package import parse_package

    pkg = parse_package(str(REPO / 'package.xml'))
    pkg.validate()  # raises InvalidPackage with the reasons
    assert pkg.package_format == 3
    assert pkg.name == 'fourbar_ros'
    assert pkg.get_build_type() == 'ament_python'
    runtime = {d.name for d in pkg.exec_depends}
    assert {'rclpy', 'std_msgs', 'sensor_msgs', 'diagnostic_msgs', 'visualization_msgs'} <= runtime


def test_setup_declares_the_console_script_and_ros_install_dir() -> None:
    setup_py = (REPO / 'setup.py').read_text(encoding='utf-8')
    # The executables the launch file, the process helpers and the commands name (interface.topics).
    assert f"'{NODE_EXECUTABLE} = fourbar_ros.node:main'" in setup_py
    assert f"'{SIM_EXECUTABLE} = fourbar_ros.plant.sim_drive:sim_actuator_main'" in setup_py
    cfg = (REPO / 'setup.cfg').read_text(encoding='utf-8')
    assert 'install_scripts=$base/lib/fourbar_ros' in cfg and 'script_dir=$base/lib/fourbar_ros' in cfg


def sourced_env(ros: RosSession, prefix: Path) -> dict[str, str]:
    """What sourcing install/setup.sh sets for this package, on the test's domain id."""
    return colcon_env(ros.env(), prefix, ros.domain_id, localhost=False)  # as this process's rclpy


def test_setup_installs_only_the_package_and_the_share_files() -> None:
    setup_py = (REPO / 'setup.py').read_text(encoding='utf-8')
    assert "find_packages(include=[PACKAGE, f'{PACKAGE}.*'])" in setup_py
    for share in ('config', 'launch', 'rviz', 'bags/demo_sweep'):
        assert f"(f'share/{{PACKAGE}}/{share}'" in setup_py, share


@pytest.mark.slow
def test_colcon_install_has_share_files_and_no_benchmarks(colcon_install: Path) -> None:
    prefix = colcon_install / 'fourbar_ros'
    share = prefix / 'share' / 'fourbar_ros'
    for rel in ('package.xml', 'config/antenna.yaml', 'launch/fourbar.launch.py', 'rviz/fourbar.rviz'):
        assert (share / rel).read_bytes() == (REPO / rel).read_bytes(), rel
    bag = share / 'bags' / 'demo_sweep'
    assert sorted(p.name for p in bag.iterdir()) == sorted(p.name for p in (REPO / 'fourbar_ros' / 'data' /
                                                                            'demo_sweep').iterdir())
    site = prefix / 'lib' / f'python{sys.version_info.major}.{sys.version_info.minor}' / 'site-packages'
    for layer in ('core', 'config', 'motion', 'node', 'bags', 'commands'):  # find_packages keeps the layer folders
        assert (site / 'fourbar_ros' / layer / '__init__.py').is_file(), layer
    assert (site / 'fourbar_ros' / 'config' / 'robot_model.py').is_file()
    assert not (site / 'benchmarks').exists() and not (site / 'test').exists()
    assert os.access(prefix / 'lib' / 'fourbar_ros' / 'fourbar', os.X_OK)


@pytest.mark.ros
@pytest.mark.slow
def test_colcon_installed_node_serves_commands(colcon_install: Path, ros: RosSession) -> None:
    prefix = colcon_install / 'fourbar_ros'
    executable = prefix / 'lib' / 'fourbar_ros' / 'fourbar_node'
    assert executable.is_file() and os.access(executable, os.X_OK)
    installed_yaml = prefix / 'share' / 'fourbar_ros' / 'config' / 'antenna.yaml'
    assert installed_yaml.read_text(encoding='utf-8') == (REPO / 'config' / 'antenna.yaml').read_text(encoding='utf-8')
    assert (colcon_install.parent / 'install' / 'fourbar_ros' / 'share' / 'ament_index' / 'resource_index' / 'packages'
            / 'fourbar_ros').is_file()
    cfg = load_config(installed_yaml)
    env = sourced_env(ros, prefix)
    where = subprocess.run([sys.executable, '-c', 'import fourbar_ros; print(fourbar_ros.__file__)'],
                           env=env, cwd=colcon_install, capture_output=True, text=True,
                           check=True).stdout.strip()
    assert where.startswith(str(prefix)), where   # the installed copy, not the source tree
    with NodeProcess(['--ros-args', '--params-file', str(REPO / 'config' / 'antenna.yaml'),
                      *ONE_JOINT_STATE_PER_COMMAND], env, command=[str(executable)], cwd=colcon_install) as proc:
        pub = ros.publisher(Float64, 'antenna_angle_cmd')
        js = ros.collect(JointState, 'joint_states')
        ros.wait_subscribers(pub)
        ros.wait_publishers(js)
        probes = [cfg.theta_min + (cfg.theta_max - cfg.theta_min) * (i + 0.5) / 600 for i in range(600)]
        sync_probe(lambda t: pub.publish(Float64(data=t)), [js], probes,
                   lambda col, msg, p: bool(msg.position[0] == cfg.linkage.state(p).gamma))
        pub.publish(Float64(data=0.05))
        msg = js.wait_count(1)[0]
        s = cfg.linkage.state(0.05, cfg.load_torque)
        assert list(msg.position) == pytest.approx([s.gamma, s.delta, s.gamma + 0.05], abs=1e-12)
        assert list(msg.effort) == pytest.approx([s.input_torque, 0.0, 0.0], abs=1e-12)
        ros.uncollect(js)
        ros.destroy(pub)
        assert proc.stop(signal.SIGINT) == 0, proc.stderr
        assert 'Traceback' not in proc.stderr
