"""`fourbar solve`: rocker angles, rates, mechanical advantage and input torque at one antenna angle."""

from __future__ import annotations

import argparse
import json
import math
import sys
from dataclasses import replace

from ..antenna import AntennaLinkage, Branch, Driven, LinkageState
from ..config import AntennaConfig, default_config, load_config
from ..errors import FourBarError

HELP = 'solve the linkage at one antenna angle: rocker angles, rates, mechanical advantage, input torque'

_GEOMETRY_FLAGS = ('frame', 'rocker', 'rocker_cd', 'coupler')


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of `fourbar solve`."""
    parser.add_argument('--theta', type=float, required=True, help='antenna angle (rad; deg with --deg), '
                        'positive tilts the antenna down')
    parser.add_argument('--deg', action='store_true', help='--theta is in degrees')
    parser.add_argument('--params', metavar='YAML', help='ROS parameter file (e.g. config/antenna.yaml); '
                        'default: the built-in Turnantenna configuration')
    parser.add_argument('--frame', type=float, metavar='H', help='frame AD length (m)')
    parser.add_argument('--rocker', type=float, metavar='L', help='rocker AB length (m), and CD unless --rocker-cd')
    parser.add_argument('--rocker-cd', type=float, metavar='L', help='rocker CD length (m) if it differs from AB')
    parser.add_argument('--coupler', type=float, metavar='C', help='coupler BC length (m)')
    parser.add_argument('--load-torque', type=float, metavar='NM',
                        help='load torque on the antenna about theta, in the sense of increasing theta (N m); '
                        'default: the configuration\'s load_torque')
    parser.add_argument('--driven', choices=[d.value for d in Driven], help='driven rocker (default: configured)')
    parser.add_argument('--branch', choices=['upper', 'lower'], help='assembly branch (default: configured)')
    parser.add_argument('--json', action='store_true', help='print one JSON object (radians, N m)')


def _configuration(args: argparse.Namespace) -> tuple[AntennaConfig, AntennaLinkage]:
    given = [f for f in _GEOMETRY_FLAGS if getattr(args, f) is not None]
    if args.params is not None and given:
        raise FourBarError(f'--params and --{given[0].replace("_", "-")} exclude each other: '
                           'take the geometry from the file or from the flags')
    cfg = load_config(args.params) if args.params is not None else default_config()
    linkage = cfg.linkage
    if given:
        rocker = cfg.rocker_ab_length if args.rocker is None else args.rocker
        linkage = AntennaLinkage(
            frame=cfg.frame_length if args.frame is None else args.frame,
            rocker_ab=rocker,
            coupler=cfg.coupler_length if args.coupler is None else args.coupler,
            rocker_cd=args.rocker_cd if args.rocker_cd is not None else (rocker if args.rocker is not None
                                                                         else cfg.rocker_cd_length))
    overrides: dict[str, object] = {}
    if args.driven is not None:
        overrides['driven'] = Driven(args.driven)
    if args.branch is not None:
        overrides['branch'] = Branch[args.branch.upper()]
    if args.load_torque is not None:
        if not math.isfinite(args.load_torque):
            raise FourBarError(f'--load-torque={args.load_torque} must be finite (N m)')
        overrides['load_torque'] = args.load_torque
    return (replace(cfg, **overrides) if overrides else cfg), linkage  # type: ignore[arg-type]


def _as_dict(state: LinkageState) -> dict[str, float]:
    keys = ('theta', 'gamma', 'delta', 'dgamma_dtheta', 'ddelta_dtheta', 'input_torque', 'mechanical_advantage',
            'transmission_angle')
    return {k: float(getattr(state, k)) for k in keys}


def run(args: argparse.Namespace) -> int:
    """Solve and print; exit 2 with one line on stderr for unreachable angles or invalid geometry."""
    try:
        cfg, linkage = _configuration(args)
        theta = math.radians(args.theta) if args.deg else args.theta
        state = linkage.state(theta, cfg.load_torque, cfg.driven, cfg.branch)
    except FourBarError as exc:
        print(f'fourbar solve: error: {exc}', file=sys.stderr)
        return 2
    values = _as_dict(state)
    if args.json:
        print(json.dumps({**values, 'load_torque': cfg.load_torque, 'driven': cfg.driven.value,
                          'branch': cfg.branch.name.lower()}))
        return 0
    deg = {'theta', 'gamma', 'delta', 'transmission_angle'}
    print(f'linkage: frame {linkage.frame} m, rockers {linkage.rocker_ab} / {linkage.rocker_cd} m, '
          f'coupler {linkage.coupler} m; branch {cfg.branch.name.lower()}, driven rocker {cfg.driven.value}')
    for key, value in values.items():
        unit = ' N m' if key == 'input_torque' else (' rad' if key in deg else '')
        extra = f'  ({math.degrees(value):.12f} deg)' if key in deg else ''
        print(f'{key:>22}: {value!r}{unit}{extra}')
    print(f'{"load_torque":>22}: {cfg.load_torque!r} N m (about theta)')
    if not cfg.theta_min <= theta <= cfg.theta_max:
        print(f'note: theta is outside the configured tilt range [{cfg.theta_min!r}, {cfg.theta_max!r}] rad')
    return 0
