"""Write a synthetic calibration recording with a known truth: a stand-in for a slow sweep recorded with an
inclinometer strapped to the antenna (docs/how-to/calibrate.md).

    .venv/bin/python scripts/make_calibration_bag.py OUT [--duration S] [--imu] [--seed N]

The linkage as built is the design of config/antenna.yaml off by tenths of a mm (frame +0.3, AB -0.2, coupler
+0.1, CD +0.2 mm), the encoder's zero 0.7 deg high (driven_joint_offset = -0.7 deg) and the sensor's mounting
0.004 rad off; joint states at 100 Hz on /joint_state_broadcaster/joint_states (4096 counts per motor turn through
500:1), the sensor at 50 Hz with 1 mrad of noise on /antenna_inclinometer (std_msgs/Float64, rad) or, with --imu,
on /imu/data (sensor_msgs/Imu). The antenna sweeps -6..+7 deg once a minute.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from fourbar_ros.bags.calibration_sweep import Sweep, write_calibration_bag

TRUTH = {'frame_length': 0.1803, 'rocker_ab_length': 0.0598, 'coupler_length': 0.1021, 'rocker_cd_length': 0.0602,
         'driven_joint_offset': -math.radians(0.7), 'sensor_offset': 0.004}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or '').splitlines()[0])
    parser.add_argument('out', type=Path, help='bag directory to create (must not exist)')
    parser.add_argument('--duration', type=float, default=120.0, help='seconds recorded (default 120)')
    parser.add_argument('--imu', action='store_true', help='an IMU on /imu/data instead of the inclinometer')
    parser.add_argument('--seed', type=int, default=0)
    args = parser.parse_args(argv)
    sweep = Sweep(TRUTH, duration=args.duration, cycles=args.duration / 60.0, sensor='imu' if args.imu else 'float64',
                  seed=args.seed)
    write_calibration_bag(args.out, sweep, angle_topic='/imu/data' if args.imu else '/antenna_inclinometer')
    print(f'wrote {args.out}: {args.duration:g} s, truth {TRUTH}', file=sys.stderr)
    return 0


if __name__ == '__main__':
    sys.exit(main())
