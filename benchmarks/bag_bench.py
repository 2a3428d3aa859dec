"""Replay throughput through fourbar_node against the bare rosbags read rate of the same bag, same run.

    .venv/bin/python -m benchmarks.bag_bench [--quick]   (figures printed as JSON)

- baseline: how fast ``rosbags`` reads the bag's command messages (raw CDR, and decoded to floats as
  ``fourbar replay`` does before it starts), messages per second, median of repeats;
- replay: ``fourbar replay --as-fast-as-node-keeps-up [--window 16]`` done in-process (the same
  ``Replayer``) into ``fourbar_node`` started as a process with config/antenna.yaml: strict lock-step
  (window 1: each command waits for its answer on input_torque) and pipelined (window 16: at most 16 answers
  outstanding, far below the node's queue of 1000), interleaved. Nothing is lost by construction; the run
  also checks it (every answer arrived, and the node's diagnostics count every command received and every
  JointState published). Commands per second, median of repeats.
- ratios replay/read: how much of the reading speed survives the round trip through the middleware.

The bag is a sweep over the tilt range written fresh (deterministic) in a temporary directory; the node runs
on a free ROS_DOMAIN_ID (the test suite's lock files) and this host only. Nothing here is asserted by a test.
"""

from __future__ import annotations

import os
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from benchmarks import CONFIG, options, print_json
from benchmarks.process_bench import make_bag
from benchmarks.timing import cpu_seconds
from fourbar_ros.interface.topics import DEFAULT_STORAGE, Storage

WINDOWS = (1, 16)


def read_rates(bag: Path) -> tuple[float, float]:
    """(raw messages/s with rosbags' Reader, decoded commands/s with bags.storage.read_commands)."""
    from rosbags.rosbag2 import Reader

    from fourbar_ros.bags.storage import read_commands

    start = time.perf_counter()
    with Reader(bag) as reader:
        count = sum(1 for _ in reader.messages())
    raw = count / (time.perf_counter() - start)
    start = time.perf_counter()
    stream = read_commands(bag)
    decoded = len(stream) / (time.perf_counter() - start)
    return raw, decoded


def thread_cpu_s(pid: int) -> dict[str, float]:
    """CPU seconds of process ``pid`` so far: its main thread (Python, the executor, the callbacks) and its
    other threads (the middleware's receive and event threads; those that ended are left out)."""
    out = {'main_thread': 0.0, 'other_threads': 0.0}
    for tid in os.listdir(f'/proc/{pid}/task'):
        seconds = cpu_seconds(pid, tid)
        if seconds is not None:
            out['main_thread' if tid == str(pid) else 'other_threads'] += seconds
    return out


