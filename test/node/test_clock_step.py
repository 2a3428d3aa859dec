"""fourbar_node's periodic work keeps its rate when the system clock steps (NTP, a virtual machine resumed).

The node runs as a process, as a user starts it, with an LD_PRELOAD shim (support/clock_step_shim.c, built here with
the C compiler) in its environment only: the shim offsets that process's realtime clock by an amount the test
rewrites mid-run, and moves the realtime deadlines of the waits in progress as a real step does. The test steps the
clock 30 s back, then 30 s forward again, and counts the diagnostics (0.2 s period) that arrive within a deadline on
its own steady clock: a node whose timers follow the system clock, or whose executor waits on system-clock
deadlines, sends nothing for the 30 s after the backward step.
"""

from __future__ import annotations

import contextlib
import shutil
import signal
import struct
import subprocess
import time
from pathlib import Path

import pytest
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.clock_type import ClockType
from rclpy.node import Node
from support.paths import REPO
from support.ros_support import Collector, NodeProcess, RosSession, wait_for

from fourbar_ros.node.timers import periodic_timer, work_clock
from fourbar_ros.runtime.executor import EXECUTOR_ENV, EXECUTORS, StallWatch, create_executor

pytestmark = [pytest.mark.ros, pytest.mark.slow]

YAML = REPO / 'config' / 'antenna.yaml'
SHIM_SOURCE = Path(__file__).parents[1] / 'support' / 'clock_step_shim.c'
DIAGNOSTICS_PERIOD_S = 0.2
STEP_S = 30.0
#: Diagnostics that must arrive after each step ...
AFTER_STEP = 10
#: ... within this time on the test's steady clock: 2 s at the period plus a few seconds of recovery (the node
#: restarts stalled waits within a second or two) and slack for a busy machine; far below the 30 s a stalled timer
#: would wait.
AFTER_STEP_DEADLINE_S = 15.0


@pytest.fixture(scope='module')
def shim(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The shim built into a temporary directory; the tests skip where it cannot be built."""
    compiler = shutil.which('cc') or shutil.which('gcc')
    if compiler is None:
        pytest.skip('no C compiler (cc or gcc) to build the clock-step shim')
    out = tmp_path_factory.mktemp('clock_step') / 'clock_step_shim.so'
    build = subprocess.run([compiler, '-shared', '-fPIC', '-O2', '-o', str(out), str(SHIM_SOURCE), '-ldl'],
                           capture_output=True, text=True, check=False)
    if build.returncode != 0:
        pytest.skip(f'the clock-step shim does not build here: {build.stderr.strip()[-300:]}')
    return out


class ClockStep:
    """The offset file the shim reads: ``step(s)`` sets the child's realtime clock to real time plus ``s``."""

    def __init__(self, path: Path) -> None:
        self.path = path
        path.write_bytes(struct.pack('<q', 0))

    def step(self, offset_s: float) -> None:
        with self.path.open('r+b') as f:
            f.write(struct.pack('<q', round(offset_s * 1e9)))


def stamp_s(msg: DiagnosticArray) -> float:
    return float(msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9)


def arrivals_within(diag: Collector[DiagnosticArray], count: int, deadline_s: float) -> tuple[int, float]:
    """Wait until ``diag`` holds ``count`` messages or the deadline passed; (how many, seconds waited)."""
    start = time.monotonic()
    with contextlib.suppress(AssertionError):  # the deadline: the caller reports how many came
        diag.wait_count(count, timeout=deadline_s)
    return len(diag), time.monotonic() - start


@pytest.mark.parametrize('executor', EXECUTORS)
def test_timers_keep_their_rate_across_realtime_steps(ros: RosSession, shim: Path, tmp_path: Path,
                                                      executor: str) -> None:
    clock = ClockStep(tmp_path / 'realtime_offset')
    topic = f'/clock_step_{executor}/diagnostics'
    diag = ros.collect(DiagnosticArray, topic)
    env = ros.env(**{EXECUTOR_ENV: executor, 'LD_PRELOAD': str(shim), 'CLOCK_STEP_FILE': str(clock.path)})
    args = ['--ros-args', '--params-file', str(YAML), '-r', f'__ns:=/clock_step_{executor}',
            '-r', f'/diagnostics:={topic}', '-p', f'diagnostics_period:={DIAGNOSTICS_PERIOD_S}']
    try:
        with NodeProcess(args, env) as node:
            diag.wait_count(2)  # running, and the subscription matched
            before = len(diag)

            clock.step(-STEP_S)
            stepped_at = time.time()
            got, took = arrivals_within(diag, before + AFTER_STEP, AFTER_STEP_DEADLINE_S)
            assert got >= before + AFTER_STEP, (
                f'{got - before} diagnostics in {took:.1f} s after a {STEP_S:g} s backward step of the system clock '
                f'(period {DIAGNOSTICS_PERIOD_S:g} s): the timers stalled')
            # The step really happened in the node: its stamps (system time) went back.
            assert stamp_s(diag.messages[-1]) < stepped_at - STEP_S / 2, 'the shim did not step the node clock'

            before = len(diag)
            clock.step(0.0)
            got, took = arrivals_within(diag, before + AFTER_STEP, AFTER_STEP_DEADLINE_S)
            assert got >= before + AFTER_STEP, (
                f'{got - before} diagnostics in {took:.1f} s after a {STEP_S:g} s forward step: the timers stalled')
            assert abs(stamp_s(diag.messages[-1]) - time.time()) < STEP_S / 2

            assert node.stop(signal.SIGINT) == 0, node.stderr
    finally:
        ros.uncollect(diag)


@pytest.mark.parametrize('executor', EXECUTORS)
def test_the_stall_watch_restarts_an_overdue_steady_timer(ros: RosSession, executor: str) -> None:
    """A steady timer whose call is overdue by more than the check interval (nothing spins here) is found stalled;
    on the EventsExecutor it is reset (its next call is then in the future)."""
    node = Node('stall_watch_probe', context=ros.context)
    spinner = create_executor(executor, context=ros.context)
    try:
        spinner.add_node(node)
        timer = periodic_timer(node, 0.001, lambda: None)
        assert timer.clock.clock_type == ClockType.STEADY_TIME
        assert work_clock(node) is timer.clock  # one steady clock per node
        watch = StallWatch(spinner, check_s=0.05)
        assert watch.check() == 0
        wait_for(lambda: (timer.time_until_next_call() or 0) < -100_000_000, what='the timer to be overdue')
        assert watch.check() == 1
        if executor == 'events':
            assert timer.time_until_next_call() > 0
        with watch.running():
            pass  # the thread starts and ends with the block
    finally:
        spinner.shutdown(timeout_sec=1.0)
        node.destroy_node()
