"""Shared pytest setup: the helpers of test/support/ importable as ``support.<module>`` from every test folder;
hypothesis made deterministic; ulp jitter; the ``stress`` marker; the session-wide ROS fixtures.

Property tests draw the same examples on every run (derandomize), so CI cannot pass or fail by luck. Set
HYPOTHESIS_PROFILE=explore to search with fresh random examples locally.

``--ulp-jitter`` (or FOURBAR_ULP_JITTER=1) runs the session as if on another CPU: numpy's transcendental ufuncs
(and with ``--ulp-jitter-math`` the math module's functions) move their results by one ulp (see
support/ulp_jitter.py; ``--ulp-jitter-share``, default 1: every element; ``--ulp-jitter-seed``: another choice;
``--ulp-jitter-direction`` hash, up or down; or the FOURBAR_ULP_JITTER_* variables). Only this process is
affected, not the processes a test starts.

``stress`` marks the statistical repeats (a stop case 20 times, soaks, long bursts): a run leaves them out unless
its ``-m`` expression names the marker (``make test-stress`` is ``-m stress``); every case also runs once without it.

Every test process (each pytest-xdist worker, or the lone pytest process) leases a ROS_DOMAIN_ID of its own at
start and runs with ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST (support.isolation): its rclpy session and every child
started from its environment use that domain. A module's processes must end with it: what is left running at
its end is killed and reported as an error (``no_process_outlives_its_module``). SIGINT and SIGQUIT are restored
to their defaults where the run inherited them ignored (a background job's), so the commands the tests interrupt
are interruptible as in a terminal.

Fixtures:
- ``ros``: one rclpy context, client node and executor on the process's domain id (support.ros_support.RosSession).
  Whatever a module created on the client node (subscriptions, publishers, clients, timers, extra nodes) is
  destroyed when the module ends, so the next module starts from the same graph.
- ``colcon_install``: the install base of one colcon build of the package (support.colcon_support).
- ``ros2_cli`` (per module): an environment that sources that install, on its own leased domain id limited to this
  host, with the ros2 daemon started for it (and stopped at the module's end).
- ``lease``: a domain id of one test's own, for processes that must not share the module's domain.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING

import pytest
from hypothesis import settings

sys.path.insert(0, str(Path(__file__).parent))  # test/: the helpers' package ``support``

from support import isolation, ulp_jitter  # found through the path above

if TYPE_CHECKING:
    from support.colcon_support import CliEnv
    from support.ros_support import DomainLease, RosSession

settings.register_profile('deterministic', derandomize=True, deadline=None, print_blob=True)
settings.register_profile('explore', derandomize=False, deadline=None, print_blob=True)
settings.load_profile(os.environ.get('HYPOTHESIS_PROFILE', 'deterministic'))

_undo_jitter: list[Callable[[], None]] = []


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup('fourbar')
    group.addoption('--ulp-jitter', action='store_true', default=os.environ.get('FOURBAR_ULP_JITTER', '') not in
                    ('', '0'), help='move numpy transcendental results by one ulp on a fixed share of elements '
                    '(as another CPU might); also FOURBAR_ULP_JITTER=1')
    group.addoption('--ulp-jitter-share', type=float,
                    default=float(os.environ.get('FOURBAR_ULP_JITTER_SHARE', ulp_jitter.DEFAULT_SHARE)),
                    help=f'share of elements moved (default {ulp_jitter.DEFAULT_SHARE}); also '
                    'FOURBAR_ULP_JITTER_SHARE')
    group.addoption('--ulp-jitter-seed', type=int, default=int(os.environ.get('FOURBAR_ULP_JITTER_SEED', '0')),
                    help='another deterministic choice of the moved elements; also FOURBAR_ULP_JITTER_SEED')
    group.addoption('--ulp-jitter-math', action='store_true',
                    default=os.environ.get('FOURBAR_ULP_JITTER_MATH', '') not in ('', '0'),
                    help='move the math module\'s results too (the scalar paths); also FOURBAR_ULP_JITTER_MATH=1')
    group.addoption('--ulp-jitter-direction', choices=ulp_jitter.DIRECTIONS,
                    default=os.environ.get('FOURBAR_ULP_JITTER_DIRECTION', 'hash'),
                    help='each moved result up or down by a hash, or all up, or all down; also '
                    'FOURBAR_ULP_JITTER_DIRECTION')


def pytest_configure(config: pytest.Config) -> None:
    # Before xdist starts its workers: they, and every command a test starts, get SIGINT as from a terminal.
    isolation.default_stop_signals()
    # Every process that runs tests (each pytest-xdist worker, or the lone pytest process; not xdist's controller)
    # on a ROS domain of its own, discovery limited to this host, before any rclpy context exists.
    if not (getattr(config.option, 'numprocesses', None) and not hasattr(config, 'workerinput')):
        isolation.isolate_process()
    if config.getoption('--ulp-jitter'):
        _undo_jitter.append(ulp_jitter.install(config.getoption('--ulp-jitter-share'),
                                               config.getoption('--ulp-jitter-seed'),
                                               direction=config.getoption('--ulp-jitter-direction'),
                                               math_names=tuple(ulp_jitter.MATH_FUNCS)
                                               if config.getoption('--ulp-jitter-math') else ()))


def pytest_unconfigure(config: pytest.Config) -> None:
    while _undo_jitter:
        _undo_jitter.pop()()
    isolation.release_process()


def pytest_report_header(config: pytest.Config) -> str | None:
    if config.getoption('--ulp-jitter'):
        return (f'ulp jitter: on (share {config.getoption("--ulp-jitter-share")}, seed '
                f'{config.getoption("--ulp-jitter-seed")}, direction {config.getoption("--ulp-jitter-direction")}): '
                f'numpy{" and math" if config.getoption("--ulp-jitter-math") else ""} transcendentals moved by '
                'one ulp')
    return None


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Leave out the ``stress`` items unless the ``-m`` expression names the marker."""
    if 'stress' in (config.option.markexpr or ''):
        return
    kept, stress = [], []
    for item in items:
        (stress if item.get_closest_marker('stress') else kept).append(item)
    if stress:
        config.hook.pytest_deselected(items=stress)
        items[:] = kept


