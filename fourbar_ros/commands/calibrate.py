"""`fourbar calibrate BAG --params FILE --angle-topic TOPIC`: the linkage as built, fitted to a recorded sweep."""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from fourbar_ros.commands import CommandError

if TYPE_CHECKING:
    from fourbar_ros.bags.calibration_data import CalibrationData
    from fourbar_ros.config.antenna_config import AntennaConfig
    from fourbar_ros.core.calibration import Calibration, DirectionTerms, Reference

HELP = ('fit the linkage as built (the four lengths, the driven joint\'s offset and the sensor\'s) to a recorded '
        'sweep of the measured driven joint and an antenna angle sensor; write the calibrated parameter file, a '
        'report and a plot of the residuals')

#: A recording must sweep at least this much tilt (rad, 1 deg) to say anything about the geometry.
MIN_TILT_SPAN = math.radians(1.0)
#: Points of the measured joint's swept range at which the report gives the antenna angle and its sd.
GRID_POINTS = 41


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of `fourbar calibrate`."""
    parser.add_argument('bag', type=Path, metavar='BAG', help='the recording (directory, .mcap or .db3)')
    parser.add_argument('--params', type=Path, metavar='FILE', required=True,
                        help='the node\'s parameter file: the lengths as designed (the prior), the driven rocker, '
                        'its joint name and the branch')
    parser.add_argument('--angle-topic', metavar='TOPIC', required=True,
                        help='the antenna angle sensor: std_msgs/Float64 (rad, positive tilts the antenna down) or '
                        'sensor_msgs/Imu (the tilt from gravity, axes as the coupler frame)')
    parser.add_argument('--measured-topic', metavar='TOPIC',
                        help='the measured driven joint, sensor_msgs/JointState (default: '
                        '/joint_state_broadcaster/joint_states or /measured_joint_states, else the one such topic '
                        'in a namespace)')
    parser.add_argument('-o', '--output', type=Path, metavar='OUT.yaml',
                        help='write the parameter file with the calibrated lengths, driven_joint_offset and '
                        'antenna_sensor_offset (and OUT.png, the residuals)')
    parser.add_argument('--report', type=Path, metavar='OUT.json', help='write the report as JSON')
    parser.add_argument('--length-tolerance', type=float, default=5e-4, metavar='M',
                        help='standard deviation of each given length, the prior (m, default 0.0005)')
    parser.add_argument('--sensor-offset', type=float, default=0.0, metavar='RAD',
                        help='the sensor\'s reading with the antenna level as its datasheet or mounting gives it, the '
                        'prior (rad, default 0)')
    parser.add_argument('--sensor-offset-sd', type=float, default=0.1, metavar='RAD',
                        help='standard deviation of --sensor-offset (rad, default 0.1: weak); the antenna\'s absolute '
                        'angle is no better than this unless a --reference pins it')
    parser.add_argument('--reference', action='append', default=[], metavar='JOINT:THETA:SD',
                        help='a known antenna angle, e.g. from a precision level: the measured driven joint JOINT '
                        '(rad, as the joint states report it with this parameter file), the antenna angle THETA there '
                        '(rad, positive tilts the antenna down) and its SD (rad); repeat for more poses; write '
                        '--reference=-0.1:... when JOINT is negative')


def run(args: argparse.Namespace) -> int:
    """Calibrate; exit 0 with the outputs written, 1 with one line when the recording cannot calibrate, 2 on bad
    input; nothing written unless everything is."""
    import numpy as np

    from fourbar_ros.analysis.residual_plot import draw
    from fourbar_ros.bags.calibration_data import read_calibration_data
    from fourbar_ros.commands._param_file import check_outputs, param_file_with, write_atomically
    from fourbar_ros.config.antenna_config import load_config
    from fourbar_ros.core.calibration import (
        LENGTH_NAMES,
        CalibrationError,
        calibrate,
        check_sensor_scale,
        direction_terms,
        far_from_prior,
        sensor_scale,
    )

    for option, value, unit in (('--length-tolerance', args.length_tolerance, 'm'),
                                ('--sensor-offset-sd', args.sensor_offset_sd, 'rad')):
        if not (math.isfinite(value) and value > 0.0):
            raise CommandError(f'{option} {value!r} {unit} must be finite and positive')
    if not math.isfinite(args.sensor_offset):
        raise CommandError(f'--sensor-offset {args.sensor_offset!r} rad must be finite')
    references = [_reference(text) for text in args.reference]
    plot = _plot_path(args.output, args.report)
    check_outputs((('-o', args.output), ('--report', args.report), ('the residual plot', plot)), inputs=(args.bag,))
    cfg = load_config(args.params)  # ConfigError: exit 2
    try:
        data = read_calibration_data(args.bag, cfg.driven_joint, args.angle_topic, args.measured_topic)
        _check_span(cfg, data)
        check_sensor_scale(sensor_scale(data.q, data.theta, cfg.linkage, cfg.driven, cfg.measured_branch))
        lengths = (cfg.frame_length, cfg.rocker_ab_length, cfg.coupler_length, cfg.rocker_cd_length)
        fit = calibrate(data.q, data.theta, lengths, cfg.driven, cfg.measured_branch, args.length_tolerance,
                        sensor_offset=args.sensor_offset, sensor_offset_sd=args.sensor_offset_sd,
                        references=references)
        far = far_from_prior(fit)
        if far:
            raise CalibrationError(f'{"; ".join(far)}: the prior or the recording is wrong (check the parameter '
                                   'file, --length-tolerance, --sensor-offset and --sensor-offset-sd)')
        rate = data.paired_rate()
        direction = direction_terms(fit, data.q, rate)
        warnings = _warnings(data, fit, direction)
        load = _load(cfg, data, fit)
        report = _report(args, cfg, data, fit)
        values = {name: fit.parameter(name).value for name in LENGTH_NAMES}
        values.update(_offsets(cfg, fit))
        report['live_check_in_parameter_file'] = _live_check(report, direction)
        values.update(report['live_check_in_parameter_file'])
        if isinstance(load, dict):
            values.update(load['written_to_parameter_file'])
        files: dict[Path, bytes] = {}
        if args.output is not None:
            files[args.output] = param_file_with(args.params, args.bag, values, 'fourbar calibrate').encode()
        report['direction_dependent'] = _direction_report(direction)
        report['warnings'] = warnings
        report['load'] = load
        if args.report is not None:
            files[args.report] = (json.dumps(report, indent=2) + '\n').encode()
        if plot is not None:
            # x: the calibrated model's angle (from the encoder), not the noisy reading, which would bias the bins;
            # the readings set aside are left out (their residuals would set the scale)
            kept = fit.kept
            theta = np.degrees(data.theta - fit.residuals_after - fit.parameter('sensor_offset').value)[kept]
            title = (f'fourbar calibrate: {data.path.name}, {int(kept.sum())} readings '
                     f'({fit.set_aside} set aside), {cfg.driven_joint}')
            files[plot] = draw(theta, fit.residuals_before[kept], fit.residuals_after[kept], title,
                               rising=(rate > 0.0)[kept])
            report['plot'] = str(plot)
            if args.report is not None:
                files[args.report] = (json.dumps(report, indent=2) + '\n').encode()
    except CalibrationError as exc:
        raise CommandError(str(exc), status=1) from None
    write_atomically(files)
    for warning in warnings:
        print(f'fourbar calibrate: warning: {warning}', file=sys.stderr)
    print(_summary(report, files))
    return 0


def _reference(text: str) -> Reference:
    """A ``--reference JOINT:THETA:SD`` (rad, rad, rad) parsed; CommandError (status 2) when malformed."""
    from fourbar_ros.core.calibration import Reference

    values: list[float] = []
    with contextlib.suppress(ValueError):
        values = [float(x) for x in text.split(':')]
    if len(values) != 3 or not all(map(math.isfinite, values)) or not values[2] > 0.0:
        raise CommandError(f'--reference {text!r}: expected JOINT:THETA:SD in rad, finite, SD positive')
    return Reference(*values)


def _warnings(data: CalibrationData, fit: Calibration, direction: DirectionTerms) -> list[str]:
    """What the user should know but does not stop the calibration: a recording swept one way only; a latency or
    a backlash beyond PRIOR_SDS_LIMIT of its sd."""
    from fourbar_ros.core.calibration import BOTH_WAYS_FRACTION, one_way

    out = []
    both = one_way(data.q[fit.kept])
    if both < BOTH_WAYS_FRACTION:
        out.append(f'the recording sweeps the joint one way only (the way back covers {100.0 * both:.0f}% of the '
                   f'span, below {100.0 * BOTH_WAYS_FRACTION:.0f}%): a lag or backlash of the sensor or the drive '
                   'cannot show and shifts the offsets; sweep both ways')
    found = direction.significant()
    if found:
        out.append(f'{" and ".join(found)}: the sensor\'s reading moves {1e3 * direction.shift:.2g} mrad rms with '
                   'the direction of motion, which the map leaves in its residuals (and the live check in its '
                   'scatter); the absolute angle\'s sd takes it in')
    return out


def _direction_report(direction: DirectionTerms) -> dict[str, Any]:
    """The report's ``direction_dependent``: the latency and backlash fitted to the residuals."""
    return {'latency_s': direction.latency, 'latency_sd_s': direction.latency_sd,
            'backlash_rad': direction.backlash, 'backlash_sd_rad': direction.backlash_sd,
            'correlation': direction.correlation, 'shift_rms_rad': direction.shift,
            'model': ('fitted to the residuals: the sensor sees the rocker at q(t - latency) - sign(dq/dt) backlash '
                      '/ 2; not applied to the geometry, which sweeps both ways leave unbiased')}


