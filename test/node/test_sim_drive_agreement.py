"""The simulated actuator's two drives held to each other: the same reference through the lag drive
(``LagActuator``, the load model's effort) and through the MuJoCo plant (``PlantDrive``), randomized sequences of
moves and rests.

The reference is what the controller writes: a smooth motion r(t) (speed at most V, the joint's limit) sampled
one update period P ahead; the lag holds it over the period, the plant's drive moves its servo's command linearly
to it over the period (the time between the updates, all one period here; its speed limit, the motor's, is V and
does not bind); either is a command c with |c(s) - c(t)| <= V (|s - t| + P). Each drive is, while its limits
do not bind, linear with a non-negative impulse response h of unit mass, so
x(t) - c(t) = int h(u) (c(t - u) - c(t)) du and |x - c| <= V (mean delay + P):

- the lag: mean delay tau (its exact step r + (x - r) e^(-h/tau) weights the past geometrically, mean
  h e^(-h/tau) / (1 - e^(-h/tau)) < tau); its speed, acceleration and braking limits are set beyond the
  reference's here, so they never bind;
- the plant's servo: the rotor J x'' = kp (c - x) - kv x' - T/r at the motor, mean delay kv/kp (6.3 ms), and the
  reducer's torque T on the rocker holds it off by T / (kp r^2) (rad at the rocker; T at most the largest |effort|
  seen); with the linkage's inertia reflected through r^2 (1e-3 of the rotor's), the damping ratio is 0.9994 and the
  impulse response's negative lobe e^(-90) of it, nothing here.

So |x_lag - x_plant| <= V (tau + kv/kp + 2 P) + max|T| / (kp r^2). At rest, after a hold of H s: the lag's error
has decayed to e^(-H/tau) of what it was, the plant's servo to nothing, so |x_lag - x_plant| <= V (tau + P)
e^(-H/tau) + |T| / (kp r^2) + the rigid reducer's soft twist under T (REDUCER_COMPLIANCE), and the efforts
agree within the plant's soft-constraint bound (its reducer torque against the load model's at the same angle,
docs/how-to/mujoco-plant.md: 5.3e-6 relative measured; 1e-5 held) plus the load model's change over the angles'
difference (its slope, by a central difference, times it).

What the lag cannot imitate, so not asserted: in motion the plant's effort carries the linkage's inertia, which the
static load model has not (the servo's 50 Hz response at each change of the interpolated command's slope). And
with its own default limits (the motor's speed and acceleration through the reducer, braking within the error left)
the lag falls behind further, where the plant, whose servo has the speed limit only, does not.
"""

from __future__ import annotations

import dataclasses
import math
import random

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fourbar_ros.config.antenna_config import AntennaConfig, default_config
from fourbar_ros.config.robot_model import joint_limits
from fourbar_ros.config.sim_actuator_params import SIM_PARAMETERS_BY_NAME
from fourbar_ros.node.sim_actuator import LagDrive
from fourbar_ros.rules.simulated_drive import DriveLimits, LagActuator, effort_at

pytest.importorskip('mujoco', reason='the plant drive needs the mujoco package (the plant extra)')
from fourbar_ros.plant.mjcf import DriveModel
from fourbar_ros.plant.sim_drive import PlantDrive

BASE = default_config()
PERIOD = 1.0 / float(SIM_PARAMETERS_BY_NAME['publish_rate'].default)  # s: the controller's update period
TAU = float(SIM_PARAMETERS_BY_NAME['time_constant'].default)  # s
DRIVE = DriveModel()
#: The plant's drive torque at rest against the load model's (relative): the plant's documented 5.3e-6, rounded up.
REST_EFFORT_REL = 1e-5
#: The rigid reducer is a soft equality too: it twists (1 - d)/d tau^2 / (J r^2) rad per N m at the rocker
#: (impedance d = 0.9999, time constant tau = closure_timeconst, the rotor's inertia J through the reducer;
#: 1.6e-10 rad per N m, as measured); 1.1 times it is held (the linkage's inertia shares the constraint's mass).
REDUCER_COMPLIANCE = ((1 - 0.9999) / 0.9999 * DRIVE.closure_timeconst ** 2
                      / (DRIVE.rotor_inertia * BASE.reducer_ratio ** 2))


