"""`fourbar check`: the antenna design check over the configured tilt range (exit 1 when a limit fails)."""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import textwrap
from pathlib import Path
from typing import TYPE_CHECKING

from fourbar_ros.commands import CommandError
from fourbar_ros.config.antenna_config import (
    AntennaConfig,
    ConfigError,
    config_from_values,
    declared_values,
    unknown_in_node_sections,
    values_from_yaml,
)
from fourbar_ros.config.rcl_yaml import read_text
from fourbar_ros.core.design_check import (
    DEFAULT_SAMPLES,
    MAX_SAMPLES,
    CheckLimits,
    DesignReport,
    check_design,
    format_report,
)
from fourbar_ros.core.errors import FourBarError

if TYPE_CHECKING:
    from fourbar_ros.core.design_check import Curves

HELP = ('check the antenna linkage over its tilt range: reach margin, transmission angle, torque vs the drive\'s '
        'limits, sensitivity; exit 1 on failure')

#: flag dest -> parameter name, for flags that override a parameter of the file (or of the defaults).
_OVERRIDES = {
    'frame': 'frame_length', 'rocker': 'rocker_ab_length', 'rocker_cd': 'rocker_cd_length',
    'coupler': 'coupler_length', 'theta_min': 'theta_min', 'theta_max': 'theta_max',
    'load_torque': 'load_torque', 'driven': 'driven_rocker', 'branch': 'branch',
    'reducer_ratio': 'reducer_ratio', 'reducer_efficiency': 'reducer_efficiency',
    'motor_torque_limit': 'motor_torque_limit', 'output_torque_limit': 'output_torque_limit',
    'min_transmission_angle': 'transmission_angle_min',
}
_ANGLE_FLAGS = ('theta_min', 'theta_max', 'min_transmission_angle')


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of `fourbar check`."""
    parser.add_argument('--params', metavar='YAML', help='ROS parameter file (e.g. config/antenna.yaml); default: '
                        'the built-in Turnantenna configuration. Flags below override its values.')
    geo = parser.add_argument_group('geometry and drive (override --params)')
    geo.add_argument('--frame', type=float, metavar='H', help='frame AD length (m)')
    geo.add_argument('--rocker', type=float, metavar='L', help='rocker AB length (m), and CD unless --rocker-cd')
    geo.add_argument('--rocker-cd', type=float, metavar='L', help='rocker CD length (m) if it differs from AB')
    geo.add_argument('--coupler', type=float, metavar='C', help='coupler BC length (m)')
    geo.add_argument('--theta-min', type=float, metavar='RAD', help='lowest antenna angle (rad; deg with --deg)')
    geo.add_argument('--theta-max', type=float, metavar='RAD', help='highest antenna angle (rad; deg with --deg)')
    geo.add_argument('--load-torque', type=float, metavar='NM', help='constant load torque about theta (N m)')
    geo.add_argument('--driven', choices=['gamma', 'delta'], help='driven rocker')
    geo.add_argument('--branch', choices=['upper', 'lower'], help='assembly branch')
    geo.add_argument('--reducer-ratio', type=float, metavar='N', help='reducer ratio motor:rocker')
    geo.add_argument('--reducer-efficiency', type=float, metavar='ETA', help='reducer efficiency in (0, 1]')
    geo.add_argument('--motor-torque-limit', type=float, metavar='NM', help='motor torque limit (N m, motor side)')
    geo.add_argument('--output-torque-limit', type=float, metavar='NM',
                     help='reducer rating at the driven rocker (N m)')
    lim = parser.add_argument_group('check limits')
    lim.add_argument('--min-transmission-angle', type=float, metavar='ANGLE',
                     help='fail where the transmission angle comes closer than this to a dead point (rad; deg with '
                     '--deg); default: the configuration\'s transmission_angle_min')
    lim.add_argument('--min-reach-margin', type=float, default=0.0, metavar='ANGLE',
                     help='fail when an end of the tilt range is closer than this to the reach limit '
                     '(rad; deg with --deg; default 0)')
    parser.add_argument('--deg', action='store_true', help='angle flags are in degrees')
    parser.add_argument('--samples', type=integer, default=DEFAULT_SAMPLES, metavar='N',
                        help=f'grid intervals over the tilt range, 2 to {MAX_SAMPLES} (default {DEFAULT_SAMPLES}; '
                        'extrema are refined between grid points)')
    parser.add_argument('--plot', metavar='FILE.png', help='write a figure: the mechanism at both ends and the '
                        'middle of the range, input torque and transmission angle curves')
    parser.add_argument('--json', action='store_true', help='print one JSON object (rad, N m)')


def integer(text: str) -> int:
    """An integer count, also written as 1e5 or 2000.0 (argparse reports a ValueError as 'invalid value')."""
    try:
        return int(text)
    except ValueError:
        value = float(text)
        if not value.is_integer():
            raise ValueError(text) from None
        return int(value)


def configuration(args: argparse.Namespace) -> AntennaConfig:
    """The validated configuration: file (or defaults) values, overridden by the flags."""
    values: dict[str, object] = {}
    if args.params is not None:
        # Names that are not fourbar_node parameters are ignored, as the node ignores them (see run's warning).
        values = declared_values(values_from_yaml(read_text(args.params), args.params))
    for dest, name in _OVERRIDES.items():
        value = getattr(args, dest)
        if value is None:
            continue
        if dest in _ANGLE_FLAGS and args.deg:
            value = math.radians(value)
        values[name] = value
    if args.rocker is not None and args.rocker_cd is None:
        values['rocker_cd_length'] = args.rocker
    try:
        return config_from_values(values)
    except ConfigError as exc:
        raise ConfigError(f'{args.params}: {exc}' if args.params else str(exc), exc.names) from None


def warn_unknown_parameters(prog: str, path: str | None) -> None:
    """One warning line on stderr naming undeclared parameters in the file's sections for fourbar_node."""
    if path is None:
        return
    unknown = unknown_in_node_sections(path)
    if unknown:
        print(f"{prog}: warning: {path}: not fourbar_node parameters, ignored: {', '.join(unknown)}",
              file=sys.stderr)


