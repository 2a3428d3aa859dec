"""`fourbar demo`: the closed loop, fourbar_node in trajectory mode driving the simulated actuator, recorded.

On a free or given ROS domain, discovery limited to this host; both node processes stopped on every path.
What it prints and writes: docs/tutorial.md."""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path
from typing import Any

from fourbar_ros.commands import CommandError, add_storage_argument
from fourbar_ros.interface.topics import (
    BROADCASTER_JOINT_STATES,
    DIAGNOSTICS,
    MEASURED_JOINT_STATES,
    NODE_EXECUTABLE,
    STREAM_DEPTH,
)
from fourbar_ros.live.node_process import FREE_DOMAIN_IDS

HELP = ('the main job: start fourbar_node (trajectory mode) with a parameter file and the simulated actuator, '
        'replay the bundled sweep, record, print a summary and write a PNG plot')

#: Defaults, paths inside the package's share/ (found by config.share.share_path when the demo runs).
DEFAULT_PARAMS = 'config/antenna.yaml'
DEFAULT_BAG = 'bags/demo_sweep'


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
    add_storage_argument(parser, 'storage of the recorded outputs bag')
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
    import dataclasses
    import shutil

    from fourbar_ros.analysis.demo import demo_topics, pace, recording, summarize, summary_lines
    from fourbar_ros.analysis.demo import plot as plot_demo
    from fourbar_ros.bags.storage import read_commands, read_messages
    from fourbar_ros.config.antenna_config import load_config
    from fourbar_ros.config.share import share_path
    from fourbar_ros.interface.stamps import seconds_to_ns
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
    drive = demo_drive()
    if drive != 'mujoco':
        print(f'{prog}: note: the mujoco package is not installed (the plant extra): the simulated actuator runs '
              'its lag drive, whose effort is the load model\'s', file=sys.stderr, flush=True)
    period = pace(stream.values, cfg)
    first = stream.stamps_ns[0] if stream.stamps_ns else 0
    paced = dataclasses.replace(stream, stamps_ns=tuple(first + seconds_to_ns(i * period) for i in range(len(stream))))
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    outputs = out / 'outputs'
    if outputs.exists():  # the previous demo's recording: ours to replace
        shutil.rmtree(outputs)

    topics = demo_topics(cfg.trajectory_controller)
    domain = contextlib.nullcontext(chosen) if chosen is not None else free_domain_id()
    with domain as domain_id:
        print(f'{prog}: fourbar_node (mode trajectory) and the simulated actuator with {args.params} on '
              f'ROS_DOMAIN_ID {domain_id} ({source}; this host only); replaying {len(stream)} commands from '
              f'{args.bag}, one every {period * 1e3:.1f} ms', flush=True)
        replay_seconds, diagnostics = _run_ros(args, paced, domain_id, outputs, topics, cfg, drive)

    rec = recording(read_messages(outputs, topics.all()), topics, cfg)  # read back with rosbags
    figures = summarize(rec, cfg)
    png = plot_demo(rec, figures, cfg, out / 'demo.png',
                    f'fourbar demo: {args.bag.name} replayed into fourbar_node (mode trajectory) driving the '
                    f'simulated actuator (drive {drive})\n({args.params}; driven rocker {cfg.driven.value}, '
                    f'{cfg.reducer_ratio:g}:1, motor {cfg.motor_speed_limit:.4g} rad/s, '
                    f'{cfg.motor_acceleration_limit:g} rad/s^2, {cfg.motor_jerk_limit:g} rad/s^3)')
    for line in summary_lines(rec, figures, cfg, diagnostics, drive):
        print(line)
    print(f'replay   {len(stream)} commands in {replay_seconds:.2f} s; outputs bag {outputs} ({args.storage})')
    print(f'plot     {png}')
    print(f'{prog}: done in {time.monotonic() - start:.1f} s')
    return 0


def demo_drive() -> str:
    """The simulated actuator's drive in the demo: ``mujoco`` (the MuJoCo plant) where the mujoco package imports,
    else ``lag``."""
    import importlib.util

    return 'mujoco' if importlib.util.find_spec('mujoco') is not None else 'lag'


