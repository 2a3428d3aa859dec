"""Timing on a shared, noisy machine: interleaved repeats, medians, ratios against baselines of the same run.

Each repeat round times every case once, in the same order, so a burst of load from another process hits all cases
of that round alike; the reported figure is the median over rounds of the process's CPU time (wall time beside
it). Also the CPU time of another process (from /proc) and the machine the figures were measured on.
"""

from __future__ import annotations

import os
import platform
import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np


@dataclass
class Case:
    """A timed case: ``run()`` performs ``count`` solves."""

    name: str
    run: Callable[[], object]
    count: int


def pilot(fn: Callable[[], object]) -> float:
    """Seconds for one call (the fastest of three, after one warm-up)."""
    fn()
    best = float('inf')
    for _ in range(3):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def interleaved(cases: list[Case], repeats: int) -> dict[str, tuple[float, float]]:
    """(CPU, wall) median seconds per solve of each case over ``repeats`` interleaved rounds, after a warm-up round.

    CPU time (this process's, CLOCK_PROCESS_CPUTIME_ID) leaves out the time the scheduler gives to other
    processes on the shared cores, so it is the steadier figure; wall time is reported beside it.
    """
    cpu: dict[str, list[float]] = {c.name: [] for c in cases}
    wall: dict[str, list[float]] = {c.name: [] for c in cases}
    for c in cases:
        c.run()
    for _ in range(repeats):
        for c in cases:
            w0 = time.perf_counter()
            c0 = time.process_time()
            c.run()
            c1 = time.process_time()
            w1 = time.perf_counter()
            cpu[c.name].append((c1 - c0) / c.count)
            wall[c.name].append((w1 - w0) / c.count)
    return {name: (statistics.median(cpu[name]), statistics.median(wall[name])) for name in cpu}


def scalar_loop(fn: Callable[[float], object], thetas: list[float]) -> Callable[[], object]:
    """A closure calling fn on every angle of a Python list (the loop overhead is in every scalar figure alike)."""

    def run() -> None:
        for t in thetas:
            fn(t)

    return run


def percentile(values: list[float], q: float) -> float:
    """The value at quantile q (0..1) of ``values``, nearest rank."""
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, round(q * (len(ordered) - 1)))]


def round_trips_us(seconds: list[float]) -> dict[str, float]:
    """Median and p99 of round trips given in seconds, in microseconds."""
    return {'median_us': 1e6 * statistics.median(seconds), 'p99_us': 1e6 * percentile(seconds, 0.99)}


def cpu_seconds(pid: int, thread: int | str | None = None) -> float | None:
    """User + system CPU seconds so far of process ``pid`` (all its threads), or of one of its threads; None
    without /proc or once it ended."""
    path = f'/proc/{pid}/stat' if thread is None else f'/proc/{pid}/task/{thread}/stat'
    try:
        with open(path, encoding='ascii', errors='replace') as f:
            fields = f.read().rsplit(')', 1)[1].split()
    except OSError:
        return None
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def machine_info() -> dict[str, object]:
    """What the figures were measured on: the interpreter, numpy, CPU, load, and BLAS-related variables."""
    cpu = platform.processor() or platform.machine()
    try:
        with open('/proc/cpuinfo', encoding='utf-8') as fh:
            cpu = next((line.split(':', 1)[1].strip() for line in fh if line.startswith('model name')), cpu)
    except OSError:
        pass
    return {
        'python': platform.python_version(),
        'numpy': np.__version__,
        'cpu': cpu,
        'cores': os.cpu_count(),
        'load_average_1min': os.getloadavg()[0],
        'env': {k: os.environ.get(k) for k in ('OPENBLAS_CORETYPE', 'OPENBLAS_L2_SIZE', 'OMP_NUM_THREADS')},
        'note': 'shared machine (2 cores, other work running); figures are medians of interleaved repeats '
                'and only ratios measured in the same run are meaningful',
    }
