"""`fourbar demo`: start fourbar_node, replay the bundled sweep into it, record its outputs, summarize, plot.

Runs on --domain-id, else an exported ROS_DOMAIN_ID, else one nobody on this host uses, with discovery limited to this
host (ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST), so it neither sees nor disturbs other ROS traffic.
The node process is stopped on every path (done, error, Ctrl-C).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

from fourbar_ros.commands import CommandError
from fourbar_ros.config.interface import (
    DEFAULT_STORAGE,
    DIAGNOSTICS,
    PER_COMMAND_OUTPUTS,
    RECORDED_OUTPUTS,
    STORAGES,
)
from fourbar_ros.live.node_process import FREE_DOMAIN_IDS

HELP = ('the main job: start fourbar_node with a parameter file, replay the bundled sweep, record the '
        'outputs, print a summary and write a PNG plot')

#: Defaults, paths inside the package's share/ (found by config.share.share_path when the demo runs).
DEFAULT_PARAMS = 'config/antenna.yaml'
DEFAULT_BAG = 'bags/demo_sweep'
#: The recorded outputs and their names in the root namespace, where the demo's node runs.
OUTPUT_TOPICS = tuple(t.name for t in RECORDED_OUTPUTS)
JOINTS, TORQUE = (f'/{t.name}' for t in PER_COMMAND_OUTPUTS)


def _id_ranges(ids: tuple[int, ...]) -> str:
    """(90, 91, 92, 215, 216) -> '90..92 and 215..216'."""
    runs: list[list[int]] = []
    for i in ids:
        if runs and i == runs[-1][-1] + 1:
            runs[-1].append(i)
        else:
            runs.append([i])
    return ' and '.join(f'{r[0]}..{r[-1]}' if len(r) > 1 else str(r[0]) for r in runs)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of `fourbar demo`."""
    parser.add_argument('--params', type=Path, metavar='YAML',
                        help=f'node parameter file (default: the installed share/fourbar_ros/{DEFAULT_PARAMS}, '
                        'else the one in the source tree)')
    parser.add_argument('--bag', type=Path, metavar='BAG',
                        help='command bag to replay (default: the bundled sweep over the tilt range, '
                        f'share/fourbar_ros/{DEFAULT_BAG})')
    parser.add_argument('--out', type=Path, default=Path('out/demo'), metavar='DIR',
                        help='output directory: outputs bag, demo.png, node.log (default: out/demo)')
    parser.add_argument('--storage', choices=STORAGES, default=DEFAULT_STORAGE.value,
                        help=f'storage of the recorded outputs bag (default: {DEFAULT_STORAGE.value})')
    parser.add_argument('--domain-id', type=int, metavar='N',
                        help='ROS_DOMAIN_ID to use, 0..232 (default: the exported ROS_DOMAIN_ID, else the first free '
                        f'one of {_id_ranges(FREE_DOMAIN_IDS)}, searched from a place set by the process id; free: no '
                        'other fourbar run holds its lock file and no DDS participant on this host holds its '
                        'discovery ports)')
    parser.add_argument('--timeout', type=float, default=30.0, metavar='S',
                        help='deadline for the node to come up and for each wait (default: 30)')


def _diag_values(msg: object) -> dict[str, str]:
    status = getattr(msg, 'status', [])
    return {kv.key: kv.value for kv in status[0].values} if status else {}


def _environment_domain() -> tuple[int | None, str]:
    """An exported ROS_DOMAIN_ID (so other terminals see the demo's topics) and where the domain comes from."""
    text = os.environ.get('ROS_DOMAIN_ID', '').strip()
    if not text:
        return None, 'a free one: ROS_DOMAIN_ID is not set'
    if not (text.isdigit() and 0 <= int(text) <= 232):
        raise CommandError(f'ROS_DOMAIN_ID={text!r} must be an integer in 0..232 (unset it to let the demo pick '
                           'a free one)')
    return int(text), 'from ROS_DOMAIN_ID'


