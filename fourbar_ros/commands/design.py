"""`fourbar design`: Freudenstein synthesis of a four-bar from (crank angle, rocker angle) pairs."""

from __future__ import annotations

import argparse
import json
import math

from fourbar_ros.core.errors import FourBarError
from fourbar_ros.core.synthesis import MAX_CONDITION, Design, synthesize

HELP = 'design a four-bar (link lengths) from 3 or more (crank angle, rocker angle) pairs by Freudenstein\'s equation'

_BRANCH_NAMES = {1: '+1 (open)', -1: '-1 (crossed)', 0: 'toggle (both branches meet)', None: 'unreachable'}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of `fourbar design`."""
    parser.add_argument('--pairs', nargs='+', default=[], metavar='T2,T4',
                        help='crank angle t2 and rocker angle t4 of one position, from the ground line O2->O4 '
                        '(rad; deg with --deg); three pairs give an exact design, more a least-squares fit')
    parser.add_argument('--pair', action='append', default=[], metavar='T2,T4',
                        help='one more pair (repeatable)')
    parser.add_argument('--deg', action='store_true', help='angles are in degrees')
    parser.add_argument('--ground', type=float, default=1.0, metavar='LENGTH',
                        help='ground link length l1 (m); sets the scale (default 1.0)')
    parser.add_argument('--allow-flip', action='store_true',
                        help='accept K1 < 0 or K2 < 0: the crank (rocker) is then built pointing at angle + pi')
    parser.add_argument('--max-condition', type=float, default=MAX_CONDITION, metavar='C',
                        help=f'refuse systems with a larger condition number (default {MAX_CONDITION:g})')
    parser.add_argument('--json', action='store_true', help='print one JSON object (lengths in m, angles in rad)')


def parse_pair(text: str, deg: bool) -> tuple[float, float]:
    """'T2,T4' -> (t2, t4) in rad; raises FourBarError with a one-line message."""
    parts = text.split(',')
    if len(parts) != 2:
        raise FourBarError(f'pair {text!r} must be two angles T2,T4')
    try:
        t2, t4 = float(parts[0]), float(parts[1])
    except ValueError:
        raise FourBarError(f'pair {text!r} must be two numbers T2,T4') from None
    if not (math.isfinite(t2) and math.isfinite(t4)):
        raise FourBarError(f'pair {text!r} must be finite angles')
    return (math.radians(t2), math.radians(t4)) if deg else (t2, t4)


def _text(design: Design, deg: bool) -> str:
    unit = 'deg' if deg else 'rad'

    def ang(x: float | None) -> str:
        if x is None:
            return '-'
        return f'{math.degrees(x):.9f}' if deg else f'{x:.12f}'

    flips = [f'{name} flipped: built pointing at the requested angle + 180 deg'
             for name, flag in (('crank', design.crank_flipped), ('rocker', design.rocker_flipped)) if flag]
    lines = [
        f'Freudenstein constants: K1 = {design.k1!r}, K2 = {design.k2!r}, K3 = {design.k3!r}',
        f'condition number: {design.condition_number:.6g}',
        f'sensitivity: {design.sensitivity:.4g} per rad (an error of 0.01 deg in the angles moves a length by up '
        f'to {100.0 * design.sensitivity * math.radians(0.01):.3g} %)',
        f'lengths (m): ground {design.ground!r}, crank {design.crank!r}, coupler {design.coupler!r}, '
        f'rocker {design.rocker!r}',
        *flips,
        f'Grashof type: {design.grashof_type}',
    ]
    if design.branch is not None:
        lines.append(f'branch: {_BRANCH_NAMES[design.branch]} at every position')
    elif design.mixed_branches:
        lines.append('branch: MIXED - the positions lie on different assembly branches (see the table); a Grashof '
                     'linkage cannot move between them without disassembly')
    else:
        lines.append('branch: not one branch at every position (see the table)')
    lines.append(f'{"pair":>4}  {"t2 (" + unit + ")":>18}  {"t4 requested":>18}  {"t4 linkage":>18}  '
                 f'{"t4 error (rad)":>14}  branch')
    for i, p in enumerate(design.pairs, 1):
        err = '-' if p.t4_error is None else f'{p.t4_error:.3e}'
        lines.append(f'{i:>4}  {ang(p.t2):>18}  {ang(p.t4):>18}  {ang(p.t4_linkage):>18}  {err:>14}  '
                     f'{_BRANCH_NAMES[p.branch]}')
    lines.append(f'residual (2-norm of the Freudenstein residuals): {design.residual:.3e}'
                 + (' (least squares)' if len(design.pairs) > 3 else ''))
    return '\n'.join(lines)


def run(args: argparse.Namespace) -> int:
    """Design and print; bad, degenerate or unbuildable requests raise FourBarError (status 2 from `main`)."""
    pairs = [parse_pair(t, args.deg) for t in [*args.pairs, *args.pair]]
    if len(pairs) < 3:
        raise FourBarError(f'need at least 3 pairs (--pairs T2,T4 T2,T4 T2,T4), got {len(pairs)}')
    if not (math.isfinite(args.max_condition) and args.max_condition > 0.0):
        raise FourBarError(f'--max-condition={args.max_condition} must be finite and > 0')
    design = synthesize(pairs, args.ground, max_condition=args.max_condition, allow_flip=args.allow_flip)
    if args.json:
        print(json.dumps(design.to_dict()))
    else:
        print(_text(design, args.deg))
    return 0
