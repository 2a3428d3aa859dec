"""What a headless pole computer may leave out: the how-to's ``--skip-keys`` names exec_depends of package.xml whose
modules only the desktop and the simulation use; with those modules blocked every module of the package imports
(the MuJoCo plant's own two excepted) and the node, in every mode, and the drive bridge start and stop."""

from __future__ import annotations

import re
import subprocess
import sys

import pytest
from support.paths import REPO
from support.ros_support import RosSession
from test_rosdep_keys import package

HOWTO = REPO / 'docs' / 'how-to' / 'ros2-control.md'
#: A skipped key -> the top-level modules it installs (rviz2: a program the launch starts only where installed).
KEY_MODULES = {'rviz2': (), 'python3-matplotlib': ('matplotlib',), 'python3-pil': ('PIL',),
               'python3-mujoco-pip': ('mujoco',)}
#: The modules that import mujoco itself: the plant and its backend.
NEEDS_MUJOCO = ['fourbar_ros.plant.backend', 'fourbar_ros.plant.plant']

SCRIPT = """
import importlib, importlib.abc, pkgutil, sys
BLOCKED = set(sys.argv[1].split())
class Block(importlib.abc.MetaPathFinder):
    def find_spec(self, fullname, path=None, target=None):
        if fullname.split('.')[0] in BLOCKED:
            raise ModuleNotFoundError(f'blocked: {fullname}', name=fullname)
sys.meta_path.insert(0, Block())
import fourbar_ros
failed = []
for info in pkgutil.walk_packages(fourbar_ros.__path__, 'fourbar_ros.'):
    if info.name.rpartition('.')[2] in ('__main__', 'run'):  # entry points: they run when imported
        continue
    try:
        importlib.import_module(info.name)
    except ModuleNotFoundError as exc:
        failed.append(f'{info.name}: {exc.name}')
print('failed', *sorted(failed), sep='\\n')
import rclpy
from rclpy.parameter import Parameter
from fourbar_ros.drive.bridge_node import DriveBridge
from fourbar_ros.node.fourbar_node import FourBarNode
rclpy.init()
for mode in ('open_loop', 'trajectory', 'forward'):
    node = FourBarNode(namespace=f'/headless_{mode}', parameter_overrides=[Parameter('mode', value=mode)])
    node.destroy_node()
    print('started', mode)
bridge = DriveBridge(namespace='/headless_bridge')  # the default backend: the simulated drive
bridge.destroy_node()
print('started bridge')
rclpy.shutdown()
"""


def skipped_keys() -> list[str]:
    """The keys of the how-to's ``--skip-keys "..."``."""
    found = re.findall(r'--skip-keys "([^"]+)"', HOWTO.read_text(encoding='utf-8'))
    assert len(found) == 1, f'{HOWTO}: {len(found)} --skip-keys lines'
    return found[0].split()


def test_the_skipped_keys_are_exec_depends_of_desktop_or_simulation_modules() -> None:
    exec_keys = {d.name for d in package().exec_depends}  # type: ignore[attr-defined]
    keys = skipped_keys()
    assert sorted(keys) == sorted(KEY_MODULES), keys
    assert set(keys) <= exec_keys, set(keys) - exec_keys


@pytest.mark.ros
def test_without_the_skipped_modules_the_node_and_the_bridge_start(ros: RosSession) -> None:
    blocked = ' '.join(m for k in skipped_keys() for m in KEY_MODULES[k])
    done = subprocess.run([sys.executable, '-c', SCRIPT, blocked], env=ros.env(), capture_output=True, text=True,
                          timeout=120, check=False)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    lines = done.stdout.splitlines()
    failed = lines[lines.index('failed') + 1:lines.index('started open_loop')]
    assert failed == [f'{m}: mujoco' for m in NEEDS_MUJOCO], done.stdout
    assert lines[-4:] == ['started open_loop', 'started trajectory', 'started forward', 'started bridge'], done.stdout
