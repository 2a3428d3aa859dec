"""`fourbar replay BAG`: publish a bag's antenna angle commands to a running fourbar_node."""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from fourbar_ros.commands import CommandError
from fourbar_ros.interface.topics import INPUT_TORQUE, STREAM_DEPTH, sibling_topic

HELP = ('replay a command bag into a running fourbar_node: recorded timing (--rate) '
        'or lock-step with its answers (--as-fast-as-node-keeps-up)')


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of `fourbar replay`."""
    parser.add_argument('bag', type=Path, metavar='BAG', help='rosbag2 bag (directory, .mcap or .db3)')
    mode = parser.add_mutually_exclusive_group()
    mode.add_argument('--rate', type=float, default=1.0, metavar='F',
                      help='play F times as fast as recorded (default: 1.0)')
    mode.add_argument('--as-fast-as-node-keeps-up', dest='lockstep', action='store_true',
                      help='publish each command once the node answered the previous one on '
                      'input_torque (nothing is lost, whatever the speed)')
    parser.add_argument('--clock', nargs='?', type=float, const=40.0, default=None, metavar='HZ',
                        help='timed replay: also publish /clock (rosgraph_msgs/Clock) with the bag\'s playback '
                        'time at HZ (default 40, as `ros2 bag play --clock`), for nodes with use_sim_time:=true; '
                        'put it after BAG or give HZ')
    parser.add_argument('--bag-topic', metavar='NAME',
                        help='the command topic (std_msgs/Float64) to read from BAG, e.g. a namespaced recording\'s '
                        '/robot/antenna_angle_cmd (default: /antenna_angle_cmd, else the one */antenna_angle_cmd)')
    parser.add_argument('--topic', metavar='NAME',
                        help='publish on NAME instead of the recorded topic (e.g. /tilt/antenna_angle_cmd)')
    parser.add_argument('--answer-topic', metavar='NAME',
                        help='lock-step: the node\'s input torque topic, std_msgs/Float64, one message per '
                        'served command (default: input_torque next to the command topic)')
    parser.add_argument('--params', type=Path, metavar='YAML',
                        help='lock-step: predict which commands the node answers from this parameter file '
                        '(default: ask the node for its theta_min, theta_max, out_of_limits)')
    parser.add_argument('--wait', type=float, default=10.0, metavar='S',
                        help='seconds to wait for the node to appear (default: 10)')
    parser.add_argument('--deadline', type=float, default=5.0, metavar='S',
                        help='lock-step: seconds to wait for each answer (default: 5)')
    parser.add_argument('--window', type=int, default=1, metavar='N',
                        help='lock-step: let up to N answers be outstanding (pipelining; default 1: strict '
                        f'lock-step; keep N below the node\'s queue depth, {STREAM_DEPTH})')
    parser.add_argument('--no-progress', action='store_true', help='no progress bar (it is off when '
                        'stderr is not a terminal)')


def run(args: argparse.Namespace) -> int:
    """Replay; exit 0 when every command went out (and, lock-step, every answer came back).

    Bad input raises (status 2), a node that does not answer or goes away raises with status 1; `main` prints it.
    """
    from rclpy.executors import ExternalShutdownException
    from rclpy.node import Node

    from fourbar_ros.bags.storage import read_commands
    from fourbar_ros.live.graph import ReplayError
    from fourbar_ros.live.node_params import Predictor, predictor
    from fourbar_ros.live.progress import Progress
    from fourbar_ros.live.replay import Replayer
    from fourbar_ros.live.ros_context import close_context, init_context
    from fourbar_ros.runtime.executor import create_executor

    prog = 'fourbar replay'
    for name in ('rate', 'wait', 'deadline'):
        value = getattr(args, name)
        if not (math.isfinite(value) and value > 0):
            raise CommandError(f'--{name} must be a positive number, got {value}')
    if args.clock is not None:
        if args.lockstep:
            raise CommandError('--clock works with timed replay (--rate), not --as-fast-as-node-keeps-up')
        if not (math.isfinite(args.clock) and args.clock > 0):
            raise CommandError(f'--clock must be a positive rate in Hz, got {args.clock}')
    if not 1 <= args.window <= STREAM_DEPTH:
        raise CommandError(f'--window must be in 1..{STREAM_DEPTH}, got {args.window}')
    stream = read_commands(args.bag, args.bag_topic)  # BagError: one line, status 2 (main)
    answers_from_file: Predictor | None = None
    if args.params is not None:
        from fourbar_ros.config.antenna_config import load_config

        cfg = load_config(args.params)
        answers_from_file = predictor(cfg.theta_min, cfg.theta_max, cfg.out_of_limits)

    context = init_context()  # a stop raises KeyboardInterrupt (commands.main), not inside a callback
    node = Node('fourbar_replay', context=context, start_parameter_services=False)
    executor = create_executor(context=context)  # $FOURBAR_EXECUTOR, else events
    executor.add_node(node)
    progress = Progress(len(stream), 'replay', enabled=False if args.no_progress else None)
    try:
        topic = args.topic or stream.topic
        answer_topic = None
        if args.lockstep:
            answer_topic = (args.answer_topic
                            or sibling_topic(node.resolve_topic_name(topic), INPUT_TORQUE.name))
        replayer = Replayer(node, stream, topic, answer_topic, clock=args.clock is not None)
        replayer.wait_for_node(executor, args.wait)
        if not args.lockstep:
            unreachable, ignoring = replayer.prepare_timed(executor, args.wait)
            for fqn in unreachable:
                print(f'{prog}: warning: {fqn} has no parameter services; it may miss the first and last commands',
                      file=sys.stderr)
            for fqn in ignoring if args.clock is not None else []:
                print(f'{prog}: warning: {fqn} has use_sim_time false; it ignores /clock', file=sys.stderr)
        if args.lockstep:
            answers = replayer.prepare_lockstep(executor, args.wait, answers_from_file)
            stats = replayer.run_lockstep(executor, answers, args.deadline, progress, args.window)
            progress.end()
            print(f'{prog}: {stats.published} commands in {stats.seconds:.2f} s '
                  f'({stats.rate_hz:.0f}/s) lock-step; {stats.answers} answers on {answer_topic}, '
                  f'{stats.published - stats.expected_answers} commands rejected by the node\'s limits',
                  file=sys.stderr)
        else:
            stats = replayer.run_timed(executor, args.rate, progress,
                                       clock_hz=args.clock if args.clock is not None else 40.0)
            progress.end()
            clock = f'; /clock {stats.clocks} times at {args.clock:g} Hz' if args.clock is not None else ''
            print(f'{prog}: {stats.published} commands in {stats.seconds:.2f} s at rate {args.rate:g} '
                  f'on {replayer.publisher.topic_name}{clock}', file=sys.stderr)
        return 0
    except ReplayError as exc:  # the node did not answer or went away: status 1
        progress.end()
        raise CommandError(str(exc), status=1) from None
    except (KeyboardInterrupt, ExternalShutdownException):
        progress.end()
        print(f'{prog}: interrupted', file=sys.stderr)
        return 130
    finally:
        executor.shutdown()
        close_context(context, node)