def run(args: argparse.Namespace) -> int:
    """Run the demo; exit 0 with the summary on stdout and the plot written."""
    import contextlib
    import shutil

    from fourbar_ros.bags.demo import core_deviation, pair, plot, summary_lines
    from fourbar_ros.bags.storage import read_commands, read_messages
    from fourbar_ros.config.antenna_config import load_config
    from fourbar_ros.config.share import share_path
    from fourbar_ros.live.node_params import predictor
    from fourbar_ros.live.node_process import free_domain_id

    prog = 'fourbar demo'
    start = time.monotonic()
    if args.params is None:
        args.params = share_path(DEFAULT_PARAMS)
    if args.bag is None:
        args.bag = share_path(DEFAULT_BAG)
    cfg = load_config(args.params)  # one-line ConfigError -> status 2
    stream = read_commands(args.bag)  # one-line BagError -> status 2
    if args.domain_id is not None and not 0 <= args.domain_id <= 232:
        raise CommandError(f'--domain-id must be in 0..232, got {args.domain_id}')
    chosen, source = (args.domain_id, '--domain-id') if args.domain_id is not None else _environment_domain()
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    outputs = out / 'outputs'
    if outputs.exists():  # the previous demo's recording: ours to replace
        shutil.rmtree(outputs)

    domain = contextlib.nullcontext(chosen) if chosen is not None else free_domain_id()
    with domain as domain_id:
        print(f'{prog}: fourbar_node with {args.params} on ROS_DOMAIN_ID {domain_id} ({source}; this host only); '
              f'replaying {len(stream)} commands from {args.bag}', flush=True)
        replay_seconds, diagnostics = _run_ros(args, stream, domain_id, outputs,
                                               predictor(cfg.theta_min, cfg.theta_max, cfg.out_of_limits))

    topics = read_messages(outputs, [JOINTS, TORQUE])  # read back with rosbags
    data = pair(stream.values, cfg, [m for _, m in topics[JOINTS]], [m for _, m in topics[TORQUE]])
    angle_err, torque_err = core_deviation(data, cfg)
    png = plot(data, cfg, out / 'demo.png',
               f'fourbar demo: {args.bag.name} replayed through fourbar_node ({args.params})\n'
               f'frame {cfg.frame_length:g} m, rockers {cfg.rocker_ab_length:g}/{cfg.rocker_cd_length:g} m, '
               f'coupler {cfg.coupler_length:g} m, load {cfg.load_torque:g} N m, driven rocker {cfg.driven.value}')
    for line in summary_lines(data, cfg, diagnostics):
        print(line)
    print(f'check    node vs core: max |d angle| = {angle_err:.3g} rad, max |d torque| = {torque_err:.3g} N m')
    print(f'replay   {len(stream)} commands lock-step in {replay_seconds:.2f} s; outputs bag {outputs} '
          f'({args.storage})')
    print(f'plot     {png}')
    print(f'{prog}: done in {time.monotonic() - start:.1f} s')
    return 0


