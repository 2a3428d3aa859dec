"""`fourbar process` against a plain rosbags copy of the same command bag, same run; peak memory.

    .venv/bin/python -m benchmarks.process_bench [--rounds 3] [--storage mcap]
    .venv/bin/python -m benchmarks.process_bench --memory 200000 2000000

- copy: rosbags reads every raw message of a 200,000-command bag and writes it to a new bag (same storage),
  nothing decoded: the least any tool that rewrites the bag must spend;
- process: ``fourbar_ros.bags.process.process_bag`` (what `fourbar process IN OUT` runs) with
  config/antenna.yaml: every command read, decided, solved, a JointState and a Float64 written per command
  (twice the messages of the copy);
- ratio process/copy from the medians over ``--rounds`` interleaved rounds (copy, process, copy, ...),
  every round listed. Target: <= 2.
- ``--memory N...``: peak RSS (VmHWM) of a fresh Python process that imports the package and then
  processes, or copies, an N-command bag; the difference between N shows whether memory grows with the bag.

Figures printed as JSON. The bag is a deterministic sweep over the tilt range at 100 Hz written to a temporary
directory (with the block CDR encoder, so a 2,000,000-command bag takes seconds). No figure is asserted by a test.
"""

from __future__ import annotations

import argparse
import json
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from benchmarks import CONFIG, REPO, print_json
from fourbar_ros.interface.stamps import NS_PER_S
from fourbar_ros.interface.topics import DEFAULT_STORAGE, Storage

T0_NS = 1_700_000_000 * NS_PER_S
BLOCK = 65536  #: messages encoded at a time


def make_bag(path: Path, n: int, storage: Storage, bad_every: int = 1000) -> Path:
    """``n`` commands sweeping theta_min -> theta_max -> theta_min (period 200) at 100 Hz; every ``bad_every``-th
    a NaN (the policy path too; 0: none)."""
    import numpy as np

    from fourbar_ros.bags.storage import FLOAT64, AtomicBagWriter, recorded_qos
    from fourbar_ros.config.antenna_config import load_config
    from fourbar_ros.interface.cdr import encode_float64s

    cfg = load_config(CONFIG)
    k = np.arange(n)
    phase = (k % 200) / 100.0
    frac = np.where(phase <= 1.0, phase, 2.0 - phase)
    values = cfg.theta_min + (cfg.theta_max - cfg.theta_min) * frac
    if bad_every:
        values[k % bad_every == bad_every - 1] = np.nan
    stamps = (T0_NS + k * 10_000_000).tolist()
    with AtomicBagWriter(path, storage) as bag:
        conn = bag.add_topic('/antenna_angle_cmd', FLOAT64, [recorded_qos()])
        for start in range(0, n, BLOCK):
            for stamp, raw in zip(stamps[start:start + BLOCK], encode_float64s(values[start:start + BLOCK]),
                                  strict=True):
                bag.write(conn, stamp, raw)
    return path


def copy_bag(src: Path, dst: Path, storage: Storage) -> int:
    """Read every raw message with rosbags and write it to a new bag; the number of messages."""
    from rosbags.rosbag2 import Reader, Writer

    from fourbar_ros.bags.storage import jazzy_typestore
    from fourbar_ros.bags.storage.adapters import adapter

    plugin = adapter(storage).plugin
    count = 0
    with Reader(src) as reader, Writer(dst, version=9, storage_plugin=plugin) as writer:
        conns = {c.id: writer.add_connection(c.topic, c.msgtype, typestore=jazzy_typestore())
                 for c in reader.connections}
        for conn, stamp, data in reader.messages():
            writer.write(conns[conn.id], stamp, data)
            count += 1
    return count


def process(src: Path, dst: Path, storage: Storage) -> int:
    """`fourbar process SRC DST --params config/antenna.yaml --storage STORAGE`; the commands processed."""
    from fourbar_ros.bags.process import process_bag
    from fourbar_ros.config.antenna_config import load_config

    return process_bag(src, dst, load_config(CONFIG), storage=storage).commands


KINDS: dict[str, Callable[[Path, Path, str], int]] = {'copy': copy_bag, 'process': process}


