"""The MuJoCo plant as the simulated actuator's drive, and ``fourbar_sim_actuator``'s main that offers it.

``PlantDrive`` takes the follower's reference as the servo's command (interpolated over the update period) and
publishes the plant's rocker angle, speed and ``drive_torque`` (N m, + increasing rocker angle) as measured; the
configured ``load_torque`` L is a wind of -L. docs/how-to/ros2-control.md#without-hardware-the-simulated-actuator.
"""

from __future__ import annotations

import sys
from typing import TYPE_CHECKING

from fourbar_ros.config.antenna_config import AntennaConfig
from fourbar_ros.plant.mjcf import DriveModel

if TYPE_CHECKING:  # mujoco is imported where a plant is made: the main runs without it (the lag drive)
    from fourbar_ros.plant.plant import Plant

__all__ = ['PlantDrive', 'plant_drive', 'sim_actuator_main']


class PlantDrive:
    """The plant following a position reference at the driven rocker (rad), stepped in whole timesteps.

    Time is counted in integer nanoseconds, so a sequence of ``advance`` calls steps the plant the same whole
    number of timesteps however it is split: the rest (less than one timestep) waits for the next call.
    """

    def __init__(self, cfg: AntennaConfig, position: float, lower: float, upper: float,
                 drive: DriveModel | None = None, wind: float | None = None) -> None:
        """Assembled at rest at rocker angle ``position`` (rad, clamped to [lower, upper], the joint's range), the
        servo holding there; ``wind`` (N m on the antenna, + theta; default -cfg.load_torque)."""
        from fourbar_ros.plant.plant import Plant

        self.plant: Plant = Plant(cfg, drive)
        self.lower, self.upper = lower, upper
        self.plant.set_drive_angle(self.clamp(position))
        self.plant.set_wind_torque(-cfg.load_torque if wind is None else wind)
        self._step_ns = round(self.plant.timestep * 1e9)
        self._pending_ns = 0
        self._command = self.plant.rocker_angle  # the last command reached (rad at the rocker)

    def clamp(self, reference: float) -> float:
        """The reference within the joint's range (rad)."""
        return min(max(reference, self.lower), self.upper)

    def advance(self, dt: float, reference: float) -> None:
        """Step ``dt`` s in whole timesteps towards the position command ``reference`` (rad, clamped), reached at
        the interval's end: the servo's command moves linearly from the previous one over the interval's steps, as
        a drive in cyclic synchronous position mode interpolates between its setpoints."""
        self._pending_ns += max(round(dt * 1e9), 0)
        steps, self._pending_ns = divmod(self._pending_ns, self._step_ns)
        target = self.clamp(reference)
        previous = self._command
        for k in range(1, int(steps) + 1):
            self.plant.command_rocker(previous + (target - previous) * k / steps)
            self.plant.step(1)
        if steps:
            self._command = target

    @property
    def position(self) -> float:
        """The driven rocker's angle (rad)."""
        return self.plant.rocker_angle

    @property
    def velocity(self) -> float:
        """The driven rocker's speed (rad/s)."""
        return self.plant.rocker_velocity

    def effort(self) -> float:
        """The reducer's torque on the driven rocker (N m, + increasing rocker angle) at the present state."""
        self.plant.forward()
        return self.plant.drive_torque


def plant_drive(cfg: AntennaConfig, position: float, lower: float, upper: float) -> PlantDrive:
    """The simulated actuator's ``mujoco`` drive: the plant with the default ``DriveModel``."""
    return PlantDrive(cfg, position, lower, upper)


def sim_actuator_main(args: list[str] | None = None) -> int:
    """Console script ``fourbar_sim_actuator``: the simulated actuator, offered the plant as its ``mujoco`` drive
    where mujoco imports (``node.run.sim_actuator_main``'s exit statuses)."""
    import importlib.util

    from fourbar_ros.node.run import sim_actuator_main as run

    return run(args, drives={'mujoco': plant_drive} if importlib.util.find_spec('mujoco') is not None else {})


if __name__ == '__main__':
    sys.exit(sim_actuator_main())
