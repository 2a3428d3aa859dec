"""`fourbar record OUT`: record topics to a rosbag2 bag, written atomically; Ctrl-C stops it cleanly."""

from __future__ import annotations

import argparse
import contextlib
import math
import sys
from pathlib import Path

from fourbar_ros.commands import CommandError, add_storage_argument
from fourbar_ros.interface.topics import RECORDED_OUTPUTS

HELP = 'record topics (default: the node outputs) to a rosbag2 bag, mcap by default; Ctrl-C stops it cleanly'

DEFAULT_TOPICS = tuple(t.name for t in RECORDED_OUTPUTS)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of `fourbar record`."""
    parser.add_argument('out', type=Path, metavar='OUT', help='bag directory to create (must not exist)')
    parser.add_argument('--topics', nargs='+', metavar='TOPIC', default=list(DEFAULT_TOPICS),
                        help='topics to record; relative names resolve in the root namespace '
                        f'(default: {" ".join(DEFAULT_TOPICS)})')
    add_storage_argument(parser, 'storage plugin')
    parser.add_argument('--wait', type=float, default=10.0, metavar='S',
                        help='seconds to wait for a publisher on every topic (default: 10)')
    parser.add_argument('--duration', type=float, metavar='S', help='stop after S seconds of recording')
    parser.add_argument('--flush-interval', type=float, default=1.0, metavar='S',
                        help='hand the recorded messages to the OS every S seconds, so a killed recorder '
                        'keeps all but the last S seconds (recover with `fourbar reindex OUT`; default: 1)')
    parser.add_argument('--stop-after', action='append', default=[], metavar='TOPIC=N',
                        help='stop once TOPIC has N messages (repeatable: all must be reached)')


def _parse_stop_after(items: list[str]) -> dict[str, int]:
    from fourbar_ros.bags.storage import BagError

    out: dict[str, int] = {}
    for item in items:
        topic, sep, count = item.rpartition('=')
        try:
            n = int(count)
        except ValueError:
            n = -1
        if not sep or not topic or n < 1:
            raise BagError(f'--stop-after wants TOPIC=N with N >= 1, got {item!r}')
        out[topic] = n
    return out


def run(args: argparse.Namespace) -> int:
    """Record until Ctrl-C/SIGTERM, --duration or --stop-after; exit 0 with a complete bag."""
    from rclpy.node import Node

    from fourbar_ros.bags.storage import AtomicBagWriter, BagError
    from fourbar_ros.live.graph import spin_until
    from fourbar_ros.live.record import Recorder, discover, record_until
    from fourbar_ros.live.ros_context import close_context, init_context
    from fourbar_ros.runtime.executor import create_executor
    from fourbar_ros.runtime.stop import stop_on_signals

    prog = 'fourbar record'
    if args.wait <= 0 or (args.duration is not None and not args.duration > 0):
        raise CommandError('--wait and --duration must be positive')
    if not (math.isfinite(args.flush_interval) and args.flush_interval > 0):
        raise CommandError(f'--flush-interval must be a positive number of seconds, got {args.flush_interval}')
    stop_after = _parse_stop_after(args.stop_after)
    AtomicBagWriter(args.out, args.storage)  # checks OUT before touching ROS; writes nothing

    stack = contextlib.ExitStack()
    stop = stack.enter_context(stop_on_signals(raises=None))  # a stop ends the recording, which is then closed
    context = init_context()
    node = Node('fourbar_record', context=context)
    executor = create_executor(context=context)  # $FOURBAR_EXECUTOR, else events
    executor.add_node(node)
    recorder: Recorder | None = None
    try:
        try:
            plans = discover(node, executor, args.topics, args.wait, stop=lambda: stop.requested)
        except BagError as exc:  # a topic without a publisher within --wait: status 1
            raise CommandError(str(exc), status=1) from None
        if stop.requested:
            print(f'{prog}: interrupted before recording started; no bag written', file=sys.stderr)
            return 130
        wanted = {node.resolve_topic_name(t): n for t, n in stop_after.items()}
        unknown = sorted(set(wanted) - {p.name for p in plans})
        if unknown:
            raise CommandError(f'--stop-after names a topic not recorded: {unknown[0]}')
        recorder = Recorder(node, args.out, plans, args.storage, flush_interval=args.flush_interval)
        rec = recorder
        spin_until(executor, lambda: rec.matched() or stop.requested, args.wait)
        for fqn in rec.handshake(executor, args.wait):
            print(f'{prog}: warning: {fqn} has no parameter services; its first messages may be missed',
                  file=sys.stderr)
        names = ' '.join(p.name for p in plans)
        print(f'{prog}: recording {names} to {args.out} (Ctrl-C to stop; flushed every {args.flush_interval:g} s '
              f'to {rec.bag.work_dir})', file=sys.stderr, flush=True)

        def done() -> bool:
            return stop.requested or (bool(wanted) and all(rec.counts[t] >= n for t, n in wanted.items()))
        seconds = record_until(executor, rec, done, args.duration)
        recorder = None
        path = rec.close()
        total = sum(rec.counts.values())
        per_topic = ', '.join(f'{t}: {n}' for t, n in rec.counts.items())
        print(f'{prog}: wrote {path}: {total} messages in {seconds:.1f} s ({per_topic})', file=sys.stderr)
        return 0
    finally:
        if recorder is not None:
            recorder.abort()
        executor.shutdown()
        close_context(context, node)
        stack.close()
