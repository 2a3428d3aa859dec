"""`fourbar process` against a plain rosbags copy of the same command bag and against the storage floor, same run.

    .venv/bin/python -m benchmarks.process_bench [--rounds 5] [--storage mcap] [--markdown]
    .venv/bin/python -m benchmarks.process_bench --memory 200000 2000000

- copy: rosbags reads every raw message of a 200,000-command bag and writes it to a new bag (same storage);
- floor: rosbags reads every raw message of the same bag and writes the messages `fourbar process` writes for it
  (joint_states and input_torque per command, precomputed bytes of the package's CDR encoding): the storage cost
  of the output alone, with three writers: rosbags' Writer message by message (``floor``), the ``mcap`` package's
  chunked Writer message by message (``floor_mcap``, mcap storage only: uncompressed 1 MiB chunks, as rosbags
  writes them) and the package's storage layer a block of rows at a time (``floor_rows``,
  ``StorageAdapter.write_rows``, what `fourbar process` writes with);
- process: `fourbar process IN OUT --params config/antenna.yaml` in-process (``fourbar_ros.commands.main``);
- ratios process/copy, floor/copy and process/floor (each floor, and the fastest) of the median CPU times over
  ``--rounds`` interleaved rounds;
- ``--memory N...``: peak RSS (VmHWM) of a fresh process copying, or processing, an N-command bag.

Figures as JSON (``--markdown``: as the table of docs/benchmarks.md), which explains them.
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
    """`fourbar process SRC DST --params config/antenna.yaml --storage STORAGE`; its exit status."""
    import contextlib
    import io

    from fourbar_ros.commands import main

    with contextlib.redirect_stderr(io.StringIO()):
        return main(['process', str(src), str(dst), '--params', str(CONFIG), '--storage', storage.value])


#: What `fourbar process` writes for a bag: its (topic, type), its messages by log time (ns) as (topic index, raw),
#: and for mcap each topic's schema (name, encoding, text) and channel metadata as the file holds them.
Outputs = tuple[list[tuple[str, str]], dict[int, list[tuple[int, bytes]]],
                list[tuple[tuple[str, str, bytes], dict[str, str]]]]


def outputs_of(src: Path, storage: Storage) -> Outputs:
    """What `fourbar process` writes for ``src`` (``Outputs``)."""
    from mcap.reader import make_reader
    from rosbags.rosbag2 import Reader

    with tempfile.TemporaryDirectory(prefix='process_bench.') as tmp:
        process(src, Path(tmp) / 'out', storage)
        channels: list[tuple[tuple[str, str, bytes], dict[str, str]]] = []
        if storage is Storage.MCAP:
            with (Path(tmp) / 'out' / 'out.mcap').open('rb') as f:
                summary = make_reader(f).get_summary()
                assert summary is not None
                for channel in summary.channels.values():
                    schema = summary.schemas[channel.schema_id]
                    channels.append(((schema.name, schema.encoding, schema.data), dict(channel.metadata)))
        with Reader(Path(tmp) / 'out') as reader:
            index = {c.id: i for i, c in enumerate(reader.connections)}
            by_log: dict[int, list[tuple[int, bytes]]] = {}
            for conn, stamp, data in reader.messages():
                by_log.setdefault(stamp, []).append((index[conn.id], bytes(data)))
            # floor_rows writes rows: one message per topic, in topic order, at each log time
            assert all([i for i, _ in row] == list(range(len(index))) for row in by_log.values())
            return [(c.topic, c.msgtype) for c in reader.connections], by_log, channels


def floor(src: Path, dst: Path, storage: Storage, outputs: Outputs) -> int:
    """Read every raw message of ``src`` with rosbags and write its precomputed ``outputs`` (``outputs_of``) with
    rosbags' writer (same storage); the number of messages written."""
    from rosbags.rosbag2 import Reader, Writer

    from fourbar_ros.bags.storage import jazzy_typestore, recorded_qos
    from fourbar_ros.bags.storage.adapters import adapter

    topics, by_log, _ = outputs
    count = 0
    with Reader(src) as reader, Writer(dst, version=9, storage_plugin=adapter(storage).plugin) as writer:
        conns = [writer.add_connection(t, m, typestore=jazzy_typestore(), offered_qos_profiles=[recorded_qos()])
                 for t, m in topics]
        for _, stamp, _ in reader.messages():
            for i, raw in by_log.get(stamp, ()):
                writer.write(conns[i], stamp, raw)
                count += 1
    return count