def _live_check(report: dict[str, Any], direction: DirectionTerms) -> dict[str, float]:
    """The node's parameters for its live check in sds: an IMU's yaw (rad) where the sweep found it, the sensor's
    latency (s), its noise sd (rad) and lag-1 correlation, and the map's largest sd (rad), each within its
    parameter's range."""
    yaw = report['imu_yaw_rad']
    return {**({} if yaw is None else {'antenna_imu_yaw': yaw}),
            'antenna_sensor_latency': min(max(direction.latency, -1.0), 1.0),
            'antenna_sensor_noise': float(report['noise_sd_rad']),
            'antenna_sensor_noise_correlation': min(max(float(report['noise_lag1_correlation']), 0.0), 0.999),
            'antenna_sensor_map_sd': float(report['absolute_angle']['sensor_map_largest_sd_rad'])}


def _offsets(cfg: AntennaConfig, fit: Calibration) -> dict[str, float]:
    """The node's parameters for the fitted offsets: ``driven_joint_offset`` (rad), the URDF transmission's
    ``<offset>`` (joint = actuator / reduction + offset), is the file's, in effect while recording, plus the fitted
    correction (the true rocker angle is the measured joint plus it); ``antenna_sensor_offset`` (rad) is the fitted
    sensor_offset itself (the recording holds the sensor's raw readings)."""
    return {'driven_joint_offset': cfg.driven_joint_offset + fit.parameter('driven_joint_offset').value,
            'antenna_sensor_offset': fit.parameter('sensor_offset').value}


