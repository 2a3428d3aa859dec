"""A colcon-built install of this package, built once per test run, and the environment that sourcing
its setup script gives a child process (plus a leased ROS domain limited to this host).

conftest.py's session fixtures ``colcon_install`` and ``ros2_cli`` are built on ``colcon_install()`` and
``cli_env()``; every test that needs the install (packaging, ``ros2 run``/``topic``/``param``, ``ros2 launch``,
launch_testing, ``ros2 run ... demo``) shares that one build and, for the ros2 command line, one daemon.
"""

from __future__ import annotations

import fcntl
import importlib.util
import os
import shutil
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import pytest

from support.isolation import isolated_env
from support.paths import REPO
from support.ros2_control_support import with_ros2_control

#: What a source checkout of the package contains that its build reads.
PACKAGE_FILES = ('package.xml', 'setup.py', 'setup.cfg', 'resource', 'fourbar_ros', 'config', 'launch', 'rviz')
BIN = Path(sys.executable).parent

def colcon_install(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Install base (``.../install``) of a colcon build of a copy of the package; skip without colcon.

    Built once per run: pytest-xdist's workers share the directory above their own temporary roots, and the first
    to get its lock builds there while the others wait (a failed build is written down, so each fails fast)."""
    colcon = BIN / 'colcon'
    if not colcon.exists():
        pytest.skip('colcon is not installed in this environment (pip install colcon-core colcon-ros)')
    base = tmp_path_factory.getbasetemp()
    root = base.parent if os.environ.get('PYTEST_XDIST_WORKER') else base
    ws = root / 'colcon_ws'
    failed = root / 'colcon_build_failed.txt'
    with open(root / 'colcon_build.lock', 'w') as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes
        if failed.exists():
            pytest.fail(failed.read_text(encoding='utf-8'))
        if not (ws / 'built').exists():
            error = _build(colcon, ws)
            if error:
                failed.write_text(error, encoding='utf-8')
                pytest.fail(error)
    return ws / 'install'


def _build(colcon: Path, ws: Path) -> str | None:
    """Build a copy of the package in ``ws``; the error, or None."""
    src = ws / 'src' / 'fourbar_ros'
    shutil.rmtree(ws, ignore_errors=True)
    src.mkdir(parents=True)
    for name in PACKAGE_FILES:
        path = REPO / name
        if path.is_dir():
            shutil.copytree(path, src / name, ignore=shutil.ignore_patterns('__pycache__', '*.pyc'))
        else:
            shutil.copy2(path, src / name)
    result = subprocess.run(
        [str(colcon), '--log-base', str(ws / 'log'), 'build', '--base-paths', str(ws / 'src'),
         '--build-base', str(ws / 'build'), '--install-base', str(ws / 'install')],
        cwd=ws, capture_output=True, text=True, timeout=600, check=False)
    if result.returncode != 0:
        return 'colcon build failed: ' + result.stdout[-3000:] + result.stderr[-3000:]
    log = (ws / 'log' / 'latest_build' / 'logger_all.log').read_text(encoding='utf-8')
    # Without a valid package.xml colcon silently builds a plain Python package instead.
    if "with type 'ros.ament_python' and name 'fourbar_ros'" not in log:
        return 'colcon did not build fourbar_ros as ros.ament_python'
    (ws / 'built').touch()
    return None


def sourced_env(base: dict[str, str], prefix: Path, domain_id: int, localhost: bool = True) -> dict[str, str]:
    """``base`` plus what sourcing ``install/setup.sh`` sets for this package (PYTHONPATH, AMENT_PREFIX_PATH,
    PATH with this venv's ``ros2``) and the real ros2_control stack where one is named, on ``domain_id``; with
    ``localhost``, discovery limited to this host (all processes that must see each other need the same setting:
    every test process has it (support.isolation), so ``localhost=False`` only keeps what ``base`` says)."""
    site = prefix / 'lib' / f'python{sys.version_info.major}.{sys.version_info.minor}' / 'site-packages'
    env = with_ros2_control(dict(base))
    env['PYTHONPATH'] = os.pathsep.join(filter(None, [str(site), env.get('PYTHONPATH', '')]))
    env['AMENT_PREFIX_PATH'] = os.pathsep.join(filter(None, [str(prefix), env.get('AMENT_PREFIX_PATH', '')]))
    env['PATH'] = os.pathsep.join(filter(None, [str(BIN), env.get('PATH', '')]))
    env['ROS_DOMAIN_ID'] = str(domain_id)
    if localhost:
        env = isolated_env(env, domain_id)  # also drops ROS_LOCALHOST_ONLY (deprecated in Jazzy; it would override)
    env.setdefault('PYTHONUNBUFFERED', '1')
    env['RCUTILS_COLORIZED_OUTPUT'] = '0'
    return env


def ros2_cli_missing() -> str | None:
    """Why the ros2 command line cannot be used here (None when it can)."""
    if importlib.util.find_spec('ros2cli') is None or not ((BIN / 'ros2').exists() or shutil.which('ros2')):
        return ('the ros2 command line is not installed (source a ROS 2 Jazzy install, or run '
                'scripts/install_ros_cli.sh WHEEL_DIR)')
    return None


def launch_missing() -> str | None:
    """Why launch_ros / launch_testing cannot be used here (None when they can)."""
    missing = [m for m in ('launch', 'launch_ros', 'launch_testing', 'ros2launch')
               if importlib.util.find_spec(m) is None]
    if missing:
        return (f'{", ".join(missing)} not installed (source a ROS 2 Jazzy install, or run '
                'scripts/install_ros_cli.sh WHEEL_DIR)')
    return None


def ros2() -> str:
    """The ros2 executable: this venv's, else the one on PATH."""
    exe = BIN / 'ros2'
    return str(exe) if exe.exists() else str(shutil.which('ros2'))


@dataclass(frozen=True)
class CliEnv:
    """The sourced install for the ros2 command line: ``env`` (on a leased domain id, discovery limited to this
    host, ROS_HOME in a temporary directory), the package's install ``prefix`` and an empty working directory."""

    env: dict[str, str]
    prefix: Path
    cwd: Path


@contextmanager
def cli_env(install: Path, tmp_path_factory: pytest.TempPathFactory) -> Iterator[CliEnv]:
    """``CliEnv`` over ``install`` on a leased domain id (a module's own: conftest's ``ros2_cli``), with the ros2
    daemon started for it; the daemon is stopped and the id given back on leaving. Skips where the ros2 command line
    is missing."""
    if (why := ros2_cli_missing()) is not None:
        pytest.skip(why)
    from support.ros_support import lease_domain_id

    prefix = install / 'fourbar_ros'
    lease = lease_domain_id()
    env = sourced_env(dict(os.environ), prefix, lease.domain_id)
    env['ROS_HOME'] = str(tmp_path_factory.mktemp('ros_home'))  # logs of this run, not ~/.ros
    from support.ros_cli_support import start_daemon, stop_daemon  # psutil: with ros2cli

    try:
        start_daemon(env, Path(env['ROS_HOME']) / 'ros2_daemon.log', timeout=60)
        yield CliEnv(env, prefix, tmp_path_factory.mktemp('anywhere'))
    finally:
        try:
            stop_daemon(env, timeout=60)  # before the domain is given back
        finally:
            lease.release()
