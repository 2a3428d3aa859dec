"""The ROS quick start of README.md and its pip-only first terminal (docs/how-to/without-ros.md), run as typed and
in the documented order with the real ``ros2`` command line over the session's colcon build: terminal 1 builds (the
session's build stands in, see SETUP) and starts the node; terminal 2 waits with ``ros2 topic echo --once``;
terminal 3 publishes a command and sets parameters.

The blocks are those marked ``<!--pytest.mark.quickstart-->``. Each terminal is a bash that first does what the
document tells the reader to do in a new terminal (this environment activated, ``source ~/ws/install/setup.bash``)
unless the block sources the workspace itself; HOME is a temporary directory whose ``ws`` is the session's
workspace, so ``~/ws`` resolves. The pub line is repeated (as typed) while the echo has not printed, until a
deadline: discovery is not symmetric, and the node may not see the echo's subscription when the first command
arrives; the node's periodic republishing of the last pose also ends the echo.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import time
from pathlib import Path

import pytest
from support.colcon_support import colcon_install, ros2, ros2_cli_missing
from support.paths import REPO

if (_why := ros2_cli_missing()) is not None:
    pytest.skip(_why, allow_module_level=True)
pytest.importorskip('pytest_codeblocks', reason='the quick start is read from Markdown with pytest-codeblocks')
from pytest_codeblocks import extract_from_file
from support.ros_cli_support import (  # psutil: with ros2cli
    TIMEOUT,
    Background,
    daemon_log,
    daemon_state,
    echoed_messages,
    run,
    start_daemon,
    stop_daemon,
    wait_node,
)
from support.ros_support import DomainLease

pytestmark = [pytest.mark.ros, pytest.mark.slow]

#: Documented lines this environment has done already, and what the test runs instead (None: nothing).
SETUP: dict[str, str | None] = {
    # The session's workspace holds a copy of this checkout in src/fourbar_ros (colcon_support.PACKAGE_FILES).
    'cd ~/ws/src && git clone <this repository> fourbar_ros && cd ~/ws': 'cd ~/ws',
    'mkdir -p ~/ws/src && cd ~/ws/src && git clone <this repository> fourbar_ros && cd fourbar_ros':
        'cd ~/ws/src/fourbar_ros',
    # rosdep resolves no key here (no apt); test_rosdep_keys.py checks every key against the Jazzy list.
    'rosdep install --from-paths src --ignore-src -y --rosdistro jazzy': None,
    # This environment is that venv with the command line installed (.venv below links to it).
    'scripts/bootstrap.sh && scripts/install_ros_cli.sh WHEEL_DIR': None,
    # One colcon build per session (colcon_support); `colcon list` checks the same package selection, which
    # needs colcon-package-selection (colcon-common-extensions) as the documented build line does.
    'colcon build --packages-select fourbar_ros && source install/setup.bash':
        'colcon list --packages-select fourbar_ros && source install/setup.bash',
}
LONG_RUNNING = ('ros2 run ', 'ros2 topic echo ')


def commands(code: str) -> list[str]:
    """A block's commands: continuation lines joined, as bash reads them."""
    return [line.strip() for line in code.replace('\\\n', ' ').splitlines() if line.strip()]


def quickstart(path: Path) -> list[list[str]]:
    """The quick-start blocks of a document, in order, as lists of commands."""
    return [commands(b.code) for b in extract_from_file(path) if any('quickstart' in m for m in b.marks)]


def script(lines: list[str]) -> str:
    """The block as the test runs it: setup lines replaced (SETUP); a terminal that does not source the workspace
    itself starts as the document says a new terminal does."""
    out = [SETUP.get(' '.join(line.split('#')[0].split()), line) for line in lines]
    body = [line for line in out if line is not None]
    if not any('source install/setup.bash' in line for line in body):
        body.insert(0, 'source ~/ws/install/setup.bash')
    return '\n'.join([f'source {sys.prefix}/bin/activate', *body])


@pytest.fixture(scope='module')
def home(tmp_path_factory: pytest.TempPathFactory) -> Path:
    install = colcon_install(tmp_path_factory)
    home = tmp_path_factory.mktemp('home')
    (home / 'ws').symlink_to(install.parent)
    venv = install.parent / 'src' / 'fourbar_ros' / '.venv'  # the pip-only block activates it from the clone
    if not venv.exists():
        venv.symlink_to(Path(sys.prefix))
    return home


def _env(home: Path, lease: DomainLease) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in ('AMENT_PREFIX_PATH', 'COLCON_PREFIX_PATH')}
    env.update(HOME=str(home), ROS_DOMAIN_ID=str(lease.domain_id), ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST',
               ROS_HOME=str(home / 'ros_home'), PYTHONUNBUFFERED='1', RCUTILS_COLORIZED_OUTPUT='0')
    env.pop('ROS_LOCALHOST_ONLY', None)
    return env