def floor_mcap(src: Path, dst: Path, storage: Storage, outputs: Outputs) -> int:
    """``floor`` with the ``mcap`` package's chunked Writer (no compression, 1 MiB chunks like rosbags' writer; the
    ros2 profile, schemas and channel metadata of `fourbar process`'s file; no metadata.yaml); the number of
    messages written (0 for sqlite3: not timed)."""
    if storage is not Storage.MCAP:
        return 0
    from mcap.writer import CompressionType
    from mcap.writer import Writer as McapWriter
    from rosbags.rosbag2 import Reader

    topics, by_log, meta = outputs
    count = 0
    dst.mkdir()
    with Reader(src) as reader, (dst / f'{dst.name}.mcap').open('wb') as f:
        writer = McapWriter(f, chunk_size=2**20, compression=CompressionType.NONE)
        writer.start('ros2', 'process_bench')
        schemas = {schema: writer.register_schema(*schema) for schema in dict.fromkeys(s for s, _ in meta)}
        channels = [writer.register_channel(t, 'cdr', schemas[schema], metadata)
                    for (t, _), (schema, metadata) in zip(topics, meta, strict=True)]
        add = writer.add_message
        for _, stamp, _ in reader.messages():
            for i, raw in by_log.get(stamp, ()):
                add(channels[i], stamp, raw, stamp)
                count += 1
        writer.finish()
    return count


def floor_rows(src: Path, dst: Path, storage: Storage, outputs: Outputs) -> int:
    """``floor`` through the package's storage layer: its Writer (``BagWriter``, no atomic commit) with the adapter's
    ``write_rows``, a block of ``BLOCK`` read messages' outputs per call, as `fourbar process` writes; the number of
    messages written."""
    from itertools import islice

    from rosbags.rosbag2 import Reader

    from fourbar_ros.bags.storage import jazzy_typestore, recorded_qos
    from fourbar_ros.bags.storage.adapters import adapter
    from fourbar_ros.bags.storage.write import BagWriter as Writer

    topics, by_log, _ = outputs
    store = adapter(storage)
    count = 0
    with Reader(src) as reader, Writer(dst, version=9, storage_plugin=store.plugin) as writer:
        conns = [writer.add_connection(t, m, typestore=jazzy_typestore(), offered_qos_profiles=[recorded_qos()])
                 for t, m in topics]
        messages = reader.messages()
        while block := list(islice(messages, BLOCK)):
            rows = [by_log[stamp] for _, stamp, _ in block if stamp in by_log]
            stamps = [stamp for _, stamp, _ in block if stamp in by_log]
            store.write_rows(writer, stamps, [(conn, [row[i][1] for row in rows]) for i, conn in enumerate(conns)])
            count += len(rows) * len(conns)
    return count


def read(src: Path, dst: Path, storage: Storage) -> int:
    """Read every raw message of ``src`` with rosbags (nothing written); the number of messages."""
    from rosbags.rosbag2 import Reader

    with Reader(src) as reader:
        return sum(1 for _ in reader.messages())


KINDS: dict[str, Callable[..., int]] = {'read': read, 'copy': copy_bag, 'floor': floor, 'floor_mcap': floor_mcap,
                                       'floor_rows': floor_rows, 'process': process}
FLOORS = ('floor', 'floor_mcap', 'floor_rows')


