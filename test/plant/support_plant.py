"""What the plant's tests share: configurations, settling to rest, holding the rocker exactly."""

from __future__ import annotations

from typing import Any

import pytest

from fourbar_ros.config.antenna_config import AntennaConfig, config_from_values

try:
    import mujoco

    from fourbar_ros.plant.plant import Plant
except ImportError:  # each test skips, saying why
    mujoco = None
    Plant = Any

needs_mujoco = pytest.mark.skipif(mujoco is None, reason='the MuJoCo plant needs the mujoco package (pip install '
                                  'mujoco, pinned in requirements/constraints.txt)')

#: Rest: every joint slower than this (rad/s, rocker side); checked in chunks of CHUNK steps, for at most MAX_REST s.
REST_SPEED, CHUNK, MAX_REST = 1e-9, 50, 1.0

#: Loads, weights, centres of mass, both rockers and a reversed motor: what the statics must get right.
CASES = {
    'weight+wind-gamma': dict(antenna_mass=4.0, com_offset_along=0.02, com_offset_normal=0.01, load_torque=3.5),
    'weight+wind-delta': dict(antenna_mass=2.0, com_offset_along=-0.01, com_offset_normal=0.03, load_torque=-1.0,
                              driven_rocker='delta'),
    'wind-only-gamma': dict(antenna_mass=0.0, load_torque=3.5),
    'weight-reversed-motor': dict(antenna_mass=3.0, com_offset_normal=-0.02, load_torque=0.0, reducer_ratio=-500.0),
}


def config(name: str) -> AntennaConfig:
    return config_from_values(CASES[name])


def settle(plant: Plant, max_time: float = MAX_REST) -> None:
    """Step (at least once) until at rest, then recompute the forces at the state reached; fail if it does not
    come to rest by ``max_time`` (s of simulated time)."""
    plant.step(CHUNK)
    while plant.max_speed >= REST_SPEED:
        assert plant.time < max_time, f'not at rest after {plant.time} s: {plant.max_speed} rad/s'
        plant.step(CHUNK)
    plant.forward()


def hold_exactly(plant: Plant, rocker_angle: float) -> None:
    """Settle with the driven rocker at ``rocker_angle``: the servo's static error (motor torque / kp at the motor)
    corrected once in the command, then settled again (as the torque witness does)."""
    settle(plant)
    plant.command_motor(plant.motor_angle_for(rocker_angle) + plant.motor_torque / plant.drive.kp)
    settle(plant, plant.time + MAX_REST)
