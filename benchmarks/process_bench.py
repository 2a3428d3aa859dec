"""`fourbar process` against a plain rosbags copy of the same command bag, same run; peak memory.

    .venv/bin/python -m benchmarks.process_bench [--commands 200000] [--rounds 3] [--storage mcap]
    .venv/bin/python -m benchmarks.process_bench --memory 200000 2000000

- copy: rosbags reads every raw message of the bag and writes it to a new bag (same storage), nothing
  decoded: the least any tool that rewrites the bag must spend;
- process: ``fourbar_ros.bags.process.process_bag`` (what `fourbar process IN OUT` runs) with
  config/antenna.yaml: every command read, decided, solved, a JointState and a Float64 written per command
  (twice the messages of the copy);
- ratio process/copy from the medians over ``--rounds`` interleaved rounds (copy, process, copy, ...),
  every round listed. Target: <= 2.
- ``--memory N...``: peak RSS (VmHWM) of a fresh Python process that imports the package and then
  processes, or copies, an N-command bag; the difference between N shows whether memory grows with the bag.

The bag is a deterministic sweep over the tilt range at 100 Hz written to a temporary directory (with
the block CDR encoder, so writing a 2,000,000-command bag takes seconds). Nothing here is asserted by a test.
"""

from __future__ import annotations

import argparse
import json
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parent.parent
CONFIG = REPO / 'config' / 'antenna.yaml'
T0_NS = 1_700_000_000 * 1_000_000_000


def make_bag(path: Path, n: int, storage: str) -> Path:
    """``n`` commands sweeping theta_min -> theta_max -> theta_min (period 200) at 100 Hz, with a few bad values."""
    import numpy as np

    from fourbar_ros.bags.joint_state_cdr import encode_float64s
    from fourbar_ros.bags.storage import FLOAT64, AtomicBagWriter, recorded_qos
    from fourbar_ros.config.antenna_config import load_config

    cfg = load_config(CONFIG)
    k = np.arange(n)
    phase = (k % 200) / 100.0
    frac = np.where(phase <= 1.0, phase, 2.0 - phase)
    values = cfg.theta_min + (cfg.theta_max - cfg.theta_min) * frac
    values[k % 1000 == 999] = np.nan  # the policy path too
    stamps = (T0_NS + k * 10_000_000).tolist()
    with AtomicBagWriter(path, storage) as bag:
        conn = bag.add_topic('/antenna_angle_cmd', FLOAT64, [recorded_qos()])
        for start in range(0, n, 65536):
            for stamp, raw in zip(stamps[start:start + 65536], encode_float64s(values[start:start + 65536]),
                                  strict=True):
                bag.writer.write(conn, stamp, raw)
    return path


def copy_bag(src: Path, dst: Path, storage: str) -> int:
    """Read every raw message with rosbags and write it to a new bag; the number of messages."""
    from rosbags.rosbag2 import Reader, StoragePlugin, Writer

    from fourbar_ros.bags.storage import jazzy_typestore

    plugin = StoragePlugin.MCAP if storage == 'mcap' else StoragePlugin.SQLITE3
    count = 0
    with Reader(src) as reader, Writer(dst, version=9, storage_plugin=plugin) as writer:
        conns = {c.id: writer.add_connection(c.topic, c.msgtype, typestore=jazzy_typestore())
                 for c in reader.connections}
        for conn, stamp, data in reader.messages():
            writer.write(conns[conn.id], stamp, data)
            count += 1
    return count


def process(src: Path, dst: Path, storage: str) -> int:
    """`fourbar process SRC DST --params config/antenna.yaml --storage STORAGE`; the commands processed."""
    from fourbar_ros.bags.process import process_bag
    from fourbar_ros.config.antenna_config import load_config

    return process_bag(src, dst, load_config(CONFIG), storage=storage).commands


def timed(fn: object, src: Path, out: Path, storage: str) -> float:
    shutil.rmtree(out, ignore_errors=True)
    start = time.perf_counter()
    fn(src, out, storage)  # type: ignore[operator]
    seconds = time.perf_counter() - start
    shutil.rmtree(out, ignore_errors=True)
    return seconds


def speed(n: int, rounds: int, storage: str) -> dict[str, object]:
    """Interleaved rounds of copy and process on one n-command bag."""
    with tempfile.TemporaryDirectory(prefix='process_bench.') as tmp:
        bag = make_bag(Path(tmp) / 'commands', n, storage)
        out = Path(tmp) / 'out'
        copies: list[float] = []
        processes: list[float] = []
        timed(process, bag, out, storage)  # warm-up: imports, page cache
        for _ in range(rounds):
            copies.append(timed(copy_bag, bag, out, storage))
            processes.append(timed(process, bag, out, storage))
    copy_s, process_s = statistics.median(copies), statistics.median(processes)
    return {'commands': n, 'storage': storage, 'rounds': rounds, 'copy_s': copies, 'process_s': processes,
            'copy_median_s': copy_s, 'process_median_s': process_s, 'ratio': process_s / copy_s}


