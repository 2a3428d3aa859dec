"""`fourbar mjcf`: write the linkage and its drive as a MuJoCo model (MJCF), generated from a ROS parameter file."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from fourbar_ros.commands import CommandError
from fourbar_ros.commands._param_file import check_outputs, write_atomically
from fourbar_ros.config.antenna_config import default_config, load_config
from fourbar_ros.interface.topics import NODE_NAME
from fourbar_ros.plant.mjcf import DriveModel, mjcf

HELP = 'write the MuJoCo model (MJCF) of the linkage with its drive, generated from the node\'s parameters'


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of `fourbar mjcf`."""
    defaults = DriveModel()
    parser.add_argument('--params', metavar='YAML', help='ROS parameter file the node reads (e.g. '
                        'config/antenna.yaml); default: the built-in Turnantenna configuration')
    parser.add_argument('--node-name', default=NODE_NAME, help='node whose section of the file applies '
                        f'(default: {NODE_NAME})')
    parser.add_argument('--namespace', default='/', help='namespace of that node (default: /)')
    parser.add_argument('-o', '--output', metavar='FILE', type=Path,
                        help='write the model to FILE (atomically) instead of standard output')
    parser.add_argument('--timestep', type=float, default=defaults.timestep,
                        help=f'simulation step, s (default: {defaults.timestep})')
    parser.add_argument('--rotor-inertia', type=float, default=defaults.rotor_inertia,
                        help=f'motor rotor inertia, kg m^2 at the motor (default: {defaults.rotor_inertia})')
    parser.add_argument('--kp', type=float, default=defaults.kp,
                        help=f'motor position servo gain, N m/rad at the motor (default: {defaults.kp})')
    parser.add_argument('--kv', type=float, default=defaults.kv,
                        help=f'motor servo damping, N m s/rad at the motor (default: {defaults.kv:.3g})')
    parser.add_argument('--reducer-stiffness', type=float, default=None, metavar='K',
                        help='reducer torsional stiffness, N m/rad at the rocker (default: a rigid reducer)')
    parser.add_argument('--backlash', type=float, default=0.0,
                        help='reducer play, rad at the rocker, total (needs --reducer-stiffness; default: 0)')
    parser.add_argument('--stepper-torque', type=float, default=None, metavar='N_M',
                        help='a stepper of this pull-out torque, N m at the motor, instead of the servo (its torque '
                             'is set each step by the Python plant; default: the servo)')
    parser.add_argument('--stepper-teeth', type=int, default=defaults.stepper_teeth,
                        help=f'the stepper\'s rotor teeth (default: {defaults.stepper_teeth}, 1.8 deg full steps)')


def run(args: argparse.Namespace) -> int:
    """Write (or print) the model; a bad parameter file, drive value or output path raises (status 2)."""
    output: Path | None = args.output
    check_outputs([('-o', output)], [Path(args.params)] if args.params is not None else [])
    cfg = default_config() if args.params is None else load_config(args.params, args.node_name, args.namespace)
    try:
        drive = DriveModel(timestep=args.timestep, rotor_inertia=args.rotor_inertia, kp=args.kp, kv=args.kv,
                           reducer_stiffness=args.reducer_stiffness, backlash=args.backlash,
                           stepper_torque=args.stepper_torque, stepper_teeth=args.stepper_teeth)
    except ValueError as exc:
        raise CommandError(str(exc)) from None
    text = mjcf(cfg, drive)
    if output is None:
        sys.stdout.write(text)
    else:
        write_atomically({output: text.encode('utf-8')})
    return 0