@pytest.fixture(scope='module', autouse=True)
def no_process_outlives_its_module() -> Iterator[None]:
    """Every process a module started (node, ros2 command, launch) has ended with it: what is left is killed
    (its process group first) and the module's last test errors, naming it."""
    leftovers = isolation.Leftovers()
    yield
    left = leftovers.end()
    if left:
        pytest.fail(f'processes started by this module were still running at its end (killed now): {left}',
                    pytrace=False)


@pytest.fixture(scope='session')
def ros_session() -> Iterator[RosSession]:
    """The one rclpy session of this run (use ``ros``, which also cleans up after each module)."""
    from support.ros_support import RosSession

    with RosSession(lease=isolation.process_lease()) as session:  # None (a domain of its own) without one
        yield session


@pytest.fixture(scope='module')
def ros(ros_session: RosSession) -> Iterator[RosSession]:
    """The session's rclpy context on its leased domain id; what the module adds to it is removed at its end."""
    before = ros_session.entities()
    yield ros_session
    ros_session.destroy_entities_since(before)


@pytest.fixture
def lease() -> Iterator[DomainLease]:
    """A ROS_DOMAIN_ID of this test's own, for a process the test starts (released at its end)."""
    from support.ros_support import lease_domain_id

    held = lease_domain_id()
    try:
        yield held
    finally:
        held.release()


@pytest.fixture(scope='session')
def colcon_install(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Install base (``.../install``) of the one colcon build of this run; skips without colcon."""
    from support.colcon_support import colcon_install as build_once

    return build_once(tmp_path_factory)


@pytest.fixture(scope='module')
def ros2_cli(colcon_install: Path, tmp_path_factory: pytest.TempPathFactory) -> Iterator[CliEnv]:
    """The sourced install's environment for the ros2 command line, on a domain of this module's own, with its
    daemon (stopped when the module ends); skips without ros2."""
    from support.colcon_support import cli_env

    with cli_env(colcon_install, tmp_path_factory) as env:
        yield env