def timed(kind: str, src: Path, out: Path, storage: Storage, *extra: Any) -> tuple[float, float]:
    """(CPU seconds of this process, wall seconds) of one read, copy, floor or process into ``out`` (removed before and
    after). The ratios use CPU time: time the scheduler gives other jobs on a shared machine is left out."""
    shutil.rmtree(out, ignore_errors=True)
    cpu, wall = time.process_time(), time.perf_counter()
    KINDS[kind](src, out, storage, *extra)
    cpu, wall = time.process_time() - cpu, time.perf_counter() - wall
    shutil.rmtree(out, ignore_errors=True)
    return cpu, wall


def speed(n: int, rounds: int, storage: Storage) -> dict[str, Any]:
    """Interleaved rounds of read, copy, floor and process on one n-command bag."""
    with tempfile.TemporaryDirectory(prefix='process_bench.') as tmp:
        bag = make_bag(Path(tmp) / 'commands', n, storage)
        out = Path(tmp) / 'out'
        outputs = outputs_of(bag, storage)  # also the warm-up: imports, page cache
        times: dict[str, list[tuple[float, float]]] = {kind: [] for kind in KINDS}
        for _ in range(rounds):
            for kind, row in times.items():
                row.append(timed(kind, bag, out, storage, *((outputs,) if kind in FLOORS else ())))
    if storage is not Storage.MCAP:  # floor_mcap writes mcap only
        del times['floor_mcap']
    cpu = {kind: statistics.median(c for c, _ in row) for kind, row in times.items()}
    floors = [kind for kind in FLOORS if kind in cpu]
    fastest = min(floors, key=cpu.__getitem__)
    written = sum(map(len, outputs[1].values()))
    return {'commands': n, 'storage': storage.value, 'rounds': rounds,
            'messages_written': {'copy': n, 'floor_and_process': written},
            'write_us_per_message': {'copy': (cpu['copy'] - cpu['read']) / n * 1e6,
                                     **{kind: (cpu[kind] - cpu['read']) / written * 1e6 for kind in floors}},
            'rules_and_cdr_us_per_command': (cpu['process'] - cpu['floor_rows']) / n * 1e6,
            **{f'{kind}_cpu_s': [c for c, _ in row] for kind, row in times.items()},
            **{f'{kind}_median_cpu_s': m for kind, m in cpu.items()},
            **{f'{kind}_median_wall_s': statistics.median(w for _, w in row) for kind, row in times.items()},
            'ratio': cpu['process'] / cpu['copy'],
            **{f'{kind}_ratio': cpu[kind] / cpu['copy'] for kind in floors},
            **{f'process_over_{kind}': cpu['process'] / cpu[kind] for kind in floors},
            'fastest_floor': fastest, 'process_over_fastest_floor': cpu['process'] / cpu[fastest]}


WRITERS = {'floor': "rosbags' Writer, a message at a time",
           'floor_mcap': "the `mcap` package's chunked Writer, a message at a time",
           'floor_rows': "the package's storage layer, a block of rows at a time (`write_rows`, what process writes "
                         "with)"}


def where_the_time_goes(f: dict[str, Any]) -> str:
    """The speed figures in words: what the copy and each floor cost and what is left for process (markdown)."""
    per = f['write_us_per_message']
    floors = [kind for kind in WRITERS if kind in per]
    writers = '; '.join(f'{WRITERS[kind]}: {per[kind]:.2f} us per message, floor/copy {f[f"{kind}_ratio"]:.2f}, '
                        f'process/floor {f[f"process_over_{kind}"]:.2f}' for kind in floors)
    return (f'`fourbar process` of a {f["commands"]:,}-command {f["storage"]} bag takes **{f["ratio"]:.2f}x** the '
            f'CPU time of a rosbags copy of it and **{f["process_over_fastest_floor"]:.2f}x the fastest floor** '
            f'({f["fastest_floor"]}). A floor is a rosbags read of the input plus writing the same output messages '
            f'(precomputed bytes of the package\'s CDR encoding); by writer: {writers}. '
            f'The output holds {f["messages_written"]["floor_and_process"]:,} messages (joint_states and input_torque '
            f'per served command) against the copy\'s {f["commands"]:,}; rosbags\' writer costs '
            f'{per["copy"]:.2f} us per message in the copy, against {f["read_median_cpu_s"] / f["commands"] * 1e6:.2f} '
            f'us to read one. What process adds to the rows floor (decoding, the node\'s rules on blocks, CDR '
            f'encoding, the atomic commit) is {f["rules_and_cdr_us_per_command"]:.2f} us per command.\n')