#: Measured antenna angles in a row within the tolerance of the last command that end the run.
SETTLE_SAMPLES = 10


def _settled(antenna: list[float], target: float, tolerance: float, samples: int) -> bool:
    """The last ``samples`` measured antenna angles (rad) are all within ``tolerance`` (rad) of ``target``."""
    return len(antenna) >= samples and all(abs(a - target) <= tolerance for a in antenna[-samples:])


def _run_ros(args: argparse.Namespace, stream: object, domain_id: int, outputs: Path, topics: object,
             cfg: object, drive: str) -> tuple[float, dict[str, str]]:
    """Node and simulated actuator processes, in-process paced replay and recording. Returns (replay seconds,
    last diagnostics). A process that fails or a node that does not answer raises CommandError with status 1.
    """
    import contextlib
    import os

    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.context import Context
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
    from rclpy.node import Node
    from std_msgs.msg import Float64

    from fourbar_ros.analysis.demo import DemoTopics, served
    from fourbar_ros.bags.storage import BagError, CommandStream
    from fourbar_ros.config.antenna_config import AntennaConfig
    from fourbar_ros.live.graph import ReplayError, spin_until
    from fourbar_ros.live.node_process import NodeProcess, node_args, sim_actuator_command
    from fourbar_ros.live.progress import Progress
    from fourbar_ros.live.record import Recorder, discover
    from fourbar_ros.live.replay import Replayer
    from fourbar_ros.live.ros_context import close_context, init_context
    from fourbar_ros.runtime.executor import MessageInfoCallback

    assert isinstance(stream, CommandStream) and isinstance(topics, DemoTopics) and isinstance(cfg, AntennaConfig)
    prog = 'fourbar demo'
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'  # read by the middleware at init
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain_id))
    commands = served(stream.values, cfg).theta
    if commands.size == 0:
        raise CommandError(f'{args.bag}: the node serves none of its {len(stream)} commands', status=2)
    # The drive starts at rest at the first served command; its limits are the motor's through the reducer (the
    # plant's servo takes the motor's speed limit from the parameters itself).
    node = NodeProcess(node_args(args.params, '-p', 'mode:=trajectory', '-p', 'joint_state_rate:=0.0',
                                 '-r', f'{MEASURED_JOINT_STATES.name}:={BROADCASTER_JOINT_STATES.name}'), env,
                       log_path=args.out / 'node.log')
    sim = NodeProcess(node_args(args.params, '-p', f'drive:={drive}',
                                '-p', f'initial_theta:={float(commands[0])!r}',
                                '-p', f'max_velocity:={cfg.motor_speed_limit / cfg.reduction!r}',
                                '-p', f'max_acceleration:={cfg.motor_acceleration_limit / cfg.reduction!r}'),
                      env, command=sim_actuator_command(), log_path=args.out / 'sim_actuator.log')
    stack = contextlib.ExitStack()
    stack.callback(_stop_process, node, NODE_EXECUTABLE)  # on every path, last
    stack.callback(_stop_process, sim, 'the simulated actuator')
    context: Context | None = None
    ros: Node | None = None
    executor: SingleThreadedExecutor | None = None
    recorder: Recorder | None = None
    diagnostics: list[dict[str, str]] = []
    antenna: list[float] = []
    antenna_sources: list[int] = []  # each antenna angle's source timestamp (ns)

    names = {NODE_EXECUTABLE: node, 'the simulated actuator': sim}

    def failed() -> str | None:
        return next((name for name, p in names.items() if not p.running()), None)
    try:  # from the processes' start on: a Ctrl-C at any point still stops them (the stack's callbacks)
        node.start()
        sim.start()
        context = init_context(domain_id=domain_id)  # Ctrl-C: KeyboardInterrupt (commands.main)
        ros = Node('fourbar_demo', context=context, start_parameter_services=False)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(ros)
        replayer = Replayer(ros, stream, topic=topics.command)
        ros.create_subscription(DiagnosticArray, DIAGNOSTICS.name,
                                lambda m: diagnostics.append(_diag_values(m)), DIAGNOSTICS.depth)

        def on_antenna(msg: Float64, info: dict[str, Any]) -> None:
            antenna.append(msg.data)
            antenna_sources.append(int(info.get('source_timestamp') or 0))
        ros.create_subscription(Float64, topics.antenna_angle, MessageInfoCallback(on_antenna), STREAM_DEPTH)
        # The simulated actuator's measured joint and the node's complete joint states: both publishers first.
        spin_until(executor, lambda: failed() is not None or (ros.count_publishers(topics.measured) >= 1
                                                             and ros.count_publishers(topics.joint_states) >= 1),
                   args.timeout)
        plans = discover(ros, executor, topics.all(), args.timeout, stop=lambda: failed() is not None)
        if (dead := failed()) is not None:
            proc = names[dead]
            raise ReplayError(f'{dead} exited with status {proc.proc.poll() if proc.proc else "?"}: '
                              f'{proc.last_log_line()}')
        recorder = Recorder(ros, outputs, plans, args.storage)
        recorder.handshake(executor, args.timeout, own=(topics.command,))
        rec = recorder
        # Every publisher matched, and the node completes measurements (so it plans from the measured position).
        if not spin_until(executor, lambda: rec.matched() and bool(antenna), args.timeout):
            raise ReplayError(f'no measured antenna angle from fourbar_node within {args.timeout:g} s'
                              if rec.matched() else
                              f'the recording did not match every publisher of {", ".join(topics.all())} within '
                              f'{args.timeout:g} s')
        replayer.prepare_timed(executor, args.timeout)
        print(f'{prog}: fourbar_node (pid {node.proc.pid if node.proc else "?"}) and the simulated actuator '
              f'(pid {sim.proc.pid if sim.proc else "?"}) are up; replaying paced', file=sys.stderr, flush=True)
        progress = Progress(len(stream), 'replay')
        stats = replayer.run_timed(executor, 1.0, progress)
        progress.end()
        # The drive comes to rest at the last served command: SETTLE_SAMPLES measured angles in a row within the
        # trajectory tolerance (or the deadline; the summary then shows the error left).
        target = float(commands[-1])
        seen = len(antenna)
        if not spin_until(executor, lambda: len(antenna) > seen and _settled(
                antenna, target, cfg.trajectory_tolerance, SETTLE_SAMPLES), args.timeout):
            print(f'{prog}: warning: the measured antenna angle did not settle within '
                  f'{cfg.trajectory_tolerance:g} rad of the last command in {args.timeout:g} s', file=sys.stderr)
        # The recording's own subscription may still have older angles queued (a busy machine): it ends with the
        # angle seen last here, or a later one.
        last_seen = antenna_sources[-1]
        if not spin_until(executor, lambda: rec.last_source_ns[topics.antenna_angle] >= last_seen, args.timeout):
            raise ReplayError(f'the recording did not receive the last measured antenna angle within '
                              f'{args.timeout:g} s')
        total = len(stream)
        seen = len(diagnostics)
        if not spin_until(executor, lambda: any(d.get('commands_received') == str(total)
                                                for d in diagnostics[seen:]), args.timeout):
            raise ReplayError(f'no diagnostics counting all {total} commands within {args.timeout:g} s')
        final = next(d for d in diagnostics[seen:] if d.get('commands_received') == str(total))
        rec, recorder = recorder, None
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
                close_context(context, *([] if ros is None else [ros]))
        finally:
            stack.close()


def _stop_process(proc: object, name: str) -> None:
    """Stop a node process; say so if it did not exit cleanly."""
    from fourbar_ros.live.node_process import NodeProcess, NodeStopError

    assert isinstance(proc, NodeProcess)
    try:
        status = proc.stop() if proc.proc is not None else 0
    except NodeStopError as exc:
        print(f'fourbar demo: warning: {exc}; killed (see {proc.log_path})', file=sys.stderr)
        return
    if status != 0:
        print(f'fourbar demo: warning: {name} exited with status {status} (see {proc.log_path})',
              file=sys.stderr)