def smooth_motion(start: float, moves: list[tuple[float, float, float, float]]) -> tuple[list[float], list[bool]]:
    """The reference sampled each period, one period ahead, from ``start`` (rad) through ``moves`` (target rad,
    speed rad/s, acceleration rad/s^2, hold s after it): each a trapezoidal (or triangular) speed profile. Returns
    the held commands (one per period) and whether each period ends a hold of at least its full length."""
    out: list[float] = []
    resting: list[bool] = []
    x0 = start
    for target, speed, accel, hold in moves:
        d = target - x0
        dist = abs(d)
        ta = min(speed / accel, math.sqrt(dist / accel))  # time to top speed (or to the half-way point)
        top = accel * ta
        tc = (dist - accel * ta * ta) / top if top > 0.0 else 0.0
        total = 2 * ta + tc

        def at(t: float, x0: float = x0, d: float = d, ta: float = ta, tc: float = tc, top: float = top,
               accel: float = accel, total: float = total) -> float:
            if t <= 0.0:
                s = 0.0
            elif t < ta:
                s = 0.5 * accel * t * t
            elif t < ta + tc:
                s = 0.5 * accel * ta * ta + top * (t - ta)
            elif t < total:
                s = abs(d) - 0.5 * accel * (total - t) ** 2
            else:
                s = abs(d)
            return x0 + math.copysign(s, d)
        n_move = math.ceil(total / PERIOD)
        n_hold = math.ceil(hold / PERIOD)
        for k in range(n_move + n_hold):
            out.append(at((k + 1) * PERIOD))  # the reference one period ahead, held over the period
            resting.append(k == n_move + n_hold - 1)
        x0 = target
    return out, resting


def slope(cfg: AntennaConfig, q: float, lower: float, upper: float) -> float:
    """|d effort / d q| of the load model (N m/rad) at ``q`` by a central difference of 1e-6 rad about ``q`` moved
    into the range (the plant rests up to its deflection beyond an end)."""
    h = 1e-6
    centre = min(max(q, lower + h), upper - h)
    return abs(effort_at(cfg, centre + h) - effort_at(cfg, centre - h)) / (2 * h)


MOVE = st.tuples(st.floats(0.0, 1.0), st.floats(0.1, 1.0), st.floats(0.05, 2.0), st.floats(0.3, 0.8))


@settings(max_examples=24, suppress_health_check=[HealthCheck.too_slow])
@given(start=st.floats(0.0, 1.0), moves=st.lists(MOVE, min_size=1, max_size=3),
       mass=st.sampled_from([0.0, 4.0]))
