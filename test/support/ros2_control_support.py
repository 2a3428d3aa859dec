"""The real ros2_control stack the tests run against: a sourced ROS 2 Jazzy install that has it, or the install
space that ``$FOURBAR_ROS2_CONTROL`` names (a colcon install of controller_manager, ros2_controllers, control_msgs
and robot_state_publisher built for this venv's ROS wheels; ``make test`` sets it where one lies beside the
checkout). ``with_ros2_control`` puts the latter on a child process's paths, as sourcing its setup script would.
"""

from __future__ import annotations

import importlib.util
import os
import sys
from pathlib import Path

#: The variable naming a ros2_control install space (``.../install``) for the tests.
PREFIX_ENV = 'FOURBAR_ROS2_CONTROL'
#: What the package's launch file starts from ros2_control (package names in the ament index).
REQUIRED = ('controller_manager', 'joint_trajectory_controller', 'joint_state_broadcaster',
            'forward_command_controller', 'robot_state_publisher')


def stack_prefix() -> Path | None:
    """The install space ``$FOURBAR_ROS2_CONTROL`` names, if it exists."""
    named = os.environ.get(PREFIX_ENV, '')
    return Path(named) if named and (Path(named) / 'share').is_dir() else None


def with_ros2_control(env: dict[str, str]) -> dict[str, str]:
    """``env`` with the named install space first on the ament, library and Python paths (unchanged without one).

    The library path must be set before a process starts: the loader reads it once."""
    prefix = stack_prefix()
    if prefix is None:
        return env
    site = prefix / 'lib' / f'python{sys.version_info.major}.{sys.version_info.minor}' / 'site-packages'
    out = dict(env)
    for var, path in (('AMENT_PREFIX_PATH', prefix), ('LD_LIBRARY_PATH', prefix / 'lib'), ('PYTHONPATH', site)):
        out[var] = os.pathsep.join(filter(None, [str(path), out.get(var, '')]))
    return out


def ros2_control_missing(env: dict[str, str]) -> str | None:
    """Why the real ros2_control stack cannot be started with ``env`` (None when it can)."""
    roots = [Path(p) for p in env.get('AMENT_PREFIX_PATH', '').split(os.pathsep) if p]
    missing = [name for name in REQUIRED
               if not any((root / 'share' / 'ament_index' / 'resource_index' / 'packages' / name).exists()
                          for root in roots)]
    if not missing:
        if importlib.util.find_spec('ros2param') is None:  # the spawner imports it (controller_manager's services)
            return ('the ros2 command line (ros2param) is not installed in this environment: the controller '
                    "manager's spawner imports it (scripts/install_ros_cli.sh installs it)")
        return None
    return (f'ros2_control is not installed here ({", ".join(missing)} missing): source a ROS 2 Jazzy install '
            f'with ros2_control and ros2_controllers, or set {PREFIX_ENV} to an install space of them')
