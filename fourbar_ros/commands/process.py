"""`fourbar process IN OUT`: the bag fourbar_node would publish for a command bag, without ROS running."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from fourbar_ros.commands import add_storage_argument

if TYPE_CHECKING:
    from fourbar_ros.bags.storage import Kind

HELP = ('write the joint_states and input_torque fourbar_node would publish for a command bag, or the completed '
        'joint_states, antenna_angle, antenna_rate and load_torque for a bag of measured joint_states, or the '
        'actuator trajectories for a bag of antenna_trajectory, computed without the middleware')


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of `fourbar process`."""
    parser.add_argument('bag', type=Path, metavar='IN',
                        help='command bag, measured joint_states bag or antenna_trajectory bag (directory, .mcap or '
                        '.db3)')
    parser.add_argument('out', type=Path, metavar='OUT', help='bag directory to create (must not exist)')
    parser.add_argument('--params', type=Path, metavar='YAML',
                        help='the node\'s parameter file (default: the node\'s default parameters)')
    parser.add_argument('--topic', metavar='NAME',
                        help='command topic (std_msgs/Float64) in IN (default: /antenna_angle_cmd, else the one '
                        '*/antenna_angle_cmd), or measured JointState topic (default /joint_states, else the one '
                        '*/joint_states), or antenna trajectory topic (default /antenna_trajectory, else the one '
                        '*/antenna_trajectory); the outputs go next to it')
    add_storage_argument(parser, 'storage plugin of OUT (default: that of IN)', default=None)


def run(args: argparse.Namespace) -> int:
    """Process the first kind the input has (commands, measured joint states, antenna trajectories); exit 0 with
    a complete bag, 2 with one line on bad input (nothing written)."""
    from fourbar_ros.bags.process import process_bag
    from fourbar_ros.bags.process_measured import process_measured_bag
    from fourbar_ros.bags.process_trajectory import process_trajectory_bag
    from fourbar_ros.bags.storage import COMMANDS, MEASURED, TRAJECTORIES, open_bag
    from fourbar_ros.config.antenna_config import default_config, load_config

    cfg = load_config(args.params) if args.params is not None else default_config()  # ConfigError: exit 2
    processors: dict[Kind, Callable[..., Any]] = {
        COMMANDS: process_bag, MEASURED: process_measured_bag, TRAJECTORIES: process_trajectory_bag}
    with open_bag(args.bag) as bag:  # BagError: exit 2
        kind, topic = bag.first(tuple(processors), args.topic)  # else the commands' error
        # a stop raises KeyboardInterrupt (commands.main): the partial bag is removed
        summary = processors[kind](bag, args.out, cfg, topic=topic, storage=args.storage).summary()
    print(f'fourbar process: wrote {args.out}: {summary}', file=sys.stderr)
    return 0
