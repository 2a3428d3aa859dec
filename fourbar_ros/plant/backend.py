"""The MuJoCo plant as a drive behind the drive bridge (``DriveBackend``), stepped in real time on a clock.

What each drive reports (an open-loop stepper its step count, an encoder the rocker's true angle to a count) and
what the plant cannot imitate: docs/how-to/mujoco-plant.md#the-plant-as-a-drive. Joint side: rad, rad/s, N m.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

from fourbar_ros.config.antenna_config import AntennaConfig
from fourbar_ros.config.robot_model import driven_angle
from fourbar_ros.drive.backend import Reading
from fourbar_ros.plant.mjcf import DriveModel
from fourbar_ros.plant.plant import Plant
from fourbar_ros.plant.step_generator import ACCELERATION_FACTOR, StepGenerator

__all__ = ['MAX_CATCH_UP_S', 'MICROSTEPS', 'Gust', 'PlantBackend', 'stepper_drive']

#: Microsteps per full step of the default stepper driver.
MICROSTEPS = 16
#: Most simulated time (s) one call steps to catch up with the clock; the rest is dropped (``lost_time``).
MAX_CATCH_UP_S = 1.0


def stepper_drive(cfg: AntennaConfig, pull_out: float | None = None) -> DriveModel:
    """The default drive: a stepper (50 teeth, 1.8 deg full steps) whose pull-out torque is ``pull_out`` N m at the
    motor, by default the configuration's ``motor_torque_limit`` (the motor the configuration sized).

    For config/antenna.yaml (9e-3 N m, ratio 500, no antenna weight, load_torque 3.5 N m) the design load needs
    4.6e-3 to 7.6e-3 N m at the motor over the tilt range (``core.loads.pose(...).input_torque`` / ratio): it holds
    with a margin of 1.18 (theta_max) to 1.95 (theta_min), and a gust of twice the design load pulls it out.
    """
    return DriveModel(stepper_torque=cfg.motor_torque_limit if pull_out is None else pull_out)


@dataclass(frozen=True)
class Gust:
    """An extra wind of ``torque`` N m (on the antenna, + theta) from ``start`` to ``end`` s of simulated time."""

    start: float
    end: float
    torque: float


class PlantBackend:
    """A ``DriveBackend`` over ``Plant``: each call steps the plant to ``clock()`` (s) in whole timesteps.

    ``write`` sets a goal at the motor (a stepper's: rounded to whole microsteps, 2 pi / teeth / 4 / ``microsteps``
    rad at the motor) that the drive's step generator (``StepGenerator``: the command period 1 / ``cfg.control_rate``
    s, ``cfg.motor_speed_limit`` and ``ACCELERATION_FACTOR`` x ``cfg.motor_acceleration_limit`` at the motor)
    follows. ``read`` reports, at the driven joint:

    - ``encoder_counts`` (counts per rocker revolution): the rocker's true angle to a count, the velocity differenced
      between reads (rad/s, simulated time), effort None for a stepper;
    - else a stepper (open loop): its count, microsteps issued / ratio + offset (what it believes; it lies once the
      rotor slips), velocity None, effort None;
    - else the servo: its motor encoder through the reducer (motor angle / ratio + offset), motor speed / ratio and
      its torque times the ratio (N m).
    """

    def __init__(self, cfg: AntennaConfig, drive: DriveModel | None = None, position: float | None = None,
                 clock: Callable[[], float] = time.monotonic, encoder_counts: int | None = None,
                 microsteps: int = MICROSTEPS, wind_torque: float | None = None,
                 max_catch_up: float = MAX_CATCH_UP_S) -> None:
        """The plant of ``cfg`` with ``drive`` (default ``stepper_drive(cfg)``), at rest with the driven rocker at
        ``position`` rad (default ``driven_angle(cfg)``; a stepper's to the nearest microstep) under a steady wind
        of ``wind_torque`` N m on the antenna (+ theta; default -cfg.load_torque, the design load)."""
        self.cfg = cfg
        self.drive = drive if drive is not None else stepper_drive(cfg)
        if encoder_counts is not None and encoder_counts < 1:
            raise ValueError(f'encoder_counts: must be None or at least 1, got {encoder_counts!r}')
        if microsteps < 1:
            raise ValueError(f'microsteps: must be at least 1, got {microsteps!r}')
        if not (math.isfinite(max_catch_up) and max_catch_up > 0.0):
            raise ValueError(f'max_catch_up: must be a positive finite number, got {max_catch_up!r}')
        self.plant = Plant(cfg, self.drive)
        self.encoder_counts = encoder_counts
        self.stepper = self.drive.stepper_torque is not None
        #: rad at the motor per microstep (a stepper), None for the servo.
        self.microstep = (2.0 * math.pi / self.drive.stepper_teeth / 4.0 / microsteps) if self.stepper else None
        start = driven_angle(cfg) if position is None else position
        if not math.isfinite(start):
            raise ValueError(f'position: must be finite, got {start!r}')
        motor = self._quantize(cfg.reducer_ratio * (start - cfg.driven_joint_offset))
        self.plant.set_drive_angle(motor / cfg.reducer_ratio + cfg.driven_joint_offset)
        self.generator = StepGenerator(motor, abs(cfg.motor_speed_limit),
                                       ACCELERATION_FACTOR * abs(cfg.motor_acceleration_limit), 1.0 / cfg.control_rate,
                                       self.microstep or 0.0)
        self.plant.command_motor(motor)
        self._steady = -cfg.load_torque if wind_torque is None else wind_torque
        self._gusts: list[Gust] = []
        self._wind = math.nan
        self._apply_wind()
        self._clock = clock
        self._t0 = clock()
        self._step_ns = round(self.plant.timestep * 1e9)
        self._steps = 0  # timesteps of the clock accounted for (stepped or dropped)
        self._max_steps = max(1, math.floor(max_catch_up / self.plant.timestep))
        self.lost_time = 0.0  #: s of the clock dropped, not simulated (calls more than max_catch_up apart)
        self.enabled = False
        self._last: tuple[float, float, float] | None = None  # (sim time, position, velocity) of the last read

    # -- the drive's quantities -------------------------------------------------------------------------------------

    def _quantize(self, motor: float) -> float:
        """A motor angle (rad) to the nearest whole microstep (a stepper), else as it is."""
        if self.microstep is None:
            return motor
        return round(motor / self.microstep) * self.microstep

    @property
    def count(self) -> int:
        """A stepper's microsteps issued (the step generator's position; 0 for the servo)."""
        return 0 if self.microstep is None else round(self.generator.position / self.microstep)

    @property
    def commanded_position(self) -> float:
        """The drive's commanded rocker angle (rad): the motor command / ratio + offset (a stepper: its count)."""
        return self.plant.motor_command / self.cfg.reducer_ratio + self.cfg.driven_joint_offset

    # -- wind -------------------------------------------------------------------------------------------------------

    def set_wind_torque(self, torque: float) -> None:
        """The steady wind on the antenna (N m, + theta; the design load L is a wind of -L), from now on."""
        if not math.isfinite(torque):
            raise ValueError(f'wind torque: must be finite, got {torque!r}')
        self._steady = torque
        self._apply_wind()

    def gust(self, torque: float, duration: float, start: float | None = None) -> Gust:
        """An extra wind of ``torque`` N m for ``duration`` s of simulated time from ``start`` (default now)."""
        begin = self.plant.time if start is None else start
        if not (math.isfinite(torque) and math.isfinite(begin) and math.isfinite(duration) and duration > 0.0):
            raise ValueError(f'gust {torque!r} N m for {duration!r} s at {begin!r} s: finite, the duration > 0')
        made = Gust(begin, begin + duration, torque)
        self._gusts.append(made)
        self._apply_wind()
        return made

    def wind_at(self, t: float) -> float:
        """The wind on the antenna at simulated time ``t`` s (N m, + theta): the steady one plus the gusts on."""
        return self._steady + sum(g.torque for g in self._gusts if g.start <= t < g.end)

    @property
    def wind_torque(self) -> float:
        """The wind acting now (N m, + theta)."""
        return self._wind

    def _apply_wind(self) -> None:
        wind = self.wind_at(self.plant.time)
        if wind != self._wind:
            self._wind = wind
            self.plant.set_wind_torque(wind)

    def _steps_to_change(self) -> int:
        """Whole timesteps until the wind next changes (at least 1; a large number if it never does)."""
        t, dt = self.plant.time, self.plant.timestep
        edges = [e for g in self._gusts for e in (g.start, g.end) if e > t]
        self._gusts = [g for g in self._gusts if g.end > t]
        return max(1, math.ceil((min(edges) - t) / dt - 1e-9)) if edges else self._max_steps

    # -- stepping ---------------------------------------------------------------------------------------------------

    def advance(self) -> None:
        """Step the plant to the clock in whole timesteps (at most ``max_catch_up`` s of them; the rest dropped)."""
        due = round((self._clock() - self._t0) * 1e9) // self._step_ns
        n = due - self._steps
        if n <= 0:
            return
        if n > self._max_steps:
            self.lost_time += (n - self._max_steps) * self.plant.timestep
            self._steps += n - self._max_steps
            n = self._max_steps
        self._steps += n
        generator, dt = self.generator, self.plant.timestep
        while n > 0:
            self._apply_wind()
            if not generator.at_rest:  # the step generator moving: one timestep at a time
                generator.step(self.plant.time, dt)
                self.plant.command_motor(self._quantize(generator.position), generator.speed)
                self.plant.step(1)
                n -= 1
            else:
                self.plant.command_motor(self.plant.motor_command)  # the field at rest
                chunk = min(n, self._steps_to_change())
                self.plant.step(chunk)
                n -= chunk

    # -- DriveBackend -----------------------------------------------------------------------------------------------

    def enable(self) -> None:
        """Ready for ``write`` (the drive holds its position from construction on)."""
        self.advance()
        self.enabled = True

    def read(self) -> Reading:
        """(position rad, velocity rad/s or None, effort N m or None) at the driven joint, as this drive reports."""
        self.advance()
        cfg, plant = self.cfg, self.plant
        if self.encoder_counts is not None:
            resolution = 2.0 * math.pi / self.encoder_counts
            position = round(plant.rocker_angle / resolution) * resolution
            velocity = 0.0
            if self._last is not None:
                elapsed = plant.time - self._last[0]
                velocity = (position - self._last[1]) / elapsed if elapsed > 0.0 else self._last[2]
            self._last = (plant.time, position, velocity)
            effort = None if self.stepper else cfg.reducer_ratio * plant.motor_torque
            return position, velocity, effort
        if self.stepper:
            return self.commanded_position, None, None
        ratio = cfg.reducer_ratio
        return (plant.motor_angle / ratio + cfg.driven_joint_offset, plant.motor_velocity / ratio,
                ratio * plant.motor_torque)

    def write(self, position: float) -> None:
        """A new goal (rad at the joint) for the step generator; RuntimeError while disabled or for a non-finite
        position."""
        if not self.enabled:
            raise RuntimeError('the plant drive is disabled')
        if not math.isfinite(position):
            raise RuntimeError(f'position {position!r} is not finite')
        self.advance()
        self.generator.set_goal(self._quantize(self.cfg.reducer_ratio * (position - self.cfg.driven_joint_offset)),
                                self.plant.time)

    def disable(self) -> None:
        """Stop the step generator where it is (the motor goes on holding: see the how-to)."""
        self.advance()
        self.generator.stop()
        self.enabled = False

    # -- truth, for the world and tests (of the state the last step ended in; forces of the one it began in) ------

    @property
    def true_rocker_angle(self) -> float:
        """The driven rocker's true angle (rad)."""
        return self.plant.rocker_angle

    @property
    def theta(self) -> float:
        """The antenna's true angle (rad)."""
        return self.plant.theta

    @property
    def drive_torque(self) -> float:
        """What the reducer applies to the driven rocker (N m, + rocker angle)."""
        return self.plant.drive_torque

    @property
    def slipped_cycles(self) -> int:
        """A stepper's slip in whole electrical cycles (0 for the servo): rotor less count, nearest integer."""
        return self.plant.slipped_cycles

    @property
    def simulated_time(self) -> float:
        """The plant's time (s since construction, less ``lost_time``)."""
        return self.plant.time

    def antenna_acceleration(self) -> tuple[float, float, float]:
        """The antenna's accelerometer now (m/s^2 in the antenna's axes, the package's IMU convention: at rest
        (-g sin theta, 0, g cos theta)); steps to the clock first, then recomputes the present state's."""
        self.advance()
        self.plant.forward()
        return self.plant.antenna_acceleration
