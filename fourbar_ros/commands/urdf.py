"""`fourbar urdf`: print the linkage's URDF robot model, generated from a ROS parameter file."""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

from fourbar_ros.commands import CommandError
from fourbar_ros.config.antenna_config import default_config
from fourbar_ros.config.robot_model import (
    DEFAULT_HARDWARE_PLUGIN,
    robot_description,
    robot_description_for,
)
from fourbar_ros.core.errors import FourBarError
from fourbar_ros.interface.topics import NODE_NAME

HELP = ('print the URDF robot model (for robot_state_publisher and ros2_control) generated from the node\'s '
        'parameters')


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of `fourbar urdf`."""
    parser.add_argument('--params', metavar='YAML', help='ROS parameter file the node reads (e.g. '
                        'config/antenna.yaml); default: the built-in Turnantenna configuration')
    parser.add_argument('--node-name', default=NODE_NAME, help='node whose section of the file applies '
                        f'(default: {NODE_NAME})')
    parser.add_argument('--namespace', default='/', help='namespace of that node (default: /)')
    parser.add_argument('--robot-name', default='fourbar', help='<robot name=...> (default: fourbar)')
    parser.add_argument('--hardware-plugin', default=DEFAULT_HARDWARE_PLUGIN, metavar='PLUGIN',
                        help='hardware interface of the <ros2_control> block (default: '
                             f'{DEFAULT_HARDWARE_PLUGIN}, which echoes commands as states)')
    parser.add_argument('-o', '--output', metavar='FILE', help='write the URDF to FILE (atomically) instead of '
                        'standard output')


def _write(path: str, text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file in the same directory, so no half file is left."""
    target = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f'.{target.name}.', dir=target.parent if str(target.parent) else '.')
    try:
        with os.fdopen(fd, 'w', encoding='utf-8') as f:
            f.write(text)
        os.replace(tmp, target)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def run(args: argparse.Namespace) -> int:
    """Print (or write) the URDF; a bad parameter file or output path raises (status 2 from `main`)."""
    try:
        if args.params is None:
            text = robot_description(default_config(), args.robot_name, args.hardware_plugin)
        else:
            text = robot_description_for(args.params, args.node_name, args.namespace, args.robot_name,
                                         args.hardware_plugin)[1]
    except FourBarError:
        raise
    except (ValueError, OSError) as exc:
        raise CommandError(str(exc)) from None
    if args.output is None:
        sys.stdout.write(text)
        return 0
    try:
        _write(args.output, text)
    except OSError as exc:
        raise CommandError(f'cannot write {args.output}: {exc}') from None
    return 0
