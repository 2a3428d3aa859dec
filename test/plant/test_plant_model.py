"""The generated model at rest against the core: the closure (theta for the held rocker, ``from_rocker``) and the
torque the drive supplies at the rocker (``input_torque``), across the tilt range including both ends.

MuJoCo's constraints are soft: at rest the closure at C is violated by about (1 - d)/d tau^2 f/m (impedance d, time
constant tau, force f at C, the mass it moves m), so most with the light coupler of no antenna (0.1 kg). Measured with
mujoco 4.0.0 and the DriveModel defaults (1 ms step, tau 2 ms, d 0.9999) over CASES x ANGLES: gap at C at most
7.3e-8 m, theta off ``from_rocker``'s by at most 1.4e-6 rad (the gap over a lever of ~0.055 m), the drive torque
within 5.3e-6 relative of ``input_torque``. The bounds below leave a factor ~7 to 10 and are far below a modelling
error: gravity's sign, a ratio 1 % off or C misplaced by 1e-5 m each fail them (the mutants at the end).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from support.mujoco_log import mujoco_warnings
from support_plant import CASES, Plant, config, hold_exactly, needs_mujoco, settle

from fourbar_ros.config.antenna_config import AntennaConfig
from fourbar_ros.core.loads import pose

pytestmark = needs_mujoco

#: Bounds (see the module docstring): m, rad, relative and N m.
GAP_TOL, CLOSURE_TOL = 5e-7, 1e-5
TORQUE_REL, TORQUE_ABS = 5e-5, 1e-6
#: Fractions of the tilt range: both ends and three inside.
ANGLES = (0.0, 0.25, 0.5, 0.75, 1.0)


def theta_at(cfg: AntennaConfig, fraction: float) -> float:
    return cfg.theta_min + fraction * (cfg.theta_max - cfg.theta_min)


def at_rest(cfg: AntennaConfig, theta: float, xml: str | None = None) -> Plant:
    """The plant held at the rocker angle of theta, the wind the configuration's load (a wind of -load_torque)."""
    with mujoco_warnings() as warnings:
        plant = Plant(cfg, xml=xml)
        plant.set_drive_angle(plant.drive_angle_at(theta))
        plant.set_wind_torque(-cfg.load_torque)
        settle(plant)
    assert not warnings, warnings
    return plant


def closure_error(cfg: AntennaConfig, plant: Plant) -> float:
    """theta the plant reports less the core's for the rocker angle it holds (rad)."""
    core = float(cfg.linkage.from_rocker(plant.rocker_angle, cfg.driven, cfg.measured_branch).theta)
    return plant.theta - core


def torque_error(cfg: AntennaConfig, plant: Plant) -> tuple[float, float]:
    """(plant's drive torque, the core's input torque) at the theta the core gives for the held rocker (N m)."""
    theta = float(cfg.linkage.from_rocker(plant.rocker_angle, cfg.driven, cfg.measured_branch).theta)
    return plant.drive_torque, float(pose(cfg, theta).input_torque)


def torque_ok(got: float, want: float) -> bool:
    return abs(got - want) <= TORQUE_REL * abs(want) + TORQUE_ABS


@pytest.mark.parametrize('fraction', ANGLES)
@pytest.mark.parametrize('case', sorted(CASES))
def test_at_rest_theta_is_the_cores_for_the_held_rocker(case: str, fraction: float) -> None:
    cfg = config(case)
    plant = at_rest(cfg, theta_at(cfg, fraction))
    assert plant.closure_gap < GAP_TOL
    assert abs(closure_error(cfg, plant)) < CLOSURE_TOL, closure_error(cfg, plant)
    # The servo holds the rocker where commanded up to its static error (motor torque / kp at the motor).
    assert abs(plant.rocker_angle - plant.drive_angle_at(theta_at(cfg, fraction))) < 1e-4


@pytest.mark.parametrize('fraction', ANGLES)
@pytest.mark.parametrize('case', sorted(CASES))
def test_the_drive_torque_at_rest_is_the_cores_input_torque(case: str, fraction: float) -> None:
    cfg = config(case)
    plant = at_rest(cfg, theta_at(cfg, fraction))
    got, want = torque_error(cfg, plant)
    assert torque_ok(got, want), (got, want, (got - want) / want)
    # The servo holds it through the reducer: motor torque = rocker torque / ratio (an ideal reducer, efficiency 1).
    assert math.isclose(plant.motor_torque * cfg.reducer_ratio, got, rel_tol=1e-6, abs_tol=1e-9)


def test_a_held_rocker_lands_on_its_angle_and_the_figures_hold() -> None:
    """Holding the exact rocker angle (the servo's static error corrected) changes nothing in the comparison."""
    cfg = config('weight+wind-gamma')
    plant = Plant(cfg)
    q = plant.drive_angle_at(cfg.theta_min)
    plant.set_drive_angle(q)
    plant.set_wind_torque(-cfg.load_torque)
    hold_exactly(plant, q)
    assert abs(plant.rocker_angle - q) < 1e-9
    assert abs(closure_error(cfg, plant)) < CLOSURE_TOL
    assert torque_ok(*torque_error(cfg, plant))


# ---------------------------------------------------------------------------------------------------- mutants

def _mutant(cfg: AntennaConfig, old: str, new: str) -> str:
    xml = Plant(cfg).xml
    assert xml.count(old) == 1, old
    return xml.replace(old, new)


def test_gravity_of_the_wrong_sign_fails_the_torque_check() -> None:
    cfg = config('weight+wind-gamma')
    g = repr(-cfg.gravity)
    xml = _mutant(cfg, f'gravity="0 0 {g}"', f'gravity="0 0 {-float(g)!r}"')
    plant = at_rest(cfg, cfg.theta_max, xml)
    assert not torque_ok(*torque_error(cfg, plant))


def test_a_reducer_ratio_one_percent_off_fails_the_torque_check() -> None:
    cfg = config('weight+wind-gamma')
    r = cfg.reducer_ratio
    xml = _mutant(cfg, f'polycoef="-0.0 {r!r} 0 0 0"', f'polycoef="-0.0 {1.01 * r!r} 0 0 0"')
    plant = at_rest(cfg, cfg.theta_min, xml)
    assert not torque_ok(*torque_error(cfg, plant))


def test_c_misplaced_by_ten_micrometres_fails_the_closure_check() -> None:
    cfg = config('weight+wind-gamma')
    h = cfg.coupler_length
    xml = _mutant(cfg, f'<site name="c_coupler" pos="{h!r} 0 0.0"/>',
                  f'<site name="c_coupler" pos="{h + 1e-5!r} 0 0.0"/>')
    plant = at_rest(cfg, 0.5 * (cfg.theta_min + cfg.theta_max), xml)
    assert abs(closure_error(cfg, plant)) > CLOSURE_TOL


def test_the_figures() -> None:
    """The worst closure and torque errors over the cases (printed with -s)."""
    gap = closure = rel = 0.0
    for case in sorted(CASES):
        cfg = config(case)
        for fraction in ANGLES:
            plant = at_rest(cfg, theta_at(cfg, fraction))
            got, want = torque_error(cfg, plant)
            gap = max(gap, plant.closure_gap)
            closure = max(closure, abs(closure_error(cfg, plant)))
            rel = max(rel, abs(got - want) / max(abs(want), 1e-12))
    print(f'\nplant at rest over {len(CASES)} cases x {len(ANGLES)} angles: gap at C <= {gap:.2g} m, '
          f'theta - from_rocker <= {closure:.2g} rad, drive torque vs input_torque <= {rel:.2g} relative')
    assert np.isfinite([gap, closure, rel]).all()