def _run_ros(args: argparse.Namespace, stream: object, domain_id: int, outputs: Path,
             answers: object) -> tuple[float, dict[str, str]]:
    """Node process + in-process replay and recording. Returns (replay seconds, last diagnostics).

    A node that fails or does not answer raises CommandError with status 1.
    """
    import contextlib
    import os

    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.context import Context
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
    from rclpy.node import Node

    from fourbar_ros.bags.storage import BagError, CommandStream
    from fourbar_ros.live.graph import ReplayError, spin_until
    from fourbar_ros.live.node_process import NodeProcess, node_args
    from fourbar_ros.live.progress import Progress
    from fourbar_ros.live.record import Recorder, discover
    from fourbar_ros.live.replay import Replayer
    from fourbar_ros.live.ros_context import close_context, init_context
    from fourbar_ros.node.run import stop_on_signals

    assert isinstance(stream, CommandStream)
    prog = 'fourbar demo'
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'  # read by the middleware at init
    # One JointState per answered command: the recording is paired with the commands (no idle republishing).
    proc = NodeProcess(node_args(args.params, '-p', 'joint_state_rate:=0.0'),
                       dict(os.environ, ROS_DOMAIN_ID=str(domain_id)), log_path=args.out / 'node.log')
    stack = contextlib.ExitStack()
    stack.enter_context(stop_on_signals())
    stack.callback(_stop_node, proc)  # on every path, last
    context: Context | None = None
    node: Node | None = None
    executor: SingleThreadedExecutor | None = None
    recorder: Recorder | None = None
    diagnostics: list[dict[str, str]] = []
    try:  # from the node's start on: a Ctrl-C at any point still stops it (finally)
        proc.start()
        context = init_context(domain_id=domain_id, handle_signals=False)  # Ctrl-C: KeyboardInterrupt
        node = Node('fourbar_demo', context=context, start_parameter_services=False)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        replayer = Replayer(node, stream, answer_topic=TORQUE)
        node.create_subscription(DiagnosticArray, DIAGNOSTICS.name,
                                 lambda m: diagnostics.append(_diag_values(m)), DIAGNOSTICS.depth)
        plans = discover(node, executor, OUTPUT_TOPICS, args.timeout, stop=lambda: not proc.running())
        if not proc.running():
            raise ReplayError(f'fourbar_node exited with status {proc.proc.poll() if proc.proc else "?"}: '
                              f'{proc.last_log_line()}')
        recorder = Recorder(node, outputs, plans, args.storage)
        replayer.wait_for_node(executor, args.timeout)
        predicted = replayer.prepare_lockstep(executor, args.timeout, answers)  # type: ignore[arg-type]
        pid = proc.proc.pid if proc.proc else '?'
        print(f'{prog}: fourbar_node (pid {pid}) is up; replaying lock-step', file=sys.stderr, flush=True)
        progress = Progress(len(stream), 'replay')
        stats = replayer.run_lockstep(executor, predicted, 5.0, progress)
        progress.end()
        rec = recorder
        want = stats.expected_answers
        if not spin_until(executor, lambda: rec.counts[JOINTS] >= want
                          and rec.counts[TORQUE] >= want, args.timeout):
            raise ReplayError(f'recorded {rec.counts} of {want} answers')
        # The first status that counts every command (published every diagnostics_period s).
        total = len(stream)
        seen = len(diagnostics)
        if not spin_until(executor, lambda: any(d.get('commands_received') == str(total)
                                                for d in diagnostics[seen:]), args.timeout):
            raise ReplayError(f'no diagnostics counting all {total} commands within {args.timeout:g} s')
        final = next(d for d in diagnostics[seen:] if d.get('commands_received') == str(total))
        recorder = None
        rec.close()
        return stats.seconds, final
    except (ReplayError, BagError) as exc:
        raise CommandError(str(exc), status=1) from None
    except (KeyboardInterrupt, ExternalShutdownException):
        print(f'{prog}: interrupted; no outputs bag written', file=sys.stderr)
        raise KeyboardInterrupt from None
    finally:
        try:
            if recorder is not None:
                recorder.abort()
            if executor is not None:
                executor.shutdown()
            if context is not None:
                close_context(context, *([] if node is None else [node]))
        finally:
            stack.close()


def _stop_node(proc: object) -> None:
    """Stop the node process; say so if it did not exit cleanly."""
    from fourbar_ros.live.node_process import NodeProcess, NodeStopError

    assert isinstance(proc, NodeProcess)
    try:
        status = proc.stop() if proc.proc is not None else 0
    except NodeStopError as exc:
        print(f'fourbar demo: warning: {exc}; killed (see {proc.log_path})', file=sys.stderr)
        return
    if status != 0:
        print(f'fourbar demo: warning: fourbar_node exited with status {status} (see {proc.log_path})',
              file=sys.stderr)
