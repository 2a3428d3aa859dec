"""`fourbar process IN OUT`: the bag fourbar_node would publish for a command bag, without ROS running."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from fourbar_ros.commands import add_storage_argument

if TYPE_CHECKING:
    from fourbar_ros.interface.topics import Kind

HELP = ('write the joint_states and input_torque fourbar_node would publish for a command bag, or the completed '
        'joint_states, antenna_angle, antenna_rate and load_torque for a bag of measured joint states, or the '
        'actuator trajectories for a bag of antenna_trajectory, computed without the middleware')


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of `fourbar process`."""
    parser.add_argument('bag', type=Path, metavar='IN',
                        help='command bag, measured joint states bag or antenna_trajectory bag (directory, .mcap or '
                        '.db3)')
    parser.add_argument('out', type=Path, metavar='OUT', help='bag directory to create (must not exist)')
    parser.add_argument('--params', type=Path, metavar='YAML',
                        help='the node\'s parameter file (default: the node\'s default parameters)')
    parser.add_argument('--topic', metavar='NAME', help=topic_help())
    add_storage_argument(parser, 'storage plugin of OUT (default: that of IN)', default=None)


def topic_help() -> str:
    """``--topic``'s help, from the kinds and their topics the processing looks for (``interface.topics``)
    and the outputs a measured topic must not be one of (``bags.process_measured``)."""
    from fourbar_ros.interface.topics import COMMANDS, MEASURED, PER_MEASUREMENT_OUTPUTS, TRAJECTORIES

    def kind(k: Kind) -> str:
        return (f'{k.role} topic ({k.topics[0].msgtype}; default: {", else ".join(k.ends)}, else the one '
                f'{" or ".join("*" + end for end in k.ends)}')

    outputs = [t.name for t in PER_MEASUREMENT_OUTPUTS]
    return (f'{kind(COMMANDS)}), or {kind(MEASURED)}; any other name ending in /{", /".join(outputs[:-1])} or '
            f'/{outputs[-1]} is refused: the outputs go there), or {kind(TRAJECTORIES)}) in IN; the outputs go next '
            'to it')


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
