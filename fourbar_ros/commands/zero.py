"""`fourbar zero BAG --params FILE --angle-topic TOPIC`: the driven joint's zero from the antenna sensor at rest."""

from __future__ import annotations

import argparse
from pathlib import Path

from fourbar_ros.commands import CommandError

HELP = ('the driven joint\'s zero (driven_joint_offset) from a few seconds of the antenna sensor and the joint at '
        'rest, with the calibrated parameter file: for a drive whose encoder loses its zero at power-up')


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of `fourbar zero`."""
    parser.add_argument('bag', type=Path, metavar='BAG', help='the recording at rest (directory, .mcap or .db3)')
    parser.add_argument('--params', type=Path, metavar='FILE', required=True,
                        help='the calibrated parameter file (`fourbar calibrate`): the lengths, antenna_sensor_offset, '
                        'and the driven_joint_offset in effect while recording')
    parser.add_argument('--angle-topic', metavar='TOPIC', required=True,
                        help='the antenna angle sensor: std_msgs/Float64 (rad) or sensor_msgs/Imu')
    parser.add_argument('--measured-topic', metavar='TOPIC',
                        help='the measured driven joint, sensor_msgs/JointState (default as `fourbar calibrate`)')
    parser.add_argument('-o', '--output', type=Path, metavar='OUT.yaml',
                        help='write the parameter file with the new driven_joint_offset')


def run(args: argparse.Namespace) -> int:
    """Print the zero in one line (and write OUT.yaml); exit 1 with one line when the recording cannot give it, 2 on
    bad input."""
    from fourbar_ros.bags.calibration_data import read_calibration_data
    from fourbar_ros.commands._param_file import param_file_with, write_atomically
    from fourbar_ros.config.antenna_config import load_config
    from fourbar_ros.core.calibration import CalibrationError, rest_zero

    if args.output is not None and not args.output.parent.is_dir():
        raise CommandError(f'{args.output}: directory {args.output.parent} does not exist')
    cfg = load_config(args.params)  # ConfigError: exit 2
    try:
        data = read_calibration_data(args.bag, cfg.driven_joint, args.angle_topic, args.measured_topic)
        zero = rest_zero(cfg.linkage, cfg.driven, cfg.branch, data.q, data.theta, cfg.antenna_sensor_offset)
        offset = cfg.driven_joint_offset + zero.correction
        files = {} if args.output is None else {args.output: param_file_with(
            args.params, args.bag, {'driven_joint_offset': offset}, 'fourbar zero').encode()}
    except CalibrationError as exc:
        raise CommandError(str(exc), status=1) from None
    write_atomically(files)
    print(f'driven_joint_offset {offset!r} rad (sd {zero.sd:.2g} rad from the readings\' noise; the file\'s '
          f'{cfg.driven_joint_offset!r} plus {zero.correction:.6g}): the antenna at theta = {zero.theta:.6g} rad from '
          f'{zero.readings} readings at rest ({zero.set_aside} set aside); the calibration\'s absolute-angle sd adds '
          'to it' + ''.join(f'\n  wrote {path}' for path in files))
    return 0
