"""The plant in motion and under wind: a slow sweep followed within the servo's stated lag, a wind torque changing
the drive torque by what the mechanical advantage says, a compliant reducer with backlash resting where its deadband
spring says; each with a mutant that must fail the same check."""

from __future__ import annotations

import math
import time

import pytest
from support.mujoco_log import mujoco_warnings
from support_plant import Plant, config, hold_exactly, needs_mujoco, settle

from fourbar_ros.config.antenna_config import AntennaConfig
from fourbar_ros.core.antenna import Driven
from fourbar_ros.plant.mjcf import DriveModel

pytestmark = needs_mujoco

#: The sweep: theta from theta_min to theta_max as a half cosine in SWEEP_TIME s (peak 0.036 rad/s here), held
#: SETTLE_TIME s after. The servo's kv damps the motor's own speed, so a ramp lags by kv/kp times the motor's speed,
#: plus the static error (motor torque / kp): for the defaults (kv/kp = 6.3 ms) and the weight+wind case 2.6e-4 rad
#: at the rocker, 2.0e-4 rad of theta, measured with mujoco 4.0.0 (both rockers). TRACK_TOL leaves a factor 2;
#: after the hold the residual is the static error only (FINAL_TOL).
SWEEP_TIME, SETTLE_TIME, TRACK_TOL, FINAL_TOL = 10.0, 0.5, 4e-4, 2e-5
#: Wind (N m, + theta) and the bound on the drive torque's change against -wind / mechanical_advantage (relative).
#: Measured with the rocker held exactly: within 2e-6 relative.
WIND, WIND_REL = 2.0, 2e-5


def sweep(cfg: AntennaConfig, xml: str | None = None) -> tuple[float, float, float]:
    """(worst |theta - commanded|, |theta - theta_max| after the hold (rad), real-time factor) of the sweep under the
    configured wind (-load_torque); the rocker commanded each step from the core's kinematics."""
    with mujoco_warnings() as warnings:
        plant = Plant(cfg, xml=xml)
        lo, hi = cfg.theta_min, cfg.theta_max
        plant.set_drive_angle(plant.drive_angle_at(lo))
        plant.set_wind_torque(-cfg.load_torque)
        settle(plant)
        start, worst = plant.time, 0.0
        steps = round((SWEEP_TIME + SETTLE_TIME) / plant.timestep)
        wall = time.perf_counter()
        for _ in range(steps):
            t = min(plant.time - start, SWEEP_TIME)
            wanted = lo + (hi - lo) * 0.5 * (1.0 - math.cos(math.pi * t / SWEEP_TIME))
            plant.command_rocker(plant.drive_angle_at(wanted))
            plant.step()
            worst = max(worst, abs(plant.theta - wanted))
        wall = time.perf_counter() - wall
    assert not warnings, warnings
    return worst, abs(plant.theta - hi), (plant.time - start) / wall


@pytest.mark.parametrize('case', ['weight+wind-gamma', 'weight+wind-delta'])
def test_a_slow_sweep_is_followed_within_the_servo_lag(case: str) -> None:
    cfg = config(case)
    worst, final, rtf = sweep(cfg)
    print(f'\nsweep {case}: worst theta error {worst:.3g} rad, after the hold {final:.3g} rad, '
          f'real-time factor {rtf:.0f} (the loop with the core kinematics each step)')
    assert worst < TRACK_TOL
    assert final < FINAL_TOL


def test_a_reducer_ratio_one_percent_off_fails_the_sweep() -> None:
    cfg = config('weight+wind-gamma')
    xml = Plant(cfg).xml
    r = cfg.reducer_ratio
    old = f'polycoef="-0.0 {r!r} 0 0 0"'
    assert xml.count(old) == 1
    worst, final, _ = sweep(cfg, xml.replace(old, f'polycoef="-0.0 {1.01 * r!r} 0 0 0"'))
    assert worst > TRACK_TOL and final > FINAL_TOL