def _load(cfg: AntennaConfig, data: CalibrationData, fit: Calibration) -> dict[str, Any] | None:
    """The load model fitted to the measured effort (``core.load_calibration``), as the report's ``load``: None
    without an effort in the recording; ``{"skipped": why}`` when it cannot be fitted (the geometry still is)."""
    import numpy as np

    from fourbar_ros.core.calibration import CalibrationError
    from fourbar_ros.core.load_calibration import Geometry, LoadPrior, calibrate_load, target_sd, written

    effort = data.joint_effort
    finite = np.isfinite(effort)
    if not finite.any() or not np.any(effort[finite] != 0.0):
        return None
    if not cfg.gravity > 0.0:
        return {'skipped': 'gravity is 0 in the parameter file'}
    q_rate = data.joint_rate()
    prior = LoadPrior(cfg.antenna_mass, cfg.com_offset_along, cfg.com_offset_normal,
                      reducer_efficiency=cfg.reducer_efficiency)
    try:
        load, used = calibrate_load(Geometry(fit.values, fit.covariance), data.joint_q, q_rate, effort, cfg.driven,
                                    cfg.measured_branch, cfg.gravity, prior)
    except CalibrationError as exc:
        return {'skipped': str(exc)}
    units = {'antenna_mass': 'kg', 'coulomb_friction': 'N m', 'viscous_friction': 'N m s/rad',
             'reducer_efficiency': ''}

    parameters = {p.name: {'value': p.value, 'sd': p.sd, 'target_sd': target_sd(p.name, p.value),
                           'determined_by_data': p.determined_by_data, 'prior': p.prior, 'prior_sd': p.prior_sd,
                           'unit': units.get(p.name, 'm')}
                  for p in load.parameters}
    r = load.residuals
    return {
        'parameters': parameters,
        'readings': int(np.count_nonzero(used)),
        'velocity': 'measured' if data.velocity_measured else 'differentiated from the positions',
        'residual_rms_N_m': float(np.sqrt(np.mean(r * r))),
        'largest_residual_N_m': float(np.max(np.abs(r))),
        'noise_sd_N_m': load.sigma,
        'singular_values': [float(x) for x in load.singular_values],
        'directions_determined_by_data': int(np.count_nonzero(load.singular_values > math.sqrt(3.0))),
        'model': ('effort = tau_in / reducer_efficiency + coulomb_friction sign(q_dot) + viscous_friction q_dot '
                  'when the motor drives, tau_in reducer_efficiency + ... when back-driven; tau_in = antenna_mass g '
                  'dy_com/dtheta dtheta/dq; readings at rest left out; fitted with the geometry under its '
                  'calibrated covariance, the offsets as moments (mass times offset)'),
        'written_to_parameter_file': written(load),
    }