def child(kind: str, src: Path, dst: Path, storage: Storage) -> None:
    """Run one copy or process in this (fresh) process and print its peak RSS.

    VmHWM, not getrusage's ru_maxrss: Linux carries the parent's peak at fork into a child's ru_maxrss even after
    exec, so a child started by a big parent would report that."""
    import fourbar_ros.bags.process  # noqa: F401  (the same imports in both kinds)

    seconds = timed(kind, src, dst, storage)[1]
    peak = next(line for line in Path('/proc/self/status').read_text().splitlines() if line.startswith('VmHWM:'))
    print(json.dumps({'kind': kind, 'seconds': seconds, 'max_rss_mib': int(peak.split()[1]) / 1024}))


def memory(sizes: list[int], storage: Storage) -> list[dict[str, Any]]:
    """Peak RSS of a fresh process copying and processing each size."""
    rows = []
    for n in sizes:
        with tempfile.TemporaryDirectory(prefix='process_bench.') as tmp:
            bag = make_bag(Path(tmp) / 'commands', n, storage)
            for kind in ('copy', 'process'):
                done = subprocess.run([sys.executable, '-m', 'benchmarks.process_bench', '--child', kind,
                                       str(bag), str(Path(tmp) / kind), '--storage', storage.value],
                                      cwd=REPO, capture_output=True, text=True, check=True)
                rows.append({**json.loads(done.stdout.strip().splitlines()[-1]), 'commands': n})
    return rows


def run(quick: bool) -> dict[str, Any]:
    """For ``python -m benchmarks.run``: the speed ratios and peak memory (at two bag sizes in a full run)."""
    n, rounds = (20_000, 3) if quick else (200_000, 5)
    figures: dict[str, Any] = {'speed': speed(n, rounds, DEFAULT_STORAGE)}
    figures['process_over_copy_ratio'] = figures['speed']['ratio']
    figures['floor_over_copy_ratio'] = figures['speed']['floor_ratio']
    figures['process_over_fastest_floor'] = figures['speed']['process_over_fastest_floor']
    figures['memory'] = {f'{r["kind"]}_{r["commands"]}_peak_rss_mib': r['max_rss_mib']
                         for r in memory([20_000] if quick else [200_000, 2_000_000], DEFAULT_STORAGE)}
    return figures


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or '').splitlines()[0])
    parser.add_argument('--rounds', type=int, default=5)
    parser.add_argument('--markdown', action='store_true', help='print the table of docs/benchmarks.md')
    parser.add_argument('--storage', type=Storage, choices=tuple(Storage), default=DEFAULT_STORAGE)
    parser.add_argument('--memory', type=int, nargs='+', metavar='N', help='peak RSS for these bag sizes')
    parser.add_argument('--child', nargs=3, metavar=('KIND', 'IN', 'OUT'), help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        child(args.child[0], Path(args.child[1]), Path(args.child[2]), args.storage)
        return 0
    if args.memory:
        return print_json(memory(args.memory, args.storage))
    figures = speed(200_000, args.rounds, args.storage)
    if args.markdown:
        from benchmarks.report import figures_table

        print(where_the_time_goes(figures), figures_table(
            f'fourbar process (python -m benchmarks.process_bench --rounds {args.rounds})', figures), sep='\n')
        return 0
    return print_json(figures)


if __name__ == '__main__':
    sys.exit(main())
