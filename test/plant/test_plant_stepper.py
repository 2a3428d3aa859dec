"""A stepper instead of the servo: below its pull-out torque it holds a load at the electrical angle asin(load /
pull-out) off its command; beyond it, it slips, and once the load is gone it rests whole electrical cycles off the
command: the commanded step count and the true angle part, and the antenna with them."""

from __future__ import annotations

import math

import pytest
from support.mujoco_log import mujoco_warnings
from support_plant import Plant, needs_mujoco

from fourbar_ros.config.antenna_config import AntennaConfig, config_from_values
from fourbar_ros.plant.mjcf import DriveModel

pytestmark = needs_mujoco

#: Pull-out torque (N m at the motor: the configuration's motor_torque_limit) and rotor teeth (1.8 deg full steps).
PULL_OUT, TEETH = 0.009, 50
CYCLE = 2.0 * math.pi / TEETH  # rad at the motor: one electrical cycle, four full steps
#: Steps with the load on, then off (1 ms each): enough to hold or slip, then to come to rest.
LOADED, UNLOADED = 300, 1000


def loaded_then_released(cfg: AntennaConfig, fraction: float, pull_out: float = PULL_OUT) -> tuple[Plant, float]:
    """The stepper holding mid-range, a wind putting ``fraction`` of PULL_OUT on the motor, then none: the plant at
    rest after, and the motor's error (rad) under the load."""
    with mujoco_warnings() as warnings:
        plant = Plant(cfg, DriveModel(stepper_torque=pull_out, stepper_teeth=TEETH))
        theta = 0.5 * (cfg.theta_min + cfg.theta_max)
        plant.set_drive_angle(plant.drive_angle_at(theta))
        advantage = float(cfg.linkage.mechanical_advantage(theta, cfg.driven, cfg.branch))
        # A wind w needs -w / advantage at the rocker (it holds), -w / (advantage ratio) at the motor.
        plant.set_wind_torque(-fraction * PULL_OUT * cfg.reducer_ratio * advantage)
        plant.step(LOADED)
        under_load = plant.motor_angle - plant.motor_command
        plant.set_wind_torque(0.0)
        plant.step(UNLOADED)
    assert not warnings, warnings
    assert plant.max_speed < 1e-6
    return plant, under_load


def wind_only() -> AntennaConfig:
    return config_from_values({'antenna_mass': 0.0, 'load_torque': 0.0})  # no weight: nothing loads it after


@pytest.mark.parametrize('fraction', [0.5, 0.97])
def test_below_pull_out_it_holds_at_the_electrical_angle_and_returns(fraction: float) -> None:
    cfg = wind_only()
    plant, under_load = loaded_then_released(cfg, fraction)
    # The motor carries +fraction PULL_OUT (the drive holds the wind); the stepper's -PULL_OUT sin(TEETH error).
    assert math.isclose(under_load, -math.asin(fraction) / TEETH, rel_tol=1e-3)
    assert plant.slipped_cycles == 0
    assert abs(plant.motor_angle - plant.motor_command) < 1e-9


@pytest.mark.parametrize('fraction', [1.05, 1.5, 3.0])
def test_beyond_pull_out_it_slips_by_whole_electrical_cycles(fraction: float) -> None:
    cfg = wind_only()
    plant, _ = loaded_then_released(cfg, fraction)
    cycles = plant.slipped_cycles
    assert cycles < 0  # the way the wind pushed it
    slip = plant.motor_angle - plant.motor_command
    assert abs(slip - cycles * CYCLE) < 1e-9  # whole cycles: the rotor rests in another detent
    # The command (the step count a controller keeps) and the true angle part: the rocker, and the antenna, with the
    # rotor, whole cycles / ratio off where the command puts them.
    commanded_rocker = plant.motor_command / cfg.reducer_ratio + cfg.driven_joint_offset
    assert abs(plant.rocker_angle - commanded_rocker - cycles * CYCLE / cfg.reducer_ratio) < 1e-9
    theta_commanded = float(cfg.linkage.from_rocker(commanded_rocker, cfg.driven, cfg.measured_branch).theta)
    advantage = float(cfg.linkage.mechanical_advantage(theta_commanded, cfg.driven, cfg.branch))  # d q / d theta
    assert math.isclose(plant.theta - theta_commanded, cycles * CYCLE / cfg.reducer_ratio / advantage, rel_tol=2e-2)


def test_a_stepper_twice_as_strong_does_not_slip_at_one_and_a_half() -> None:
    """The slip is the pull-out torque's: the same load on a stepper with twice the torque holds (the check above
    fails for it)."""
    plant, _ = loaded_then_released(wind_only(), 1.5, pull_out=2.0 * PULL_OUT)
    assert plant.slipped_cycles == 0


def test_the_servo_never_slips() -> None:
    plant = Plant(wind_only())
    assert plant.slipped_cycles == 0 and '<position name="motor_servo"' in plant.xml
    assert '<motor name="motor_servo"' in Plant(wind_only(), DriveModel(stepper_torque=PULL_OUT)).xml