def _check_span(cfg: AntennaConfig, data: CalibrationData) -> None:
    from fourbar_ros.core.calibration import CalibrationError

    theta = cfg.linkage.from_rocker(data.q, cfg.driven, cfg.measured_branch, on_invalid='nan').theta
    finite = [float(t) for t in (theta.min(), theta.max())] if theta.size else [0.0, 0.0]  # type: ignore[union-attr]
    span = finite[1] - finite[0] if all(map(math.isfinite, finite)) else math.nan
    if not span >= MIN_TILT_SPAN:
        shown = f'{math.degrees(span):.1f}' if math.isfinite(span) else 'an unknown range'
        raise CalibrationError(f'the recording spans {shown} deg of tilt: it cannot determine the geometry; sweep '
                               f'the tilt range')


def _parameters(fit: Calibration) -> dict[str, dict[str, Any]]:
    units = {'driven_joint_offset': 'rad', 'sensor_offset': 'rad'}
    return {p.name: {'value': p.value, 'sd': p.sd, 'determined_by_data': p.determined_by_data, 'prior': p.prior,
                     'prior_sd': p.prior_sd, 'unit': units.get(p.name, 'm')} for p in fit.parameters}


def _report(args: argparse.Namespace, cfg: AntennaConfig, data: CalibrationData, fit: Calibration) -> dict[str, Any]:
    from fourbar_ros.core.calibration import DEFAULT_LOSS, DETERMINED_RATIO, PARAMETER_NAMES, SET_ASIDE_SDS

    kept = fit.kept
    before, after = fit.residuals_before[kept], fit.residuals_after[kept]
    # the calibrated model's angle at the readings kept
    theta = (data.theta - fit.residuals_after - fit.parameter('sensor_offset').value)[kept]
    return {
        'bag': str(args.bag),
        'params': str(args.params),
        'measured_topic': data.joint_topic,
        'sensor_topic': data.sensor_topic,
        'sensor_type': data.sensor_type,
        'driven_joint': cfg.driven_joint,
        'paired_readings': int(data.times.size),
        'readings_left_out': int(data.outside),
        'sensor_readings_invalid': data.sensor_invalid,
        'joint_readings_invalid': data.joint_invalid,
        'imu_roll_rad': data.imu_roll if math.isfinite(data.imu_roll) else None,
        'imu_yaw_rad': data.imu_yaw if math.isfinite(data.imu_yaw) else None,
        'readings_set_aside': fit.set_aside,
        'set_aside_rule': (f'a robust fit ({DEFAULT_LOSS} loss) first; readings whose residual exceeds '
                           f'{SET_ASIDE_SDS:g} robust noise sds are set aside, the fit and its sds use the rest'),
        'tilt_span_rad': [float(theta.min()), float(theta.max())],
        'parameters': _parameters(fit),
        'residual_rms_rad': float(math.sqrt(float((after * after).mean()))),
        'largest_residual_rad': float(abs(after).max()),
        'residual_rms_before_rad': float(math.sqrt(float((before * before).mean()))),
        'largest_residual_before_rad': float(abs(before).max()),
        'noise_sd_rad': fit.sigma,
        'noise_lag1_correlation': fit.correlation,
        'independent_readings': fit.independent * int(kept.sum()),
        'singular_values': [float(s) for s in fit.singular_values],
        'singular_directions': {'parameters': list(PARAMETER_NAMES),
                                'rows': [[float(x) for x in row] for row in fit.directions]},
        'directions_determined_by_data': fit.determined_directions,
        'rule': (f'determined_by_data: the posterior sd is below {DETERMINED_RATIO} of the prior sd; a direction is '
                 f'determined by the data when its singular value (of J diag(prior sd) / noise sd) exceeds '
                 f'{math.sqrt(DETERMINED_RATIO ** -2 - 1.0):.4g}'),
        'conventions': ('lengths m, angles rad; sensor = theta(q_measured + driven_joint_offset) + sensor_offset; '
                        'driven_joint_offset here is the correction of the measured joint: the true rocker angle is '
                        'the measured joint plus it; the parameter file\'s driven_joint_offset, the ros2_control '
                        'transmission <offset> (joint = actuator / reduction + offset), becomes the one in effect '
                        'while recording (the file\'s) plus it; sensor_offset is the sensor\'s reading at theta = 0, '
                        'the node\'s antenna_sensor_offset'),
        'driven_joint_offset_recorded_rad': cfg.driven_joint_offset,
        'offsets_in_parameter_file': _offsets(cfg, fit),
        'absolute_angle': _absolute_angle(data.q[kept], fit),
        'references': [{'joint_rad': r.joint, 'theta_rad': r.theta, 'sd_rad': r.sd,
                        'calibrated_theta_rad': float(fit.angle(r.joint)[0][0])} for r in fit.references],
        'iterations': fit.iterations,
    }