def replay_rates(bag: Path, repeats: int, timeout_s: float = 60.0) -> dict[str, Any]:
    """Per executor (the replayer's and the node's alike): replay ``repeats`` times per window, interleaved
    with the other executor, into one node process each; rates, CPU per command and the loss check."""
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.node import Node

    from fourbar_ros.bags.storage import read_commands
    from fourbar_ros.live.graph import ReplayError, spin_until
    from fourbar_ros.live.node_process import NodeProcess, free_domain_id, node_args
    from fourbar_ros.live.replay import Replayer
    from fourbar_ros.live.ros_context import close_context, init_context
    from fourbar_ros.runtime.executor import EXECUTOR_ENV, EXECUTORS, create_executor

    stream = read_commands(bag)
    rates: dict[str, dict[int, list[float]]] = {k: {w: [] for w in WINDOWS} for k in EXECUTORS}
    cpu: dict[str, dict[int, dict[str, float]]] = {k: {w: {} for w in WINDOWS} for k in EXECUTORS}
    answers = dict.fromkeys(EXECUTORS, 0)
    expected = dict.fromkeys(EXECUTORS, 0)
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    out: dict[str, Any] = {}
    with free_domain_id() as domain_id:
        # One node per executor, each with its own name: the diagnostics status is named after the node.
        procs = {k: NodeProcess(node_args(CONFIG, '-r', f'__ns:=/{k}', '-r', f'__node:=fourbar_node_{k}'),
                                dict(os.environ, ROS_DOMAIN_ID=str(domain_id), **{EXECUTOR_ENV: k})).start()
                 for k in EXECUTORS}
        context = init_context(domain_id=domain_id)
        nodes = [Node(f'fourbar_bag_bench_{k}', context=context, start_parameter_services=False) for k in EXECUTORS]
        executors = {k: create_executor(k, context) for k in EXECUTORS}
        diag: dict[str, list[dict[str, str]]] = {k: [] for k in EXECUTORS}
        replayers: dict[str, Replayer] = {}
        try:
            for kind, node in zip(EXECUTORS, nodes, strict=True):
                executor = executors[kind]
                executor.add_node(node)
                replayer = Replayer(node, stream, topic=f'/{kind}/antenna_angle_cmd',
                                    answer_topic=f'/{kind}/input_torque')
                node.create_subscription(
                    DiagnosticArray, '/diagnostics',
                    lambda m, k=kind: diag[k].append(  # type: ignore[misc]
                        {kv.key: kv.value for kv in m.status[0].values}
                        if m.status and m.status[0].name.startswith(f'fourbar_node_{k}:') else {}), 10)
                replayer.wait_for_node(executor, timeout_s)
                replayers[kind] = replayer
            predicts = {k: replayers[k].prepare_lockstep(executors[k], timeout_s) for k in EXECUTORS}
            node_pids = {k: p.proc.pid for k, p in procs.items() if p.proc is not None}
            for _ in range(repeats):
                for window in WINDOWS:
                    for kind in EXECUTORS:
                        pids = {'node': node_pids[kind], 'replayer': os.getpid()}
                        before = {side: thread_cpu_s(pid) for side, pid in pids.items()}
                        stats = replayers[kind].run_lockstep(executors[kind], predicts[kind], 5.0, window=window)
                        rates[kind][window].append(stats.published / stats.seconds)
                        answers[kind] += stats.answers
                        expected[kind] += stats.expected_answers
                        for side, pid in pids.items():
                            for group, value in thread_cpu_s(pid).items():
                                used = value - before[side].get(group, value)
                                key = f'{side}_{group}'
                                cpu[kind][window][key] = cpu[kind][window].get(key, 0.0) + used
            total = repeats * len(WINDOWS) * len(stream)
            for kind in EXECUTORS:
                def counted(k: str = kind) -> bool:
                    return any(d.get('commands_received') == str(total) for d in diag[k])
                if not spin_until(executors[kind], counted, timeout_s):
                    raise ReplayError(f'{kind}: node diagnostics never counted {total} commands')
                final = next(d for d in diag[kind] if d.get('commands_received') == str(total))
                per_window = repeats * len(stream)
                row: dict[str, Any] = {}
                for window, values in rates[kind].items():
                    row[f'replay_window{window}_cmd_per_s'] = statistics.median(values)
                    row[f'replay_window{window}_cmd_per_s_all'] = [round(r, 1) for r in values]
                    row[f'window{window}_cpu_us_per_command'] = {
                        k: round(1e6 * v / per_window, 1) for k, v in sorted(cpu[kind][window].items())}
                out[kind] = {**row, 'lost_commands': expected[kind] - answers[kind]
                             + (total - int(final['commands_received'])),
                             'node_joint_states_published': int(final['joint_states_published']),
                             'commands_sent': total}
        finally:
            for executor in executors.values():
                executor.shutdown(timeout_sec=0.0)
            close_context(context, *nodes)
            for proc in procs.values():
                proc.stop()
    for window in WINDOWS:
        key = f'replay_window{window}_cmd_per_s'
        out[f'window{window}_events_over_single'] = out['events'][key] / out['single'][key]
    return out


def run(quick: bool) -> dict[str, Any]:
    """Figures for benchmarks/run.py: per storage, the replay rate, the read rates and their ratios."""
    n, repeats = (1000, 2) if quick else (5000, 3)
    storages = (DEFAULT_STORAGE,) if quick else tuple(Storage)
    out: dict[str, Any] = {'command': 'python -m benchmarks.bag_bench' + (' --quick' if quick else ''),
                           'bag_commands': n, 'repeats': repeats}
    with tempfile.TemporaryDirectory() as tmp:
        for storage in storages:
            bag = make_bag(Path(tmp) / f'bench_{storage}', n, storage, bad_every=0)
            reads = [read_rates(bag) for _ in range(repeats)]
            replay = replay_rates(bag, repeats)
            reads += [read_rates(bag) for _ in range(repeats)]  # before and after: same machine load
            raw = statistics.median(r[0] for r in reads)
            decoded = statistics.median(r[1] for r in reads)
            out[storage.value] = {**replay, 'rosbags_raw_read_msg_per_s': raw,
                            'rosbags_decoded_read_cmd_per_s': decoded}
            for kind in ('events', 'single'):
                for window in WINDOWS:
                    rate = replay[kind][f'replay_window{window}_cmd_per_s']
                    out[storage.value][kind][f'window{window}_over_raw_read'] = rate / raw
                    out[storage.value][kind][f'window{window}_over_decoded_read'] = rate / decoded
    return out


if __name__ == '__main__':
    sys.exit(print_json(run(options(sys.argv[1:], __doc__).quick)))