def _limits(args: argparse.Namespace) -> CheckLimits:
    margin = math.radians(args.min_reach_margin) if args.deg else args.min_reach_margin
    if not math.isfinite(margin):
        raise FourBarError(f'--min-reach-margin={args.min_reach_margin} must be finite')
    return CheckLimits(min_reach_margin=margin)


def run(args: argparse.Namespace) -> int:
    """Check; exit 0 (pass) or 1 (a limit fails); bad input raises (status 2, one line, from `main`)."""
    if not 2 <= args.samples <= MAX_SAMPLES:
        raise FourBarError(f'--samples={args.samples} must be between 2 and {MAX_SAMPLES}')
    cfg = configuration(args)
    limits = _limits(args)
    warn_unknown_parameters('fourbar check', args.params)
    if args.plot is not None:
        _check_plot_path(args.plot)
    report = check_design(cfg, limits, args.samples)
    if args.plot is not None:
        try:
            _plot(cfg, report, args.plot, args.samples)
        except OSError as exc:
            raise CommandError(f'cannot write {args.plot}: {exc.strerror or exc}') from None
    if args.json:
        print(json.dumps(report.to_dict()))
    else:
        print(format_report(report))
        if args.plot is not None:
            print(f'plot: {args.plot}')
    return 0 if report.passed else 1


def _check_plot_path(path: str) -> None:
    suffix = Path(path).suffix.lower().lstrip('.')
    if suffix not in ('png', 'pdf', 'svg'):
        raise FourBarError(f'--plot={path}: the file name must end in .png, .pdf or .svg')
    if not Path(path).resolve().parent.is_dir():
        raise FourBarError(f'--plot={path}: the directory does not exist')


