"""`fourbar process IN OUT`: the bag fourbar_node would publish for a command bag, without ROS running."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from fourbar_ros.commands import add_storage_argument

if TYPE_CHECKING:
    from fourbar_ros.config.antenna_config import AntennaConfig

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


def _commands(args: argparse.Namespace, cfg: AntennaConfig) -> str:
    from fourbar_ros.bags.process import process_bag
    return process_bag(args.bag, args.out, cfg, topic=args.topic, storage=args.storage).summary()


def _measured(args: argparse.Namespace, cfg: AntennaConfig) -> str:
    from fourbar_ros.bags.process_measured import process_measured_bag
    return process_measured_bag(args.bag, args.out, cfg, topic=args.topic, storage=args.storage).summary()


def _trajectories(args: argparse.Namespace, cfg: AntennaConfig) -> str:
    from fourbar_ros.bags.process_trajectory import process_trajectory_bag
    return process_trajectory_bag(args.bag, args.out, cfg, topic=args.topic, storage=args.storage).summary()


def _has_commands(path: Path, types: dict[str, str], topic: str | None) -> bool:
    from fourbar_ros.bags.storage import BagError, pick_command_topic
    try:
        pick_command_topic(path, types, topic)
    except BagError:
        return False
    return True


def _has_measured(path: Path, types: dict[str, str], topic: str | None) -> bool:
    from fourbar_ros.bags.process_measured import measured_topic
    return measured_topic(path, types, topic) is not None


def _has_trajectories(path: Path, types: dict[str, str], topic: str | None) -> bool:
    from fourbar_ros.bags.process_trajectory import antenna_trajectory_topic
    return antenna_trajectory_topic(types, topic) is not None


#: What a bag holds -> how it is processed, by the input's topics: the first kind the bag has is processed.
KINDS: tuple[tuple[str, Callable[[Path, dict[str, str], str | None], bool],
                   Callable[[argparse.Namespace, AntennaConfig], str]], ...] = (
    ('commands', _has_commands, _commands),
    ('measured joint states', _has_measured, _measured),
    ('antenna trajectories', _has_trajectories, _trajectories),
)


def run(args: argparse.Namespace) -> int:
    """Process; exit 0 with a complete bag, 2 with one line on bad input (nothing written)."""
    from fourbar_ros.bags.storage import open_bag, topic_types
    from fourbar_ros.config.antenna_config import default_config, load_config

    cfg = load_config(args.params) if args.params is not None else default_config()  # ConfigError: exit 2
    with open_bag(args.bag) as reader:  # BagError: exit 2
        types = topic_types(reader)
    process = next((p for _, has, p in KINDS if has(args.bag, types, args.topic)), _commands)  # else its error
    summary = process(args, cfg)  # a stop raises KeyboardInterrupt (commands.main): the partial bag is removed
    print(f'fourbar process: wrote {args.out}: {summary}', file=sys.stderr)
    return 0
