"""`fourbar urdf`: print the linkage's URDF robot model, generated from a ROS parameter file."""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

from ..config import AntennaConfig, default_config, load_config, values_from_yaml
from ..errors import FourBarError
from ..urdf import COUPLER_JOINT, robot_description

HELP = 'print the URDF robot model (for robot_state_publisher) generated from the node\'s parameters'


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of `fourbar urdf`."""
    parser.add_argument('--params', metavar='YAML', help='ROS parameter file the node reads (e.g. '
                        'config/antenna.yaml); default: the built-in Turnantenna configuration')
    parser.add_argument('--node-name', default='fourbar_node', help='node whose section of the file applies '
                        '(default: fourbar_node)')
    parser.add_argument('--namespace', default='/', help='namespace of that node (default: /)')
    parser.add_argument('--robot-name', default='fourbar', help='<robot name=...> (default: fourbar)')
    parser.add_argument('-o', '--output', metavar='FILE', help='write the URDF to FILE (atomically) instead of '
                        'standard output')


def _coupler_joint(args: argparse.Namespace, cfg: AntennaConfig) -> str:
    """The node's ``coupler_joint`` parameter as the file sets it (default: COUPLER_JOINT)."""
    name = getattr(cfg, 'coupler_joint', None)
    if isinstance(name, str):
        return name
    if args.params is None:
        return COUPLER_JOINT
    text = Path(args.params).read_text(encoding='utf-8')  # load_config has read and validated it already
    value = values_from_yaml(text, args.params, args.node_name, args.namespace).get('coupler_joint', COUPLER_JOINT)
    return str(value)


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
    """Print (or write) the URDF; exit 2 with one line on stderr for a bad parameter file."""
    try:
        cfg = (load_config(args.params, args.node_name, args.namespace) if args.params is not None
               else default_config())
        text = robot_description(cfg, _coupler_joint(args, cfg), args.robot_name)
    except (FourBarError, ValueError, OSError) as exc:
        print(f'fourbar urdf: error: {exc}', file=sys.stderr)
        return 2
    if args.output is None:
        sys.stdout.write(text)
        return 0
    try:
        _write(args.output, text)
    except OSError as exc:
        print(f'fourbar urdf: error: cannot write {args.output}: {exc}', file=sys.stderr)
        return 2
    return 0
