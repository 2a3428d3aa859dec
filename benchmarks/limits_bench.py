"""What checking the controller's interpolated motion costs: ``python -m benchmarks.limits_bench [--quick]``.

A 10,000-point antenna trajectory (positions, velocities and accelerations: quintic segments) is converted by the
node's rule (``rules.antenna_trajectory.convert``: validation, chain rule, refinement, limits); in the same interleaved
rounds the closed-form extremes of its segments (speed, acceleration, jerk: ``motion.limits.segment_magnitudes``)
are computed alone. Reported: CPU seconds of each (median over rounds) and their ratio; the target is at most 1x
(the check adds at most the conversion's own time). Also the worst margin the converted trajectory keeps under each
limit over its interpolated motion.
"""

from __future__ import annotations

import sys
from typing import Any

import numpy as np

from benchmarks import CONFIG, options, print_json
from benchmarks.timing import Case, interleaved, machine_info
from fourbar_ros.config.antenna_config import load_config
from fourbar_ros.interface.joint_trajectory import DurationFields, PointFields
from fourbar_ros.interface.stamps import from_ns, seconds_to_ns
from fourbar_ros.interface.topics import ANTENNA_JOINT
from fourbar_ros.motion.limits import JointLimits, segment_magnitudes
from fourbar_ros.rules.antenna_trajectory import convert

POINTS = 10_000
#: The target: the extremes' time over the conversion's.
TARGET = 1.0


def request(n: int) -> list[PointFields]:
    """A slow sweep across the tilt range and back (antenna angle, rad; rad/s; rad/s^2), n points 10 ms apart,
    starting and ending at rest."""
    cfg = load_config(CONFIG)
    t = np.arange(n) * 0.01
    span = t[-1]
    mid, amp = 0.5 * (cfg.theta_min + cfg.theta_max), 0.45 * (cfg.theta_max - cfg.theta_min)
    w = 2.0 * np.pi / span
    theta = mid - amp * np.cos(w * t)
    theta_dot = amp * w * np.sin(w * t)
    theta_ddot = amp * w * w * np.cos(w * t)
    theta_dot[[0, -1]] = 0.0
    return [PointFields([float(a)], [float(b)], [float(c)], [], DurationFields(*from_ns(seconds_to_ns(float(s)))))
            for s, a, b, c in zip(t, theta, theta_dot, theta_ddot, strict=True)]


def run(quick: bool) -> dict[str, Any]:
    cfg = load_config(CONFIG)
    points = request(POINTS)
    converted = convert(cfg, [ANTENNA_JOINT], points).trajectory
    limits = JointLimits.from_config(cfg)
    repeats = 3 if quick else 15
    times = interleaved([Case('convert', lambda: convert(cfg, [ANTENNA_JOINT], points), 1),
                         Case('segment_extremes', lambda: segment_magnitudes(converted), 1)], repeats)
    margins = {order: 1.0 - float(np.max(limits.ratio * m)) / limits.motor(order)
               for order, m in segment_magnitudes(converted).items()}
    ratio = times['segment_extremes'][0] / times['convert'][0]
    return {
        'points_requested': POINTS, 'points_sent': len(converted), 'repeats': repeats,
        'cpu_s': {k: v[0] for k, v in times.items()}, 'wall_s': {k: v[1] for k, v in times.items()},
        'extremes_over_convert': ratio, 'target_max': TARGET, 'meets_target': ratio <= TARGET,
        'worst_margin': {('speed', 'acceleration', 'jerk')[o - 1]: v for o, v in margins.items()},
        'machine': machine_info(), 'command': 'python -m benchmarks.limits_bench' + (' --quick' if quick else ''),
    }


def main(argv: list[str] | None = None) -> int:
    args = options(sys.argv[1:] if argv is None else argv, __doc__)
    return print_json(run(args.quick))


if __name__ == '__main__':
    sys.exit(main())
