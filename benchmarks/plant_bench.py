"""How fast the MuJoCo plant runs: ``python -m benchmarks.plant_bench [--quick]``.

The model of config/antenna.yaml with an antenna weight (``fourbar_ros.plant``), 1 ms steps, in the same interleaved
rounds: MuJoCo's own batched step (``mj_step`` with ``nstep``: the baseline, no Python per step), ``Plant.step()``
once per step, a control loop (the rocker commanded from the core's kinematics, then one step) and the stepper
instead of the servo (its torque set in Python each step), and the drive bridge's backend (``PlantBackend``, the
stepper under the design load) read at 100 Hz on a clock advanced 10 ms a read: at rest, and moving (a write each
read along a sine). Reported: the real-time factor of each (simulated seconds per CPU second, median over rounds)
and each one's cost over the baseline.
"""

from __future__ import annotations

import dataclasses
import math
import sys
from typing import Any

import mujoco

from benchmarks import CONFIG, options, print_json
from benchmarks.timing import Case, interleaved, machine_info
from fourbar_ros.config.antenna_config import load_config
from fourbar_ros.plant.backend import PlantBackend
from fourbar_ros.plant.mjcf import DriveModel
from fourbar_ros.plant.plant import Plant

#: Steps per timed call.
STEPS = 1000
#: The backend cases' reads per second (the drive bridge's default state_rate, Hz).
READ_RATE = 100.0


def run(quick: bool) -> dict[str, Any]:
    cfg = dataclasses.replace(load_config(CONFIG), antenna_mass=4.0, com_offset_along=0.02)
    plant = Plant(cfg)
    plant.set_wind_torque(-cfg.load_torque)
    model, data = plant.model, plant.data
    hold = plant.drive_angle_at(0.5 * (cfg.theta_min + cfg.theta_max))

    def batched() -> None:
        mujoco.mj_step(model, data, nstep=STEPS)

    def stepped() -> None:
        for _ in range(STEPS):
            plant.step()

    def loop() -> None:
        for _ in range(STEPS):
            plant.command_rocker(plant.drive_angle_at(plant.theta))
            plant.step()
        plant.command_rocker(hold)

    stepper = Plant(cfg, DriveModel(stepper_torque=cfg.motor_torque_limit))

    def stepper_steps() -> None:
        stepper.step(STEPS)

    clock = [0.0]
    period = 1.0 / READ_RATE
    reads = round(STEPS * plant.timestep * READ_RATE)  # one call: STEPS timesteps of reads
    still = PlantBackend(load_config(CONFIG), clock=lambda: clock[0])
    moving = PlantBackend(load_config(CONFIG), clock=lambda: clock[0])
    still.enable()
    moving.enable()
    centre = moving.read()[0]

    def backend_reads(backend: PlantBackend, write: bool) -> None:
        for _ in range(reads):
            clock[0] += period
            backend.read()
            if write:  # 0.005 rad at the rocker, 1 Hz: 15.7 rad/s peak at the motor
                backend.write(centre + 0.005 * math.sin(2.0 * math.pi * backend.simulated_time))

    repeats = 5 if quick else 25
    times = interleaved([Case('mujoco_batched', batched, STEPS), Case('plant_step', stepped, STEPS),
                         Case('control_loop', loop, STEPS), Case('stepper', stepper_steps, STEPS),
                         Case('backend_100hz_at_rest', lambda: backend_reads(still, False), STEPS),
                         Case('backend_100hz_moving', lambda: backend_reads(moving, True), STEPS)], repeats)
    assert moving.slipped_cycles == 0 and still.slipped_cycles == 0, 'the backend cases are to hold, not slip'
    base = times['mujoco_batched'][0]
    return {
        'timestep_s': plant.timestep, 'steps_per_call': STEPS, 'repeats': repeats,
        'cpu_s_per_step': {k: v[0] for k, v in times.items()},
        'wall_s_per_step': {k: v[1] for k, v in times.items()},
        'real_time_factor': {k: plant.timestep / v[0] for k, v in times.items()},
        'over_mujoco_batched': {k: v[0] / base for k, v in times.items()},
        'mujoco': mujoco.__version__,
        'machine': machine_info(), 'command': 'python -m benchmarks.plant_bench' + (' --quick' if quick else ''),
    }


def main(argv: list[str] | None = None) -> int:
    args = options(sys.argv[1:] if argv is None else argv, __doc__)
    return print_json(run(args.quick))


if __name__ == '__main__':
    sys.exit(main())