def child(kind: str, src: Path, dst: Path, storage: str) -> None:
    """Run one copy or process in this (fresh) process and print its peak RSS."""
    import fourbar_ros.bags.process  # noqa: F401  (the same imports in both kinds)

    start = time.perf_counter()
    (process if kind == 'process' else copy_bag)(src, dst, storage)
    seconds = time.perf_counter() - start
    print(json.dumps({'kind': kind, 'seconds': seconds, 'max_rss_mib': peak_rss_mib()}))


def peak_rss_mib() -> float:
    """This process's peak resident set (VmHWM, MiB). Not getrusage's ru_maxrss: Linux carries the parent's
    peak at fork into a child's ru_maxrss even after exec, so a child started by a big parent reports that."""
    for line in Path('/proc/self/status').read_text().splitlines():
        if line.startswith('VmHWM:'):
            return int(line.split()[1]) / 1024
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def memory(sizes: list[int], storage: str) -> list[dict[str, object]]:
    """Peak RSS of a fresh process copying and processing each size."""
    rows = []
    for n in sizes:
        with tempfile.TemporaryDirectory(prefix='process_bench.') as tmp:
            bag = make_bag(Path(tmp) / 'commands', n, storage)
            for kind in ('copy', 'process'):
                out = Path(tmp) / kind
                done = subprocess.run([sys.executable, '-m', 'benchmarks.process_bench', '--child', kind,
                                       str(bag), str(out), '--storage', storage],
                                      cwd=REPO, capture_output=True, text=True, check=True)
                row = json.loads(done.stdout.strip().splitlines()[-1])
                row['commands'] = n
                rows.append(row)
                shutil.rmtree(out, ignore_errors=True)
    return rows


def run(quick: bool) -> dict[str, Any]:
    """For ``python -m benchmarks.run``: the speed ratio (and, in a full run, peak memory at two bag sizes)."""
    n, rounds = (20_000, 3) if quick else (200_000, 5)
    figures: dict[str, Any] = {'speed': speed(n, rounds, 'mcap')}
    figures['process_over_copy_ratio'] = figures['speed']['ratio']
    figures['memory'] = {f'{r["kind"]}_{r["commands"]}_peak_rss_mib': r['max_rss_mib']
                         for r in memory([20_000] if quick else [200_000, 2_000_000], 'mcap')}
    return figures


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument('--commands', type=int, default=200_000)
    parser.add_argument('--rounds', type=int, default=3)
    parser.add_argument('--storage', choices=('mcap', 'sqlite3'), default='mcap')
    parser.add_argument('--memory', type=int, nargs='+', metavar='N', help='peak RSS for these bag sizes')
    parser.add_argument('--child', nargs=3, metavar=('KIND', 'IN', 'OUT'), help=argparse.SUPPRESS)
    parser.add_argument('--json', action='store_true', help='print the result as JSON')
    args = parser.parse_args(argv)
    if args.child:
        child(args.child[0], Path(args.child[1]), Path(args.child[2]), args.storage)
        return 0
    if args.memory:
        rows = memory(args.memory, args.storage)
        if args.json:
            print(json.dumps(rows))
        for r in rows:
            print(f'{r["commands"]:>9} commands  {r["kind"]:<7}  peak RSS {r["max_rss_mib"]:7.1f} MiB  '
                  f'({r["seconds"]:.1f} s)')
        return 0
    result = speed(args.commands, args.rounds, args.storage)
    if args.json:
        print(json.dumps(result))
    copies = ', '.join(f'{s:.2f}' for s in result['copy_s'])  # type: ignore[attr-defined]
    processes = ', '.join(f'{s:.2f}' for s in result['process_s'])  # type: ignore[attr-defined]
    print(f'{args.commands} commands, {args.storage}, {args.rounds} interleaved rounds')
    print(f'  rosbags copy      median {result["copy_median_s"]:.2f} s  (rounds: {copies})')
    print(f'  fourbar process   median {result["process_median_s"]:.2f} s  (rounds: {processes})')
    print(f'  ratio process/copy  {result["ratio"]:.2f}  (target <= 2)')
    return 0


if __name__ == '__main__':
    sys.exit(main())