def test_the_lag_and_the_plant_agree_within_their_lags_and_at_rest(
        start: float, moves: list[tuple[float, float, float, float]], mass: float) -> None:
    cfg = dataclasses.replace(BASE, antenna_mass=mass)
    lim = joint_limits(cfg)[cfg.driven_joint]
    vmax = lim.velocity  # rad/s: the joint's speed limit, the node's planner's
    span = lim.upper - lim.lower

    def q(f: float) -> float:
        return lim.lower + f * span
    plan = [(q(t), s * vmax, a, h) for t, s, a, h in moves]
    commands, resting = smooth_motion(q(start), plan)
    # The lag's own limits beyond the reference's (speed 1.2 V is the most e/tau asks, |e| <= V (tau + P)); braking
    # and acceleration limits far beyond (a staircase step asks V P (1 - e^(-h/tau)) / h per 1 ms step).
    lag = LagDrive(cfg, LagActuator(DriveLimits(lim.lower, lim.upper, 1e3, 1e9, TAU), q(start)))
    plant = PlantDrive(cfg, q(start), lim.lower, lim.upper, DRIVE)
    stiffness = DRIVE.kp * cfg.reducer_ratio ** 2  # N m/rad at the rocker
    worst_effort = abs(plant.effort())
    hold_of = {i: h for i, h in zip(
        [k for k, r in enumerate(resting) if r], [h for _, _, _, h in plan], strict=True)}
    speeds = [abs(b - a) / PERIOD for a, b in zip([q(start), *commands], commands, strict=False)]
    seen_speed = max(speeds)
    assert seen_speed <= vmax * (1 + 1e-9) + 1e-12, seen_speed
    for k, c in enumerate(commands):
        lag.advance(PERIOD, c)
        plant.advance(PERIOD, c)
        effort = plant.effort()
        worst_effort = max(worst_effort, abs(effort))
        moving_bound = vmax * (TAU + DRIVE.kv / DRIVE.kp + 2 * PERIOD) + worst_effort / stiffness
        gap = abs(lag.position - plant.position)
        assert gap <= moving_bound, (k, lag.position, plant.position, gap, moving_bound)
        if resting[k]:
            hold = hold_of[k]
            rest_bound = (vmax * (TAU + PERIOD) * math.exp(-hold / TAU)
                          + abs(effort) / stiffness + 1.1 * REDUCER_COMPLIANCE * abs(effort))
            assert gap <= rest_bound, ('at rest', k, hold, gap, rest_bound)
            lag_effort = lag.effort()
            effort_bound = (REST_EFFORT_REL * abs(lag_effort)
                            + slope(cfg, plant.position, lim.lower, lim.upper) * gap * (1 + 1e-3))
            assert abs(effort - lag_effort) <= effort_bound, ('at rest', k, effort, lag_effort, effort_bound)


def test_late_and_early_updates_move_the_plant_no_faster_than_the_reference() -> None:
    """A loaded machine's timer: each update up to 0.6 periods late (a periodic timer keeps its phase, so a late one
    is followed by an early one), the reference a ramp at 0.9 V sampled one period ahead, as the controller writes it.
    Each setpoint is reached over the real time between its update and the one before, so the servo's command moves
    at the reference's mean speed over that time: at most 0.9 V (to rounding). Spread over the next
    interval instead, a setpoint after a late update would move at up to 0.9 V (1.6 / 0.4) = 3.6 V. The rocker
    follows the command through the servo's non-negative impulse response (the load's slope dT/dq > 0 only stiffens
    it), up to the soft reducer's own mode, so it stays under V, 10% above the reference's speed; at rest at the end
    it stands at the last setpoint less the servo's deflection under the load."""
    cfg = BASE
    lim = joint_limits(cfg)[cfg.driven_joint]
    vmax = lim.velocity
    speed = 0.9 * vmax
    start, move = lim.lower + 0.1, 1.5  # rad, s

    def reference(t: float) -> float:
        return start + speed * min(max(t - 0.1, 0.0), move)
    plant = PlantDrive(cfg, start, lim.lower, lim.upper, DRIVE)
    rng = random.Random(7)
    before, setpoint, command, stepped = 0.0, reference(PERIOD), plant.command, plant.plant.data.time
    peak_command = peak_rocker = 0.0
    for k in range(1, round((move + 0.5) / PERIOD)):
        at = k * PERIOD + rng.uniform(0.0, 0.6 * PERIOD)
        plant.advance(at - before, setpoint)
        # over the whole timesteps the interval made (the rest of it waits for the next)
        if plant.plant.data.time > stepped:
            peak_command = max(peak_command, abs(plant.command - command) / (plant.plant.data.time - stepped))
        peak_rocker = max(peak_rocker, abs(plant.velocity))
        before, setpoint, command, stepped = at, reference(at + PERIOD), plant.command, plant.plant.data.time
    # to rounding: a setpoint's span is whole ns, off by up to 0.5 ns of an interval of at least 0.4 P (twice held)
    assert peak_command <= speed * (1 + 1e-9 / (0.4 * PERIOD)), (peak_command, speed)
    assert peak_rocker <= vmax, (peak_rocker, speed, vmax)
    effort = plant.effort()
    deflection = effort / (DRIVE.kp * cfg.reducer_ratio ** 2)  # rad at the rocker, against the load
    final = reference(move + 0.1)
    assert abs(plant.position - (final - deflection)) <= 1e-3 * abs(deflection), (plant.position, final, deflection)