def _absolute_angle(q: Any, fit: Calibration) -> dict[str, Any]:
    """The antenna angle the node computes with the calibration over the swept joint range, with its sd, beside
    the sensor's predicted reading; the largest sds and what sets the angle's (the largest variance source)."""
    import numpy as np

    grid = np.linspace(float(q.min()), float(q.max()), GRID_POINTS)
    theta, sd = fit.angle(grid)
    reading, reading_sd = fit.angle(grid, with_sensor=True)
    worst = int(np.argmax(sd))
    sources = fit.variance_sources(float(grid[worst]))
    total = sum(sources.values())
    return {
        'joint_rad': grid.tolist(),
        'theta_rad': theta.tolist(),
        'sd_rad': sd.tolist(),
        'sensor_reading_rad': reading.tolist(),
        'sensor_reading_sd_rad': reading_sd.tolist(),
        'largest_sd_rad': float(sd[worst]),
        'sensor_map_largest_sd_rad': float(reading_sd.max()),
        'set_by': max(sources, key=lambda name: sources[name]),
        'variance_shares_at_largest_sd': {name: v / total for name, v in sources.items()},
        'meaning': ('theta_rad: the antenna angle the node computes from the measured joint with the calibrated '
                    'parameters (the model without the sensor offset); sensor_reading_rad: the sensor\'s reading '
                    'the calibration predicts (with it); each sd (1 sd, rad) from the full posterior covariance '
                    'through the model\'s Jacobian; the variance shares split the angle\'s variance by the source '
                    'of information whose uncertainty it comes from (the readings\' noise, each prior, each '
                    'reference)'),
    }


