"""`fourbar solve`: the linkage at one antenna angle, or at the pose a measured rocker angle completes.

The input torque is the node's, through the same core calls (docs/reference/python.md); the output:
docs/reference/cli.md."""

from __future__ import annotations

import argparse
import json
import math
from dataclasses import replace

from fourbar_ros.commands.check import warn_unknown_parameters
from fourbar_ros.config.antenna_config import AntennaConfig, default_config, load_config
from fourbar_ros.core.antenna import AntennaLinkage, Branch, Driven
from fourbar_ros.core.completion import inverse_branch
from fourbar_ros.core.errors import DeadPointError, FourBarError, SingularPositionError, UnreachableError
from fourbar_ros.core.loads import gravity_torque, has_gravity_load, load_at_pose
from fourbar_ros.rules.policy import Outcome, Policy, angle_text, decide, in_reach, out_of_reach_text

HELP = ('solve the linkage at one antenna angle (or a measured rocker angle): rocker angles, rates, second '
        'derivatives, mechanical advantage, input torque')

_GEOMETRY_FLAGS = ('frame', 'rocker', 'rocker_cd', 'coupler')


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of `fourbar solve`."""
    given = parser.add_mutually_exclusive_group(required=True)
    given.add_argument('--theta', type=float, help='antenna angle (rad; deg with --deg), positive tilts the antenna '
                       'down')
    for rocker in Driven:
        given.add_argument(f'--{rocker.value}', type=float, metavar='V',
                           help=f'measured {rocker.value} rocker angle (rad; deg with --deg): the pose it completes '
                           '(on --branch: the pose that --theta on --branch gives)')
    parser.add_argument('--deg', action='store_true', help='the given angle is in degrees')
    parser.add_argument('--params', metavar='YAML', help='ROS parameter file (e.g. config/antenna.yaml); '
                        'default: the built-in Turnantenna configuration')
    parser.add_argument('--frame', type=float, metavar='H', help='frame AD length (m)')
    parser.add_argument('--rocker', type=float, metavar='L', help='rocker AB length (m), and CD unless --rocker-cd')
    parser.add_argument('--rocker-cd', type=float, metavar='L', help='rocker CD length (m) if it differs from AB')
    parser.add_argument('--coupler', type=float, metavar='C', help='coupler BC length (m)')
    parser.add_argument('--load-torque', type=float, metavar='NM',
                        help='constant load torque about theta that the drive must supply, + in the sense of '
                        'increasing theta (N m); default: the configuration\'s load_torque. The antenna\'s weight '
                        '(antenna_mass in --params) adds to it')
    parser.add_argument('--driven', choices=[d.value for d in Driven], help='driven rocker (default: configured)')
    parser.add_argument('--branch', choices=['upper', 'lower'], help='assembly branch (default: configured)')
    parser.add_argument('--json', action='store_true', help='print one JSON object (radians, N m)')


def _configuration(args: argparse.Namespace) -> tuple[AntennaConfig, AntennaLinkage]:
    """The configuration (``--params`` or the built-in one, with the flags' overrides) and its linkage. Geometry
    flags replace the lengths and the linkage in the configuration too: the load model reads them there."""
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
    if given:
        overrides.update(linkage=linkage, frame_length=linkage.frame, rocker_ab_length=linkage.rocker_ab,
                         coupler_length=linkage.coupler, rocker_cd_length=linkage.rocker_cd)
    return (replace(cfg, **overrides) if overrides else cfg), linkage  # type: ignore[arg-type]


_KEYS = ('theta', 'gamma', 'delta', 'dgamma_dtheta', 'ddelta_dtheta', 'd2gamma_dtheta2', 'd2delta_dtheta2',
         'input_torque', 'mechanical_advantage', 'transmission_angle', 'gravity_torque')
_RATES = ('dgamma_dtheta', 'ddelta_dtheta', 'd2gamma_dtheta2', 'd2delta_dtheta2', 'mechanical_advantage')


def _pose(linkage: AntennaLinkage, args: argparse.Namespace, cfg: AntennaConfig) -> tuple[float, float, float]:
    """(theta, gamma, delta) in rad from --theta, or completed from a measured --gamma / --delta: of
    from_rocker's two poses, the one on the branch the node takes for a measurement (``_measured_branch``).

    Raises FourBarError if theta is out of reach (as a number: angles are not wrapped), if the rocker cannot take
    the measured angle (the message names the value and the rocker's range), or if the angle is not finite.
    """
    measured = next((d for d in Driven if getattr(args, d.value) is not None), None)
    value = args.theta if measured is None else getattr(args, measured.value)
    value = math.radians(value) if args.deg else value
    if measured is None:
        if math.isfinite(value) and abs(value) > math.pi:  # the core would wrap it (its theta is periodic)
            raise UnreachableError(f'theta={angle_text(value)} {out_of_reach_text(linkage.reach(), value)}')
        gamma, delta = linkage.rocker_angles(value, cfg.branch)
        return value, float(gamma), float(delta)
    theta, other = linkage.from_rocker(value, measured, _measured_branch(linkage, cfg, measured))
    return (float(theta), value, float(other)) if measured is Driven.GAMMA else (float(theta), float(other), value)


def _measured_branch(linkage: AntennaLinkage, cfg: AntennaConfig, measured: Driven) -> Branch:
    """The branch of ``from_rocker`` that gives back ``cfg.branch``'s pose, by the node's rule
    (``AntennaConfig.measured_branch``: ``inverse_branch`` at mid-range of the tilt limits; at theta = 0 for a
    geometry given on the command line that does not reach that angle). Not by comparing the rocker angles the two
    poses give back: both can be poses of the same branch with the same rocker angle, a tie rounding decides."""
    mid = 0.5 * (cfg.theta_min + cfg.theta_max)
    at = mid if in_reach(linkage.reach(), mid) else 0.0
    return inverse_branch(linkage, at, measured, cfg.branch)


def _solve(linkage: AntennaLinkage, pose: tuple[float, float, float],
           cfg: AntennaConfig) -> tuple[dict[str, float | None], dict[str, str]]:
    """Every quantity of `_KEYS` at the pose (theta, gamma, delta in rad; None where it has no finite value) and,
    for each None, why.

    The pose exists wherever the linkage reaches (also at the reach limit, where the rockers are in line); only the
    rates, their derivatives and the mechanical advantage (a rate) are unbounded there, and the torque is unbounded
    at a dead point. ``gravity_torque`` is the antenna weight's share of the load about theta (N m, + in the sense of
    increasing theta; 0.0 without a weight); with a weight, it and the input torque are undetermined at the reach
    limit (the weight's lever holds dgamma/dtheta).
    """
    theta, gamma, delta = pose
    values: dict[str, float | None] = {'theta': theta, 'gamma': gamma, 'delta': delta}
    reasons: dict[str, str] = {}
    dgamma_dtheta: float | None = None
    try:
        rates = linkage.rates_at(theta, gamma, delta)
        second = linkage.second_derivatives_at(theta, gamma, delta, rates)
        dgamma_dtheta = float(rates[0])
        values['dgamma_dtheta'], values['ddelta_dtheta'] = dgamma_dtheta, float(rates[1])
        values['d2gamma_dtheta2'], values['d2delta_dtheta2'] = float(second[0]), float(second[1])
        values['mechanical_advantage'] = values['dgamma_dtheta' if cfg.driven is Driven.GAMMA else 'ddelta_dtheta']
    except SingularPositionError:
        for key in _RATES:
            values[key] = None
            reasons[key] = 'unbounded: theta is at the reach limit (the rockers are parallel)'
    weight = has_gravity_load(cfg)
    if weight and dgamma_dtheta is None:
        # The weight's lever dy_com/dtheta holds dgamma/dtheta, unbounded here (the torque's limit is finite but
        # the core does not take it).
        for key in ('gravity_torque', 'input_torque'):
            values[key] = None
            reasons[key] = ('undetermined: the antenna weight\'s load needs dgamma/dtheta, unbounded at the reach '
                            'limit')
    else:
        # The core's load model, as the node evaluates it (core.loads.pose_solver): constant plus weight.
        values['gravity_torque'] = (float(gravity_torque(cfg, theta, gamma, dgamma_dtheta))
                                    if weight and dgamma_dtheta is not None else 0.0)
        load = load_at_pose(cfg, theta, gamma, delta, dgamma_dtheta)
        try:
            values['input_torque'] = float(linkage.torque_at(theta, gamma, delta, load, cfg.driven))
        except DeadPointError:
            values['input_torque'] = None
            reasons['input_torque'] = f'unbounded: theta is a dead point of the {cfg.driven.value} rocker'
    values['transmission_angle'] = float(linkage.transmission_angle_at(theta, gamma, delta, cfg.driven))
    for key in _KEYS:
        value = values[key]
        if value is not None and not math.isfinite(value):
            values[key] = None
            reasons[key] = 'overflow: its magnitude exceeds the largest double, 1.8e308'
    return {key: values[key] for key in _KEYS}, reasons


def run(args: argparse.Namespace) -> int:
    """Solve and print; unreachable angles or invalid geometry raise FourBarError (status 2 from `main`).

    JSON is strict (no NaN or Infinity): a quantity without a finite value is null and ``null_reasons`` says why.
    """
    cfg, linkage = _configuration(args)
    pose = _pose(linkage, args, cfg)
    theta = pose[0]
    values, reasons = _solve(linkage, pose, cfg)
    warn_unknown_parameters('fourbar solve', args.params)
    if args.json:
        gravity = values.pop('gravity_torque')
        print(json.dumps({**values, 'load_torque': cfg.load_torque, 'gravity_torque': gravity,
                          'driven': cfg.driven.value, 'branch': cfg.branch.name.lower(), 'null_reasons': reasons},
                         allow_nan=False))
        return 0
    deg = {'theta', 'gamma', 'delta', 'transmission_angle'}
    print(f'linkage: frame {linkage.frame} m, rockers {linkage.rocker_ab} / {linkage.rocker_cd} m, '
          f'coupler {linkage.coupler} m; branch {cfg.branch.name.lower()}, driven rocker {cfg.driven.value}')
    for key, value in values.items():
        if key == 'gravity_torque':
            continue
        if value is None:
            print(f'{key:>22}: none ({reasons[key]})')
            continue
        unit = ' N m' if key == 'input_torque' else ' rad' if key in deg else ' /rad' if key.startswith('d2') else ''
        extra = f'  ({math.degrees(value):.12f} deg)' if key in deg else ''
        print(f'{key:>22}: {value!r}{unit}{extra}')
    print(f'{"load_torque":>22}: {cfg.load_torque!r} N m (about theta)')
    if has_gravity_load(cfg):
        gravity = values['gravity_torque']
        weight = (f'antenna_mass {cfg.antenna_mass!r} kg, centre of mass {cfg.com_offset_along!r} m along B->C and '
                  f'{cfg.com_offset_normal!r} m normal from the coupler midpoint, gravity {cfg.gravity!r} m/s^2')
        print(f'{"gravity_torque":>22}: ' + (f'none ({reasons["gravity_torque"]})' if gravity is None
                                             else f'{gravity!r} N m (about theta, in input_torque: {weight})'))
    decision = decide(theta, cfg.theta_min, cfg.theta_max, Policy(cfg.out_of_limits), linkage.reach())
    if decision.outcome is not Outcome.ACCEPTED:
        print(f'note: as a command, the node would not serve it as is: {decision.reason}')
    return 0