def timed(kind: str, src: Path, out: Path, storage: Storage) -> float:
    """Seconds of one copy or process into ``out`` (removed before and after)."""
    shutil.rmtree(out, ignore_errors=True)
    start = time.perf_counter()
    KINDS[kind](src, out, storage)
    seconds = time.perf_counter() - start
    shutil.rmtree(out, ignore_errors=True)
    return seconds


def speed(n: int, rounds: int, storage: Storage) -> dict[str, Any]:
    """Interleaved rounds of copy and process on one n-command bag."""
    with tempfile.TemporaryDirectory(prefix='process_bench.') as tmp:
        bag = make_bag(Path(tmp) / 'commands', n, storage)
        out = Path(tmp) / 'out'
        timed('process', bag, out, storage)  # warm-up: imports, page cache
        times: dict[str, list[float]] = {'copy': [], 'process': []}
        for _ in range(rounds):
            for kind, row in times.items():
                row.append(timed(kind, bag, out, storage))
    copy_s, process_s = statistics.median(times['copy']), statistics.median(times['process'])
    return {'commands': n, 'storage': storage.value, 'rounds': rounds, 'copy_s': times['copy'],
            'process_s': times['process'], 'copy_median_s': copy_s, 'process_median_s': process_s,
            'ratio': process_s / copy_s}


def child(kind: str, src: Path, dst: Path, storage: Storage) -> None:
    """Run one copy or process in this (fresh) process and print its peak RSS.

    VmHWM, not getrusage's ru_maxrss: Linux carries the parent's peak at fork into a child's ru_maxrss even after
    exec, so a child started by a big parent would report that."""
    import fourbar_ros.bags.process  # noqa: F401  (the same imports in both kinds)

    seconds = timed(kind, src, dst, storage)
    peak = next(line for line in Path('/proc/self/status').read_text().splitlines() if line.startswith('VmHWM:'))
    print(json.dumps({'kind': kind, 'seconds': seconds, 'max_rss_mib': int(peak.split()[1]) / 1024}))


def memory(sizes: list[int], storage: Storage) -> list[dict[str, Any]]:
    """Peak RSS of a fresh process copying and processing each size."""
    rows = []
    for n in sizes:
        with tempfile.TemporaryDirectory(prefix='process_bench.') as tmp:
            bag = make_bag(Path(tmp) / 'commands', n, storage)
            for kind in KINDS:
                done = subprocess.run([sys.executable, '-m', 'benchmarks.process_bench', '--child', kind,
                                       str(bag), str(Path(tmp) / kind), '--storage', storage.value],
                                      cwd=REPO, capture_output=True, text=True, check=True)
                rows.append({**json.loads(done.stdout.strip().splitlines()[-1]), 'commands': n})
    return rows


def run(quick: bool) -> dict[str, Any]:
    """For ``python -m benchmarks.run``: the speed ratio and peak memory (at two bag sizes in a full run)."""
    n, rounds = (20_000, 3) if quick else (200_000, 5)
    figures: dict[str, Any] = {'speed': speed(n, rounds, DEFAULT_STORAGE)}
    figures['process_over_copy_ratio'] = figures['speed']['ratio']
    figures['memory'] = {f'{r["kind"]}_{r["commands"]}_peak_rss_mib': r['max_rss_mib']
                         for r in memory([20_000] if quick else [200_000, 2_000_000], DEFAULT_STORAGE)}
    return figures


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or '').splitlines()[0])
    parser.add_argument('--rounds', type=int, default=3)
    parser.add_argument('--storage', type=Storage, choices=tuple(Storage), default=DEFAULT_STORAGE)
    parser.add_argument('--memory', type=int, nargs='+', metavar='N', help='peak RSS for these bag sizes')
    parser.add_argument('--child', nargs=3, metavar=('KIND', 'IN', 'OUT'), help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        child(args.child[0], Path(args.child[1]), Path(args.child[2]), args.storage)
        return 0
    return print_json(memory(args.memory, args.storage) if args.memory else speed(200_000, args.rounds, args.storage))


if __name__ == '__main__':
    sys.exit(main())