def _plot(cfg: AntennaConfig, report: DesignReport, path: str, samples: int) -> None:
    """Write the figure atomically (a temporary file in the same directory, then renamed)."""
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    from fourbar_ros.core.design_check import TRANSMISSION_RULE_OF_THUMB, sample_curves
    from fourbar_ros.core.transforms import antenna_joint_positions

    curves: Curves = sample_curves(cfg, samples)
    deg = [math.degrees(t) for t in curves.theta]
    fig = plt.figure(figsize=(12, 9))
    grid = fig.add_gridspec(2, 2, height_ratios=[1.0, 1.0])
    ax_m = fig.add_subplot(grid[0, :])
    ax_t = fig.add_subplot(grid[1, 0])
    ax_mu = fig.add_subplot(grid[1, 1])

    link = cfg.linkage
    mid = 0.5 * (cfg.theta_min + cfg.theta_max)
    for theta, colour in ((cfg.theta_min, 'tab:blue'), (mid, 'tab:gray'), (cfg.theta_max, 'tab:red')):
        gamma, delta = link.rocker_angles(theta, cfg.branch)
        assert link.rocker_cd is not None
        j = antenna_joint_positions(link.frame, link.rocker_ab, link.coupler, link.rocker_cd, theta, gamma, delta)
        xs = [j.a[0], j.b[0], j.c[0], j.d[0]]
        ys = [j.a[1], j.b[1], j.c[1], j.d[1]]
        ax_m.plot(xs, ys, '-o', color=colour, lw=1.6, ms=4,
                  label=f'theta {math.degrees(theta):+.2f} deg')
        ax_m.plot(xs[1:3], ys[1:3], '-', color=colour, lw=5, alpha=0.45, solid_capstyle='round')
    ax_m.plot([0.0, link.frame], [0.0, 0.0], 'k-', lw=3, alpha=0.6)
    for x, name in ((0.0, 'A'), (link.frame, 'D')):
        ax_m.annotate(name, (x, 0.0), textcoords='offset points', xytext=(0, -14), ha='center')
    ax_m.set_aspect('equal')
    ax_m.margins(x=0.05, y=0.25)
    ax_m.set_xlabel('x (m)')
    ax_m.set_ylabel('y (m)')
    ax_m.set_title(f'mechanism (driven rocker {cfg.driven.value}; thick: coupler/antenna)')
    ax_m.legend(loc='center left', bbox_to_anchor=(1.01, 0.5), fontsize=9)
    ax_m.grid(alpha=0.3)

    ax_t.plot(deg, [abs(v) for v in curves.input_torque], color='tab:purple', label='|input torque| at rocker')
    ax_t.axhline(cfg.output_torque_limit, color='tab:red', ls='--',
                 label=f'reducer rating {cfg.output_torque_limit:g} N m')
    motor_equiv = cfg.motor_torque_limit * cfg.reduction * cfg.reducer_efficiency
    ax_t.axhline(motor_equiv, color='tab:orange', ls=':',
                 label=f'motor limit x ratio x efficiency = {motor_equiv:.4g} N m')
    ax_t.plot([math.degrees(report.peak_input_torque.theta)], [report.peak_input_torque.value], 'kx')
    ax_t.set_xlabel('theta (deg)')
    ax_t.set_ylabel('torque at the driven rocker (N m)')
    ax_t.set_title(f'input torque, load {cfg.load_torque:g} N m' + (' + weight' if cfg.has_gravity_load else ''))
    ax_t.set_ylim(bottom=0.0)
    ax_t.legend(fontsize=8, loc='lower left')
    ax_t.grid(alpha=0.3)

    mu = [math.degrees(min(m, math.pi - m)) for m in curves.transmission_angle]
    ax_mu.plot(deg, mu, color='tab:green', label='min(mu, 180 - mu)')
    ax_mu.axhline(math.degrees(TRANSMISSION_RULE_OF_THUMB), color='tab:orange', ls=':', label='40 deg rule of thumb')
    ax_mu.axhline(math.degrees(report.transmission_limit), color='tab:red', ls='--',
                  label=f'limit {math.degrees(report.transmission_limit):.4g} deg')
    ax_mu.plot([math.degrees(report.min_transmission.theta)], [math.degrees(report.min_transmission.value)], 'kx')
    ax_mu.set_xlabel('theta (deg)')
    ax_mu.set_ylabel('transmission angle from dead point (deg)')
    ax_mu.set_title('transmission angle')
    ax_mu.set_ylim(0.0, 90.0)
    ax_mu.legend(fontsize=8, loc='lower left')
    ax_mu.grid(alpha=0.3)

    fig.suptitle(textwrap.fill(f'fourbar check: {report.verdict}', 130), fontsize=10,
                 color='tab:green' if report.passed else 'tab:red')
    fig.tight_layout()
    target = Path(path)
    tmp = target.with_name(f'.{target.name}.{os.getpid()}.tmp')
    try:
        fig.savefig(tmp, format=target.suffix.lower().lstrip('.'), dpi=110)
        os.replace(tmp, target)
    finally:
        plt.close(fig)
        if tmp.exists():
            tmp.unlink()
