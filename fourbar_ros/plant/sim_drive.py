"""The MuJoCo plant as the simulated actuator's drive, and ``fourbar_sim_actuator``'s main that offers it.

``PlantDrive`` takes the follower's references as the servo's position setpoints (interpolated over the real time
between the updates that wrote them, within the motor's speed limit) and publishes the plant's rocker angle, speed
and ``drive_torque`` (N m, + increasing rocker angle) as measured; the configured ``load_torque`` L is a wind of -L.
docs/how-to/ros2-control.md#without-hardware-the-simulated-actuator.
"""

from __future__ import annotations

import sys
from collections import deque
from dataclasses import dataclass
from typing import TYPE_CHECKING

from fourbar_ros.config.antenna_config import AntennaConfig
from fourbar_ros.plant.mjcf import DriveModel

if TYPE_CHECKING:  # mujoco is imported where a plant is made: the main runs without it (the lag drive)
    from fourbar_ros.plant.plant import Plant

__all__ = ['PlantDrive', 'plant_drive', 'sim_actuator_main']


@dataclass
class _Setpoint:
    """A setpoint (rad) to be reached over ``span_ns`` of interpolation, ``played_ns`` of it played."""

    position: float
    span_ns: int
    played_ns: int = 0


class PlantDrive:
    """The plant following a position reference at the driven rocker (rad), stepped in whole timesteps.

    Time is counted in integer nanoseconds, so a sequence of ``advance`` calls steps the plant the same whole
    number of timesteps however it is split: the rest (less than one timestep) waits for the next call.

    Each ``advance`` brings the setpoint the controller wrote at the interval's start. The servo's command moves to
    it linearly over the real time between that update and the one before it (the time the reference took to move
    there, so the command moves at the reference's own mean speed), the setpoints played in order: one that comes
    early waits for the one before it to be reached, and where the next comes late the command holds the last. And
    the command moves at most ``speed_limit`` (rad/s at the rocker), as a drive limits its speed command.
    """

    def __init__(self, cfg: AntennaConfig, position: float, lower: float, upper: float,
                 drive: DriveModel | None = None, wind: float | None = None, speed_limit: float | None = None) -> None:
        """Assembled at rest at rocker angle ``position`` (rad, clamped to [lower, upper], the joint's range), the
        servo holding there; ``wind`` (N m on the antenna, + theta; default -cfg.load_torque); ``speed_limit``
        (rad/s at the rocker; default the motor's, motor_speed_limit / |reducer_ratio|)."""
        from fourbar_ros.plant.plant import Plant

        self.plant: Plant = Plant(cfg, drive)
        self.lower, self.upper = lower, upper
        self.speed_limit = cfg.motor_speed_limit / cfg.reduction if speed_limit is None else speed_limit
        if not self.speed_limit > 0.0:
            raise ValueError(f'speed_limit: must be positive, got {self.speed_limit!r}')
        self.plant.set_drive_angle(self.clamp(position))
        self.plant.set_wind_torque(-cfg.load_torque if wind is None else wind)
        self._step_ns = round(self.plant.timestep * 1e9)
        self._pending_ns = 0
        self._command = self.plant.rocker_angle  # the servo's command (rad at the rocker)
        self._reached = self._command  # the last setpoint the interpolation reached (rad)
        self._setpoints: deque[_Setpoint] = deque()  # queued, the one being reached first
        self._last_dt_ns: int | None = None  # the previous interval (ns): the time the latest setpoint spans

    def clamp(self, reference: float) -> float:
        """The reference within the joint's range (rad)."""
        return min(max(reference, self.lower), self.upper)

    def advance(self, dt: float, reference: float) -> None:
        """Step ``dt`` s in whole timesteps under the position setpoint ``reference`` (rad, clamped) written at the
        interval's start: queued to be reached over the previous interval's length (this one's for the first)."""
        dt_ns = max(round(dt * 1e9), 0)
        span = dt_ns if self._last_dt_ns is None else self._last_dt_ns
        self._last_dt_ns = dt_ns
        self._setpoints.append(_Setpoint(self.clamp(reference), span))
        self._pending_ns += dt_ns
        steps, self._pending_ns = divmod(self._pending_ns, self._step_ns)
        most = self.speed_limit * self._step_ns * 1e-9  # rad per timestep
        for _ in range(int(steps)):
            target = self._interpolate(self._step_ns)
            self._command += min(max(target - self._command, -most), most)
            self.plant.command_rocker(self._command)
            self.plant.step(1)

    def _interpolate(self, ns: int) -> float:
        """Play ``ns`` more of the queued setpoints; the interpolated command (rad) there."""
        queue = self._setpoints
        while queue:
            head = queue[0]
            take = min(ns, head.span_ns - head.played_ns)
            head.played_ns += take
            ns -= take
            if head.played_ns < head.span_ns:
                return self._reached + (head.position - self._reached) * head.played_ns / head.span_ns
            self._reached = head.position
            queue.popleft()
        return self._reached

    @property
    def command(self) -> float:
        """The servo's position command now (rad at the driven rocker)."""
        return self._command

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