def drive_torque_change(cfg: AntennaConfig, theta: float, wind: float) -> float:
    """The drive torque with ``wind`` less without it, the rocker held exactly at theta's angle (N m)."""
    torques = []
    for w in (0.0, wind):
        plant = Plant(cfg)
        q = plant.drive_angle_at(theta)
        plant.set_drive_angle(q)
        plant.set_wind_torque(w)
        hold_exactly(plant, q)
        assert abs(plant.rocker_angle - q) < 1e-9
        torques.append(plant.drive_torque)
    return torques[1] - torques[0]


@pytest.mark.parametrize('fraction', [0.0, 0.5, 1.0])
@pytest.mark.parametrize('case', ['weight+wind-gamma', 'weight+wind-delta'])
def test_a_wind_changes_the_drive_torque_by_the_mechanical_advantage(case: str, fraction: float) -> None:
    cfg = config(case)
    theta = cfg.theta_min + fraction * (cfg.theta_max - cfg.theta_min)
    change = drive_torque_change(cfg, theta, WIND)
    advantage = float(cfg.linkage.mechanical_advantage(theta, cfg.driven, cfg.branch))  # d q / d theta
    expected = -WIND / advantage  # the drive holds the wind: its opposite about theta, through the linkage
    assert abs(change - expected) <= WIND_REL * abs(expected), (change, expected, change / expected - 1.0)
    # The other rocker's advantage (what a wrong driven joint would give) is not within the bound.
    other = Driven.DELTA if cfg.driven is Driven.GAMMA else Driven.GAMMA
    wrong = -WIND / float(cfg.linkage.mechanical_advantage(theta, other, cfg.branch))
    assert abs(change - wrong) > WIND_REL * abs(wrong)


#: A compliant reducer: stiffness (N m/rad at the rocker), damping (N m s/rad) and play (rad, total).
STIFFNESS, DAMPING, BACKLASH = 2000.0, 1.0, 2e-3


@pytest.mark.parametrize('wind_sign', [1.0, -1.0])
def test_a_compliant_reducer_with_backlash_rests_where_its_deadband_spring_says(wind_sign: float) -> None:
    """Motor held at the rigid reducer's angle for q: the rocker rests at q - (backlash/2 + T/k) sign(T), T the torque
    it carries; that torque is still the core's input torque at the pose reached."""
    cfg = config('wind-only-gamma')
    drive = DriveModel(reducer_stiffness=STIFFNESS, reducer_damping=DAMPING, backlash=BACKLASH)
    with mujoco_warnings() as warnings:
        plant = Plant(cfg, drive)
        q = plant.drive_angle_at(0.5 * (cfg.theta_min + cfg.theta_max))
        plant.set_drive_angle(q)
        plant.set_wind_torque(-wind_sign * cfg.load_torque)
        hold_exactly(plant, q)  # the motor at its rigid angle for q (the servo's error corrected)
    assert not warnings, warnings
    torque = plant.drive_torque
    assert math.copysign(1.0, torque) == wind_sign
    motor_side = plant.motor_angle / cfg.reducer_ratio
    twist = motor_side - plant.rocker_angle
    assert math.isclose(twist, math.copysign(0.5 * BACKLASH, torque) + torque / STIFFNESS, rel_tol=1e-6)
    theta = float(cfg.linkage.from_rocker(plant.rocker_angle, cfg.driven, cfg.measured_branch).theta)
    load = wind_sign * cfg.load_torque  # what the drive supplies about theta: the wind's opposite
    want = float(cfg.linkage.input_torque(theta, load, cfg.driven, cfg.branch))
    assert math.isclose(torque, want, rel_tol=5e-5), (torque, want)
    # Without the play the rocker would rest BACKLASH/2 closer: the deadband shows.
    assert abs(twist - torque / STIFFNESS) > 0.4 * BACKLASH


def test_the_real_time_factor_of_the_bare_step() -> None:
    """Simulated seconds per wall second of ``Plant.step`` alone (printed with -s); the figure the benchmark
    (benchmarks/plant_bench.py) puts beside MuJoCo's own batched step."""
    cfg = config('weight+wind-gamma')
    plant = Plant(cfg)
    steps = 5000
    wall = time.perf_counter()
    for _ in range(steps):
        plant.step()
    wall = time.perf_counter() - wall
    print(f'\nplant real-time factor, one step per call: {steps * plant.timestep / wall:.0f}')
    assert plant.max_speed < 1e-6  # it held still meanwhile
