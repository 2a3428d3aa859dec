"""`fourbar zero BAG --params FILE --angle-topic TOPIC`: the driven joint's zero from the antenna sensor at rest."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from fourbar_ros.commands import CommandError

if TYPE_CHECKING:
    from fourbar_ros.bags.calibration_data import CalibrationData

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
    from fourbar_ros.commands._param_file import check_outputs, param_file_with, write_atomically
    from fourbar_ros.config.antenna_config import load_config
    from fourbar_ros.core.calibration import CalibrationError, rest_zero

    check_outputs((('-o', args.output),), inputs=(args.bag,))
    cfg = load_config(args.params)  # ConfigError: exit 2
    try:
        data = read_calibration_data(args.bag, cfg.driven_joint, args.angle_topic, args.measured_topic)
        _check_enough_finite(data)
        zero = rest_zero(cfg.linkage, cfg.driven, cfg.branch, data.q, data.theta, cfg.antenna_sensor_offset)
        offset = cfg.driven_joint_offset + zero.correction
        files = {} if args.output is None else {args.output: param_file_with(
            args.params, args.bag, {'driven_joint_offset': offset}, 'fourbar zero').encode()}
    except CalibrationError as exc:
        raise CommandError(str(exc), status=1) from None
    write_atomically(files)
    print(f'driven_joint_offset {offset!r} rad (sd {zero.sd:.2g} rad from the readings\' noise; the file\'s '
          f'{cfg.driven_joint_offset!r} plus {zero.correction:.6g}): the antenna at theta = {zero.theta:.6g} rad from '
          f'{zero.readings} readings at rest ({_set_aside(zero.set_aside, data)}); the calibration\'s absolute-angle '
          'sd adds to it' + ''.join(f'\n  wrote {path}' for path in files))
    return 0


def _set_aside(spikes: int, data: CalibrationData) -> str:
    """The readings left out of the zero: the spikes, and the non-finite readings (NaN, +-inf) the recording's
    reader drops, of the sensor and of the joint."""
    from fourbar_ros.core.calibration import SET_ASIDE_SDS

    total = spikes + data.sensor_invalid
    parts = [f'{total} set aside' + (f': {spikes} beyond {SET_ASIDE_SDS:g} noise sds, {data.sensor_invalid} not finite'
                                     if data.sensor_invalid else '')]
    if data.joint_invalid:
        parts.append(f'{data.joint_invalid} non-finite joint positions dropped')
    return ', '.join(parts)


def _check_enough_finite(data: CalibrationData) -> None:
    """CalibrationError (one line) when the non-finite readings leave fewer than two paired: rest_zero would report
    a joint that moved, hiding why."""
    from fourbar_ros.core.calibration import CalibrationError

    if data.sensor_invalid and data.q.size < 2:
        total = data.sensor_invalid + data.sensor_times.size
        raise CalibrationError(f'{data.path}: {data.sensor_invalid} of the {total} readings on {data.sensor_topic} '
                               f'are not finite (NaN or inf), leaving {data.q.size} paired with the joint states: too '
                               'few for a zero')
