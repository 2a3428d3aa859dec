"""The drive room's imports: only the ``fourbar`` commands and the plant (a drive of its own) import it; its backend
and rules run without ROS."""

from __future__ import annotations

import importlib.util
import subprocess
import sys

from support.paths import REPO


def _graph() -> dict[str, set[str]]:
    """test_layers.py's import graph (module -> the package's modules it imports)."""
    spec = importlib.util.spec_from_file_location('drive_room_layers', REPO / 'test' / 'package' / 'test_layers.py')
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    graph: dict[str, set[str]] = module.GRAPH
    return graph


GRAPH = _graph()

PURE = ('fourbar_ros.drive.backend', 'fourbar_ros.drive.rules')
ROS = ('rclpy', 'sensor_msgs', 'std_msgs', 'diagnostic_msgs', 'rcl_interfaces', 'builtin_interfaces')


def test_only_the_commands_and_the_plant_import_the_drive_room() -> None:
    outside = [f'{name} -> {dep}' for name, deps in GRAPH.items() for dep in deps
               if dep.startswith('fourbar_ros.drive') and not name.startswith(('fourbar_ros.drive',
                                                                                 'fourbar_ros.commands',
                                                                                 'fourbar_ros.plant'))]
    assert not outside, '\n'.join(outside)


def test_backend_and_rules_import_with_ros_blocked() -> None:
    script = f"""
import importlib, importlib.abc, sys
class Block(importlib.abc.MetaPathFinder):
    def find_spec(self, fullname, path=None, target=None):
        if fullname.split('.')[0] in {ROS!r}:
            raise ImportError(f'blocked: {{fullname}}')
        return None
sys.meta_path.insert(0, Block())
for name in {PURE!r}:
    importlib.import_module(name)
"""
    done = subprocess.run([sys.executable, '-c', script], capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 0, done.stderr
