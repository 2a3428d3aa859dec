"""`fourbar process IN OUT`: the bag fourbar_node would publish for a command bag, without ROS running."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from fourbar_ros.config.interface import STORAGES

HELP = ('write the joint_states and input_torque fourbar_node would publish for a command bag, '
        'computed without the middleware (stamps = the commands\' log times)')


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of `fourbar process`."""
    parser.add_argument('bag', type=Path, metavar='IN', help='command bag (directory, .mcap or .db3)')
    parser.add_argument('out', type=Path, metavar='OUT', help='bag directory to create (must not exist)')
    parser.add_argument('--params', type=Path, metavar='YAML',
                        help='the node\'s parameter file (default: the node\'s default parameters)')
    parser.add_argument('--topic', metavar='NAME',
                        help='command topic (std_msgs/Float64) in IN (default: /antenna_angle_cmd, else the one '
                        '*/antenna_angle_cmd); the outputs go next to it')
    parser.add_argument('--storage', choices=STORAGES,
                        help='storage plugin of OUT (default: that of IN)')


def run(args: argparse.Namespace) -> int:
    """Process; exit 0 with a complete bag, 2 with one line on bad input (nothing written)."""
    from fourbar_ros.bags.process import process_bag
    from fourbar_ros.config.antenna_config import default_config, load_config
    from fourbar_ros.node.run import stop_on_signals

    cfg = load_config(args.params) if args.params is not None else default_config()  # ConfigError: exit 2
    with stop_on_signals():  # SIGTERM, like Ctrl-C, raises KeyboardInterrupt: the partial bag is removed
        stats = process_bag(args.bag, args.out, cfg, topic=args.topic, storage=args.storage)
    print(f'fourbar process: wrote {args.out}: {stats.summary()}', file=sys.stderr)
    return 0