def run_terminals(terminals: list[list[str]], env: dict[str, str], home: Path, log: Path) -> tuple[str, str]:
    """Run the terminals in order; return (echo output, last terminal's output). Node and echo stay in the
    background; the last terminal runs to completion, its pub line repeated until the echo has printed. The ros2
    daemon's output goes to ``log``."""
    background: list[Background] = []
    try:
        started = start_daemon(env, log)  # what wait_node asks (stopped below)
        node, echo = None, None
        for lines in terminals[:-1]:
            assert lines[-1].startswith(LONG_RUNNING), lines
            proc = Background(['bash', '-e', '-c', script(lines)], env, cwd=home)
            background.append(proc)
            if lines[-1].startswith('ros2 run '):
                node = proc
                proc.wait_output(lambda text: 'callbacks run on the' in text, 'the node to start')
                # A reader types terminal 3 seconds later; `ros2 param set` finds the node through the ros2
                # daemon's graph, which learns of it by discovery some time after it starts ("Node not found").
                ns = re.search(r'__ns:=(\S+)', lines[-1])
                wait_node(env, f'{ns.group(1) if ns else ""}/fourbar_node')
            else:
                echo = proc
        assert node is not None and echo is not None, terminals
        last = terminals[-1]
        out = subprocess.run(['bash', '-e', '-c', script(last)], env=env, cwd=home, capture_output=True, text=True,
                             timeout=TIMEOUT * 3, check=False, stdin=subprocess.DEVNULL)
        assert out.returncode == 0, (f'terminal 3 exited {out.returncode}:\n{out.stdout}{out.stderr}'
                                     f'{graph_report(env, node, started, log)}')
        pub = next(line for line in last if line.startswith('ros2 topic pub '))
        deadline = time.monotonic() + TIMEOUT
        while echo.proc.poll() is None:
            assert time.monotonic() < deadline, f'the echo printed nothing:\n{echo.output()[-2000:]}'
            again = subprocess.run(['bash', '-e', '-c', script([pub])], env=env, cwd=home, capture_output=True,
                                   text=True, timeout=TIMEOUT, check=False, stdin=subprocess.DEVNULL)
            assert again.returncode == 0, again.stdout + again.stderr
        assert echo.wait_exit() == 0, echo.stderr
        assert node.interrupt(group=True) == 0, node.stderr[-3000:]  # Ctrl-C in terminal 1
        assert 'Traceback' not in node.stderr
        return echo.stdout, out.stdout + out.stderr
    finally:
        for proc in background:
            proc.kill()
        stop_daemon(env, timeout=30)


def graph_report(env: dict[str, str], node: Background, started: str, log: Path) -> str:
    """What the other sides saw, for a failure: the node process's state and last output, the ros2 daemon's start
    (``start_daemon``'s report), its own output, the domain's daemons and who holds the daemon's port now, this
    process's group, and the daemon's status and node list (the graph `ros2 param` reads) at this moment."""
    state = 'running' if node.proc.poll() is None else f'exited {node.proc.returncode}'
    tail = node.output().strip().splitlines()[-12:]
    daemons = (f'\nros2 daemon start on domain {env.get("ROS_DOMAIN_ID")}: {started}\nnow: {daemon_state(env)}; '
               f'this test process {os.getpid()} in process group {os.getpgid(0)}'
               f'\nros2 daemon output (start --debug), last lines:\n  ' + daemon_log(log).replace('\n', '\n  '))
    status = run([ros2(), 'daemon', 'status'], env, timeout=30)
    listed = run([ros2(), 'node', 'list'], env, timeout=30)
    return (f'\nnode terminal ({state}), last lines:\n  ' + '\n  '.join(tail) + daemons
            + f'\nros2 daemon status: {(status.stdout + status.stderr).strip()}'
            + f'\nros2 node list: {(listed.stdout + listed.stderr).split()}')


def _check(echo: str, last: str) -> None:
    messages = echoed_messages(echo)
    assert messages, f'no message in the echo\'s output:\n{echo}'
    msg = messages[0]
    assert msg['name'] == ['rocker_ab_joint', 'rocker_cd_joint', 'coupler_joint'], echo
    assert len(msg['position']) == 3, echo
    assert 'Set parameter successful' in last, last
    assert 'Setting parameter failed' in last, last  # theta_max 1.5: out of reach


def test_readme_quickstart_runs_as_typed(home: Path, lease: DomainLease, tmp_path: Path) -> None:
    terminals = quickstart(REPO / 'README.md')
    assert len(terminals) == 3, terminals
    echo, last = run_terminals(terminals, _env(home, lease), home, tmp_path / 'ros2_daemon.log')
    _check(echo, last)


def test_pip_only_quickstart_runs_as_typed(home: Path, lease: DomainLease, tmp_path: Path) -> None:
    """docs/how-to/without-ros.md: its pip-only block is a terminal 1 of its own, ending in README's node line,
    followed by README's echo and pub terminals."""
    [pip_only] = quickstart(REPO / 'docs' / 'how-to' / 'without-ros.md')
    readme = quickstart(REPO / 'README.md')
    assert pip_only[-1] == readme[0][-1]
    echo, last = run_terminals([pip_only, readme[1], readme[2]], _env(home, lease), home,
                               tmp_path / 'ros2_daemon.log')
    _check(echo, last)
