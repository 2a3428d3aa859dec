"""`fourbar compare A B`: compare two bags of the node's outputs message by message."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from fourbar_ros.interface.topics import COMPARED_FIELDS, DEFAULT_ULPS

HELP = ('compare two bags of the node\'s outputs message by message: every JointState, Float64 and JointTrajectory '
        'topic (ulps of each value\'s scale, or --atol); exit 0 equal, 1 different, 2 bad input')


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of `fourbar compare`."""
    parser.add_argument('a', type=Path, metavar='A', help='bag (directory, .mcap or .db3)')
    parser.add_argument('b', type=Path, metavar='B', help='bag to compare with A')
    tol = parser.add_mutually_exclusive_group()
    tol.add_argument('--ulps', type=float, default=DEFAULT_ULPS, metavar='N',
                     help=f'allowed difference in units in the last place of each value\'s scale (default: '
                     f'{DEFAULT_ULPS:g}; see docs/how-to/bags.md for the scales)')
    tol.add_argument('--atol', type=float, metavar='X', help='allowed absolute difference instead (rad, rad/s, N m)')
    parser.add_argument('--ignore', default='', metavar='FIELDS',
                        help=f'comma-separated fields not to compare, of {",".join(COMPARED_FIELDS)}: stamps are '
                        'header stamps and log times; positions, velocities (with trajectory accelerations) and '
                        'efforts those of JointStates and trajectory points; the others the data of the Float64 '
                        'topic of that name (e.g. a recording of a live node against `fourbar process`: '
                        'stamps,velocities, which come from the node\'s clock)')
    parser.add_argument('--params', type=Path, metavar='YAML',
                        help='parameter file of the node (geometry for the torque\'s condition; default: defaults)')
    parser.add_argument('--show', type=int, default=10, metavar='N', help='print the first N differences (default 10)')


def run(args: argparse.Namespace) -> int:
    """Compare; exit 0 when equal within the tolerance, 1 when not, 2 on bad input."""
    from fourbar_ros.bags.compare import compare_bags
    from fourbar_ros.config.antenna_config import default_config, load_config

    cfg = load_config(args.params) if args.params is not None else default_config()
    ignore = [f for f in args.ignore.split(',') if f]
    result = compare_bags(args.a, args.b, cfg, ulps=args.ulps, atol=args.atol, ignore=ignore,
                          limit=max(args.show, 0))
    for diff in result.differences:
        print(diff.describe())
    tolerance = f'atol {args.atol:g}' if args.atol is not None else f'{args.ulps:g} ulps of scale'
    counts = ', '.join(f'{t} {n}' for t, n in sorted(result.compared.items())) or 'none'
    worst = max(result.worst.values(), default=0.0)
    verdict = 'equal' if result.equal else f'{result.mismatches} differences'
    print(f'fourbar compare: {verdict} ({tolerance}; messages compared: {counts}; largest difference '
          f'{worst:.3g} of the allowed{"; ignored: " + ",".join(ignore) if ignore else ""})',
          file=sys.stdout)
    return 0 if result.equal else 1