def _plot_path(output: Path | None, report: Path | None) -> Path | None:
    """OUT.png beside OUT.yaml (else beside OUT.json); None without either."""
    base = output if output is not None else report
    return None if base is None else base.with_suffix('.png')


def _summary(report: dict[str, Any], files: dict[Path, bytes]) -> str:
    lines = [f'fourbar calibrate: {report["paired_readings"]} paired readings over '
             f'[{math.degrees(report["tilt_span_rad"][0]):.2f}, {math.degrees(report["tilt_span_rad"][1]):.2f}] deg; '
             f'residual RMS {report["residual_rms_before_rad"]:.3g} rad before, {report["residual_rms_rad"]:.3g} rad '
             f'after (largest {report["largest_residual_rad"]:.3g} rad); the data determine '
             f'{report["directions_determined_by_data"]} of {len(report["singular_values"])} directions']
    absolute = report['absolute_angle']
    lines.append(f'  the joint-to-sensor map is fixed to {1e3 * absolute["sensor_map_largest_sd_rad"]:.2g} mrad; the '
                 f'antenna\'s absolute angle to {1e3 * absolute["largest_sd_rad"]:.2g} mrad, set by '
                 f'{absolute["set_by"]}: {100.0 * absolute["variance_shares_at_largest_sd"][absolute["set_by"]]:.0f}% '
                 'of its variance (1 sd, the largest over the swept range)')
    dropped = [f'{report["readings_set_aside"]} set aside as outliers', f'{report["sensor_readings_invalid"]} '
               'invalid sensor readings dropped']
    if report['independent_readings'] < report['paired_readings'] - report['readings_set_aside']:
        dropped.append(f'the residuals\' lag-1 correlation {report["noise_lag1_correlation"]:.2f} counts them as '
                       f'{report["independent_readings"]:.0f} independent readings')
    if report['imu_roll_rad'] is not None:
        yaw = report['imu_yaw_rad']
        dropped.append(f'the IMU rolled {math.degrees(report["imu_roll_rad"]):.2f} deg about its x axis (the tilt '
                       'does not depend on it) and ' + ('no sweep to find its yaw (taken as 0)' if yaw is None else
                                                         f'yawed {math.degrees(yaw):.2f} deg about its z axis (the '
                                                         'tilt is taken about the joint axis found)'))
    lines.append(f'  {", ".join(dropped)}')
    for name, p in report['parameters'].items():
        by = 'data' if p['determined_by_data'] else 'prior'
        lines.append(f'  {name:<20} {p["value"]:.9g} {p["unit"]} (sd {p["sd"]:.2g}, prior {p["prior"]:.6g} sd '
                     f'{p["prior_sd"]:.2g}; by the {by})')
    load = report.get('load')
    if isinstance(load, dict) and 'parameters' in load:
        lines.append(f'  load from the measured effort ({load["readings"]} moving readings, residual RMS '
                     f'{load["residual_rms_N_m"]:.3g} N m):')
        written = load['written_to_parameter_file']
        for name, p in load['parameters'].items():
            by = 'data' if p['determined_by_data'] else 'prior'
            target = p['target_sd']
            fate = '' if target is None else f'; {"" if name in written else "not "}written, target sd {target:.2g}'
            lines.append(f'  {name:<20} {p["value"]:.6g} {p["unit"]} (sd {p["sd"]:.2g}, prior {p["prior"]:.6g} '
                         f'sd {p["prior_sd"]:.2g}; by the {by}{fate})'.replace('  (', ' ('))
    elif isinstance(load, dict):
        lines.append(f'  load model not fitted: {load["skipped"]}')
    offsets = report['offsets_in_parameter_file']
    if any(path.suffix == '.yaml' for path in files):
        lines.append(f'  to the parameter file: driven_joint_offset {offsets["driven_joint_offset"]:.9g} rad (the '
                     f'file\'s {report["driven_joint_offset_recorded_rad"]:.9g} plus the fitted), '
                     f'antenna_sensor_offset {offsets["antenna_sensor_offset"]:.9g} rad')
    lines += [f'  wrote {path}' for path in files]
    return '\n'.join(lines)

