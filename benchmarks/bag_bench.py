"""Replay throughput through fourbar_node against the bare rosbags read rate of the same bag, same run.

    .venv/bin/python -m benchmarks.bag_bench [--quick]

- baseline: how fast ``rosbags`` reads the bag's command messages (raw CDR, and decoded to floats as
  ``fourbar replay`` does before it starts), messages per second, median of repeats;
- replay: ``fourbar replay --as-fast-as-node-keeps-up [--window 16]`` done in-process (the same
  ``Replayer``) into ``fourbar_node`` started as a process with config/antenna.yaml: strict lock-step
  (window 1: each command waits for its JointState) and pipelined (window 16: at most 16 answers
  outstanding, far below the node's queue of 1000), interleaved. Nothing is lost by construction; the run
  also checks it (every answer arrived, and the node's diagnostics count every command received and every
  JointState published). Commands per second, median of repeats.
- ratios replay/read: how much of the reading speed survives the round trip through the middleware.

The bag is a sweep over the tilt range written fresh (deterministic) in a temporary directory; the node runs
on a free ROS_DOMAIN_ID (the test suite's lock files) and this host only. Nothing here is asserted by a test.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parent.parent
CONFIG = REPO / 'config' / 'antenna.yaml'
T0_NS = 1_700_000_000 * 1_000_000_000


def make_bag(path: Path, n: int, storage: str) -> Path:
    """A sweep theta_min -> theta_max -> theta_min repeated, ``n`` commands at 100 Hz."""
    from fourbar_ros.bags.storage import write_command_bag
    from fourbar_ros.config.antenna_config import load_config

    cfg = load_config(CONFIG)
    span = cfg.theta_max - cfg.theta_min
    period = 200
    values = []
    for k in range(n):
        phase = (k % period) / (period / 2)
        frac = phase if phase <= 1.0 else 2.0 - phase
        values.append(cfg.theta_min + span * frac)
    return write_command_bag(path, [T0_NS + k * 10_000_000 for k in range(n)], values, storage)


def read_rates(bag: Path) -> tuple[float, float]:
    """(raw messages/s with rosbags' Reader, decoded commands/s with bag_io.read_commands)."""
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


WINDOWS = (1, 16)


def replay_rates(bag: Path, repeats: int, timeout_s: float = 60.0) -> dict[str, Any]:
    """Replay ``repeats`` times per window (interleaved) into one node process; rates and the loss check."""
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node

    from fourbar_ros.bags.domain import free_domain_id
    from fourbar_ros.bags.graph import ReplayError, spin_until
    from fourbar_ros.bags.node_process import NodeProcess
    from fourbar_ros.bags.replay import Replayer
    from fourbar_ros.bags.ros_context import close_context, init_context
    from fourbar_ros.bags.storage import read_commands

    stream = read_commands(bag)
    rates: dict[int, list[float]] = {w: [] for w in WINDOWS}
    answers = expected = 0
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    with free_domain_id() as domain_id:
        node_proc = NodeProcess(CONFIG, domain_id, env=dict(os.environ)).start()
        context = init_context(domain_id=domain_id, handle_signals=False)
        node = Node('fourbar_bag_bench', context=context, start_parameter_services=False)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        diag: list[dict[str, str]] = []
        try:
            replayer = Replayer(node, stream, answer_topic='/joint_states')
            node.create_subscription(
                DiagnosticArray, '/diagnostics',
                lambda m: diag.append({kv.key: kv.value for kv in m.status[0].values} if m.status else {}), 10)
            replayer.wait_for_node(executor, timeout_s)
            predict = replayer.prepare_lockstep(executor, timeout_s)
            for _ in range(repeats):
                for window in WINDOWS:
                    stats = replayer.run_lockstep(executor, predict, 5.0, window=window)
                    rates[window].append(stats.published / stats.seconds)
                    answers += stats.answers
                    expected += stats.expected_answers
            total = repeats * len(WINDOWS) * len(stream)

            def counted() -> bool:
                return any(d.get('commands_received') == str(total) for d in diag)
            if not spin_until(executor, counted, timeout_s):
                raise ReplayError(f'node diagnostics never counted {total} commands')
            final = next(d for d in diag if d.get('commands_received') == str(total))
        finally:
            executor.shutdown()
            close_context(context, node)
            node_proc.stop()
    lost = expected - answers
    published = int(final['joint_states_published'])
    out: dict[str, Any] = {}
    for window, values in rates.items():
        out[f'replay_window{window}_cmd_per_s'] = statistics.median(values)
        out[f'replay_window{window}_cmd_per_s_all'] = [round(r, 1) for r in values]
    return {**out, 'lost_commands': lost + (total - int(final['commands_received'])),
            'node_joint_states_published': published, 'commands_sent': total}


def run(quick: bool) -> dict[str, Any]:
    """Figures for benchmarks/run.py: per storage, the replay rate, the read rates and their ratios."""
    n, repeats = (1000, 2) if quick else (5000, 3)
    storages = ('mcap',) if quick else ('mcap', 'sqlite3')
    out: dict[str, Any] = {'command': 'python -m benchmarks.bag_bench' + (' --quick' if quick else ''),
                           'bag_commands': n, 'repeats': repeats}
    with tempfile.TemporaryDirectory() as tmp:
        for storage in storages:
            bag = make_bag(Path(tmp) / f'bench_{storage}', n, storage)
            reads = [read_rates(bag) for _ in range(repeats)]
            replay = replay_rates(bag, repeats)
            reads += [read_rates(bag) for _ in range(repeats)]  # before and after: same machine load
            raw = statistics.median(r[0] for r in reads)
            decoded = statistics.median(r[1] for r in reads)
            out[storage] = {**replay, 'rosbags_raw_read_msg_per_s': raw,
                            'rosbags_decoded_read_cmd_per_s': decoded}
            for window in WINDOWS:
                rate = replay[f'replay_window{window}_cmd_per_s']
                out[storage][f'window{window}_over_raw_read'] = rate / raw
                out[storage][f'window{window}_over_decoded_read'] = rate / decoded
    return out


def main(argv: list[str] | None = None) -> int:
    """Print the figures as JSON."""
    parser = argparse.ArgumentParser(prog='python -m benchmarks.bag_bench', description=__doc__.splitlines()[0])
    parser.add_argument('--quick', action='store_true', help='1000 commands, 2 repeats, mcap only')
    args = parser.parse_args(argv)
    json.dump(run(args.quick), sys.stdout, indent=2)
    print()
    return 0


if __name__ == '__main__':
    sys.exit(main())
