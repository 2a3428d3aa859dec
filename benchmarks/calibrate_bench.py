"""`fourbar calibrate` on a 10-minute recording against rosbags reading the same bag, same run.

    .venv/bin/python -m benchmarks.calibrate_bench [--quick] [--rounds 3] [--duration 600]

- the recordings: a synthetic sweep (``fourbar_ros.bags.calibration_sweep``) of 600 s, joint states at 100 Hz
  (60,000) and a Float64 inclinometer at 50 Hz (30,000), mcap, written to a temporary directory: ``geometry``
  without an effort (the geometry, sensor latency and backlash are fitted), ``with_load`` with the velocity and the
  effort of a 2 kg antenna (the load is fitted too);
- read: a fresh Python process that imports rosbags and reads every raw message of the bag (nothing decoded): the
  least any tool reading the recording spends, start-up included;
- calibrate: a fresh process running the whole command, ``python -m fourbar_ros.commands calibrate BAG --params
  config/antenna.yaml --angle-topic /antenna_inclinometer -o OUT.yaml --report OUT.json`` (start-up, the CLI, the
  read, the pairing, the fit, the plot and the atomic writes);
- ratio calibrate/read from the medians over ``--rounds`` interleaved rounds, every round listed, of the wall
  time (target: <= 3) and of the CPU time (the process and its children).
  Also in-process: the rosbags read alone (warm), the command's bag reading alone (``read_calibration_data``: the
  read, the decoding and the pairing; ``reading_over_read``, the per-message work it adds to the read) and the
  command's ``main`` in this process (the fits, the plot and the writes beyond the reading).

Figures printed as JSON. No figure is asserted by a test.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import math
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from benchmarks import CONFIG, REPO, print_json

READ = ('import sys\nfrom rosbags.rosbag2 import Reader\nwith Reader(sys.argv[1]) as reader:\n'
        '    count = sum(1 for _ in reader.messages())\nprint(count)\n')
TRUTH = {'frame_length': 0.1803, 'rocker_ab_length': 0.0598, 'coupler_length': 0.1021, 'rocker_cd_length': 0.0602,
         'driven_joint_offset': -math.radians(0.7), 'sensor_offset': 0.004}
LOAD = {'antenna_mass': 2.0, 'com_offset_along': 0.03, 'com_offset_normal': 0.02, 'coulomb_friction': 0.05,
        'viscous_friction': 3.0, 'reducer_efficiency': 0.7}


def make_bag(path: Path, duration: float, load: dict[str, float] | None) -> Path:
    from fourbar_ros.bags.calibration_sweep import Sweep, write_calibration_bag
    return write_calibration_bag(path, Sweep(TRUTH, duration=duration, cycles=duration / 60.0, load=load))


def _wall(cmd: list[str]) -> tuple[float, float]:
    """(wall s, CPU s of the process and its children) of one run."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    subprocess.run(cmd, check=True, cwd=REPO, stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def run(duration: float, rounds: int) -> dict[str, Any]:
    return {'recording': {'seconds': duration, 'joint_states_hz': 100, 'sensor_hz': 50},
            'geometry': _one(duration, rounds, None), 'with_load': _one(duration, rounds, LOAD),
            'load_average': os.getloadavg(), 'target_ratio': 3.0}


def _one(duration: float, rounds: int, load: dict[str, float] | None) -> dict[str, Any]:
    with tempfile.TemporaryDirectory() as tmp:
        bag = make_bag(Path(tmp) / 'sweep', duration, load)
        out = Path(tmp) / 'out'
        command = [sys.executable, '-m', 'fourbar_ros.commands', 'calibrate', str(bag), '--params', str(CONFIG),
                   '--angle-topic', '/antenna_inclinometer', '-o', str(out / 'calibrated.yaml'), '--report',
                   str(out / 'report.json')]
        reads, calibrations, read_cpu, calibrate_cpu = [], [], [], []
        for _ in range(rounds):
            shutil.rmtree(out, ignore_errors=True)
            out.mkdir()
            wall, cpu = _wall([sys.executable, '-c', READ, str(bag)])
            reads.append(wall)
            read_cpu.append(cpu)
            wall, cpu = _wall(command)
            calibrations.append(wall)
            calibrate_cpu.append(cpu)
        from rosbags.rosbag2 import Reader

        from fourbar_ros.bags.calibration_data import read_calibration_data
        from fourbar_ros.commands import main
        from fourbar_ros.config.antenna_config import load_config
        start = time.perf_counter()
        with Reader(bag) as reader:
            messages = sum(1 for _ in reader.messages())
        read_in = time.perf_counter() - start
        driven_joint = load_config(CONFIG).driven_joint
        start = time.perf_counter()
        read_calibration_data(bag, driven_joint, '/antenna_inclinometer')
        reading_in = time.perf_counter() - start
        shutil.rmtree(out, ignore_errors=True)
        out.mkdir()
        start = time.perf_counter()
        with contextlib.redirect_stdout(io.StringIO()):
            status = main(command[3:])
        calibrate_in = time.perf_counter() - start
    read, calibrate = statistics.median(reads), statistics.median(calibrations)
    return {
        'messages': messages,
        'processes': {'read_s': read, 'calibrate_s': calibrate, 'ratio': calibrate / read,
                      'cpu_ratio': statistics.median(calibrate_cpu) / statistics.median(read_cpu),
                      'rounds': {'read_s': reads, 'calibrate_s': calibrations, 'read_cpu_s': read_cpu,
                                 'calibrate_cpu_s': calibrate_cpu}},
        'in_process': {'read_s': read_in, 'reading_s': reading_in, 'reading_over_read': reading_in / read_in,
                       'calibrate_s': calibrate_in, 'ratio': calibrate_in / read_in, 'status': status},
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or '').splitlines()[0])
    parser.add_argument('--quick', action='store_true', help='a 60 s recording, one round')
    parser.add_argument('--rounds', type=int, default=3)
    parser.add_argument('--duration', type=float, default=600.0, help='seconds of recording (default 600)')
    args = parser.parse_args(argv)
    return print_json(run(60.0 if args.quick else args.duration, 1 if args.quick else args.rounds))


if __name__ == '__main__':
    sys.exit(main())
