"""The simulated actuator's pure part: trajectory checks and sampling (as joint_trajectory_controller samples),
the lagged, limited drive, and the encoder."""

from __future__ import annotations

import math

import numpy as np
import pytest
from support.trajectory_points import Duration, Point

from fourbar_ros.config.antenna_config import default_config
from fourbar_ros.config.controllers import trajectory_controller
from fourbar_ros.rules.controller_contract import ContractRule
from fourbar_ros.rules.controller_motion import ControllerPoint, Reference, controller_reference
from fourbar_ros.rules.simulated_drive import (
    STEP_S,
    DriveLimits,
    Encoder,
    LagActuator,
    Setpoint,
    Trajectory,
    TrajectoryError,
    TrajectoryFollower,
    Waypoint,
    braking_speed,
    waypoints,
)

EPS = float(np.finfo(np.float64).eps)


def at(t: float) -> Duration:
    sec = math.floor(t)
    return Duration(sec, round((t - sec) * 1e9))


# ----------------------------------------------------------------------------- trajectory checks

def test_waypoints_pick_the_joint_column_and_optional_arrays() -> None:
    pts = [Point([9.0, 0.1], time_from_start=at(0.5)),
           Point([9.0, 0.2], [0.0, 0.3], [0.0, 0.4], time_from_start=at(1.0))]
    got = waypoints(['other', 'j'], 'j', pts)
    assert got == [Waypoint(0.5, 0.1, None, None), Waypoint(1.0, 0.2, 0.3, 0.4)]
    assert waypoints(['j'], 'j', []) == []


@pytest.mark.parametrize('names, points, why', [
    (['a'], [Point([0.0], time_from_start=at(1.0))], 'missing'),
    (['j', 'j'], [Point([0.0, 0.0], time_from_start=at(1.0))], 'named twice'),
    (['j'], [Point([0.0, 1.0], time_from_start=at(1.0))], '2 positions for 1'),
    (['j'], [Point([], time_from_start=at(1.0))], '0 positions'),
    (['j'], [Point([0.0], [1.0, 2.0], time_from_start=at(1.0))], '2 velocities'),
    (['j'], [Point([math.nan], time_from_start=at(1.0))], 'nan'),
    (['j'], [Point([0.0], [math.inf], time_from_start=at(1.0))], 'inf'),
    (['j'], [Point([0.0], [0.0], [-math.inf], time_from_start=at(1.0))], 'inf'),
    (['j'], [Point([0.0], time_from_start=at(1.0)), Point([0.1], time_from_start=at(1.0))], 'does not increase'),
    (['j'], [Point([0.0], time_from_start=at(2.0)), Point([0.1], time_from_start=at(1.0))], 'does not increase'),
])
def test_waypoints_refuse_bad_trajectories(names: list[str], points: list[Point], why: str) -> None:
    with pytest.raises(TrajectoryError, match=why):
        waypoints(names, 'j', points)


def test_waypoints_bound_the_point_count() -> None:
    pts = [Point([0.0], time_from_start=at(0.01 * (k + 1))) for k in range(11)]
    assert len(waypoints(['j'], 'j', pts[:10], max_points=10)) == 10
    with pytest.raises(TrajectoryError, match='11 points; at most 10'):
        waypoints(['j'], 'j', pts, max_points=10)


# ----------------------------------------------------------------------------- sampling

def trajectory(start: float, position: float, velocity: float | None, points: list[Waypoint],
               velocity_state: bool = True) -> Trajectory:
    """A trajectory taken over at ``start`` s from the measured state, zero stamp."""
    ref = controller_reference(velocity_state, [ControllerPoint(*p) for p in points], None, 0.0, position, velocity,
                               0.0)
    return Trajectory(start, ref)


def test_trajectory_sampling_in_time() -> None:
    traj = trajectory(10.0, 1.0, None, [Waypoint(1.0, 2.0, None, None), Waypoint(3.0, 0.0, None, None)],
                      velocity_state=False)  # no velocity state interface, positions only: linear lead-in
    assert traj.sample(9.0) == Setpoint(1.0, 1.0, 0.0)  # before its takeover: its value there
    assert traj.sample(10.5) == Setpoint(1.5, 1.0, 0.0)  # from the measured state to the first point
    assert traj.sample(11.0).position == 2.0
    assert traj.sample(12.0) == Setpoint(1.0, -1.0, 0.0)
    assert traj.sample(13.0) == Setpoint(0.0, 0.0, 0.0)  # after its end: hold the last position
    assert traj.sample(99.0) == Setpoint(0.0, 0.0, 0.0)
    assert traj.end == 13.0


def test_trajectory_lead_in_is_quintic_when_the_first_point_has_accelerations() -> None:
    """From the measured state (position and velocity: the controller reads no acceleration) to a point with
    velocity and acceleration: the controller zero-fills the state's acceleration, so the lead-in is quintic, with
    acceleration 0 at its start; position and velocity continuous at the start."""
    traj = trajectory(0.0, 0.3, 0.2, [Waypoint(2.0, 0.5, 0.0, 0.0)])
    s = traj.sample(0.0)
    assert (s.position, s.velocity, s.acceleration) == pytest.approx((0.3, 0.2, 0.0), abs=8 * EPS)
    assert traj.reference.degrees == (5,)
    assert traj.sample(2.0) == Setpoint(0.5, 0.0, 0.0)


# ----------------------------------------------------------------------------- the trajectory controller

JTC = trajectory_controller('', default_config().trajectory_controller)
J = default_config().driven_joint
TOL = JTC.tolerance(J)


def follower(position: float = 0.8) -> TrajectoryFollower:
    return TrajectoryFollower(JTC, J, position)


def rest(times: list[float], positions: list[float]) -> list[Point]:
    return [Point([p], [0.0], time_from_start=at(t)) for t, p in zip(times, positions, strict=True)]


#: What the controller refuses, one message per contract rule: (joint_names, points, stamp ns); arrival at 10 s.
REFUSED: dict[ContractRule, tuple[list[str], list[Point], int]] = {
    ContractRule.PARTIAL_JOINTS: ([J, 'b'], [Point([0.8, 0.0], time_from_start=at(1.0))], 0),
    ContractRule.NO_POINTS: ([J], [], 0),
    ContractRule.FOREIGN_JOINT: (['not_ours'], rest([1.0], [0.8]), 0),
    ContractRule.END_MOVING: ([J], [Point([0.8], [0.01], time_from_start=at(1.0))], 0),
    ContractRule.ENDS_IN_PAST: ([J], rest([1.0], [0.8]), 8 * 10**9),
    ContractRule.TIME_NOT_INCREASING: ([J], rest([1.0, 1.0], [0.8, 0.9]), 0),
    ContractRule.FIELD_SIZE: ([J], [Point([0.8, 0.9], time_from_start=at(1.0))], 0),
    ContractRule.EFFORT_FIELD: ([J], [Point([0.8], effort=[0.1], time_from_start=at(1.0))], 0),
}


@pytest.mark.parametrize('rule', list(REFUSED), ids=lambda r: r.value)
def test_the_follower_refuses_what_the_controller_refuses_and_goes_on(rule: ContractRule) -> None:
    f = follower()
    assert f.receive([J], rest([0.0, 2.0], [0.8, 0.9]), 0, 10 * 10**9) is None
    running = f.reference(10.0, 0.8, 0.0)
    names, points, stamp = REFUSED[rule]
    refusal = f.receive(names, points, stamp, 10 * 10**9)
    assert refusal is not None and refusal.rule is rule and f.counters.refused[rule] == 1
    # The running trajectory goes on: the same reference as without the refused message.
    assert f.reference(11.0, 0.85, 0.0) == trajectory(10.0, 0.8, 0.0, waypoints([J], J, rest([0.0, 2.0],
                                                                                              [0.8, 0.9]))
                                                       ).sample(11.0)
    assert (running.position, running.velocity) == (0.8, 0.0)


def test_a_trajectory_starts_at_its_first_update_from_the_measured_state() -> None:
    f = follower(position=0.8)
    f.hold(0.9)  # a forward command: the last commanded reference is 0.9
    assert f.receive([J], rest([1.0], [0.85]), 0, 5 * 10**9) is None
    # The first update after arrival (at 5.2 s): the drive measured at 0.83 moving at 0.01 rad/s, not at 0.9.
    r0 = f.reference(5.2, 0.83, 0.01)
    assert (r0.position, r0.velocity) == pytest.approx((0.83, 0.01), abs=4 * EPS)
    assert f.reference(6.2, 0.85, 0.0) == Setpoint(0.85, 0.0, 0.0)  # its start is that update (stamp 0)


def test_a_trajectory_is_taken_over_at_the_first_update_after_its_arrival() -> None:
    # A late tick makes the updates it missed; a trajectory is taken over by the first of them at or after its arrival.
    f = follower(position=0.8)
    assert f.receive([J], rest([1.0], [0.85]), 0, 5_005_000_000) is None
    assert f.reference(5.0, 0.8, 0.0) == Setpoint(0.8, 0.0, 0.0) and f.waiting == 1  # arrived after this update
    assert f.reference(5.01, 0.8, 0.0) != Setpoint(0.8, 0.0, 0.0) and f.waiting == 0  # taken over here
    assert f.reference(6.01, 0.85, 0.0) == Setpoint(0.85, 0.0, 0.0)  # its start was that update (stamp 0)


def test_an_update_takes_only_the_latest_trajectory_that_arrived_before_it() -> None:
    f = follower(position=0.8)
    for k, goal in enumerate((0.9, 0.85)):  # two within one update period: the first is never followed
        assert f.receive([J], rest([1.0], [goal]), 0, 5 * 10**9 + k) is None
    assert f.receive([J], rest([1.0], [0.95]), 0, 5_020_000_000) is None  # after the next update
    taken: list[Reference] = []
    f.on_takeover = taken.append
    f.reference(5.01, 0.8, 0.0)
    assert len(taken) == 1 and f.waiting == 1
    assert taken[0].sample(1.0)[0] == 0.85  # the latest of the two: at 0.85 from 1 s after its takeover on
    f.reference(5.02, 0.8, 0.0)
    assert len(taken) == 2 and f.waiting == 0 and taken[1].sample(1.0)[0] == 0.95


def test_the_follower_holds_on_a_trajectory_tolerance_violation() -> None:
    f = follower(position=0.8)
    assert f.receive([J], rest([0.0, 1.0], [0.8, 0.9]), 0, 0) is None
    assert f.reference(0.0, 0.8, 0.0).position == 0.8
    mid = f.reference(0.5, 0.85 - 0.5 * TOL.trajectory, 0.0)  # half the tolerance behind at mid-way (the cubic is
    # at 0.85 there): within
    assert mid.position == pytest.approx(0.85, abs=1e-12)
    stuck = 0.85 - TOL.trajectory - 1e-3
    held = f.reference(0.5, stuck, 0.0)
    assert f.counters.tolerance_holds == 1 and held == Setpoint(stuck, 0.0, 0.0)
    assert f.reference(5.0, stuck, 0.0) == Setpoint(stuck, 0.0, 0.0) and f.holding_reason is not None


def test_the_follower_holds_after_goal_time_outside_the_goal_tolerance() -> None:
    f = follower(position=0.8)
    assert f.receive([J], rest([0.0, 0.1], [0.8, 0.81]), 0, 0) is None
    f.reference(0.0, 0.8, 0.0)
    off = 0.81 - 2 * TOL.goal  # outside the goal tolerance, inside the path tolerance
    assert f.reference(0.1 + 0.5 * JTC.goal_time, off, 0.0) == Setpoint(0.81, 0.0, 0.0)  # still within goal_time
    assert f.counters.goal_time_holds == 0
    assert f.reference(0.1 + 1.5 * JTC.goal_time, off, 0.0) == Setpoint(off, 0.0, 0.0)
    assert f.counters.goal_time_holds == 1 and f.counters.tolerance_holds == 0


# ----------------------------------------------------------------------------- drive

LIMITS = DriveLimits(lower=-1.0, upper=1.0, max_velocity=0.5, max_acceleration=2.0, tau=0.05)


def run(act: LagActuator, reference: float, seconds: float, dt: float = 0.01) -> list[tuple[float, float]]:
    out = []
    for _ in range(round(seconds / dt)):
        act.advance(dt, reference)
        out.append((act.position, act.velocity))
    return out


def test_lag_without_binding_limits_is_the_exact_first_order_response() -> None:
    lim = DriveLimits(-1.0, 1.0, max_velocity=1e9, max_acceleration=1e12, tau=0.1)
    act = LagActuator(lim, 0.0, step=0.01)
    for k, (x, _v) in enumerate(run(act, 0.01, 1.0), start=1):
        want = 0.01 * (1.0 - math.exp(-0.01 * k / 0.1))
        # k steps each rounding a few times: a few ulps of the step size per step.
        assert abs(x - want) <= 8 * k * EPS * 0.01, (k, x, want)


@pytest.mark.parametrize('error', [0.0, 1e-9, 0.3 * 2.0 * STEP_S**2, 2.0 * STEP_S**2, 1.7 * 2.0 * STEP_S**2,
                                   3.0 * 2.0 * STEP_S**2, 1e-3, 0.3])
def test_braking_speed_stops_exactly_within_the_error(error: float) -> None:
    """From the braking speed, slowing by a h per step covers the error and no more (the largest such speed)."""
    a, h = 2.0, STEP_S
    v = braking_speed(error, a, h)
    covered, u = 0.0, v
    while u > 0.0:
        covered += u * h
        u -= a * h
    # The sum of about sqrt(2 E) terms, each rounded: a few ulps of the error per term.
    tol = 4 * EPS * (error + a * h * h) * (2 + math.sqrt(2 * error / (a * h * h)))
    assert abs(covered - error) <= tol, (v, covered, error)
    assert braking_speed(-error, a, h) == v


def test_limits_hold_and_a_step_is_reached_without_overshoot() -> None:
    act = LagActuator(LIMITS, -0.5)
    trace = run(act, 0.5, 4.0, dt=STEP_S)
    v_prev = 0.0
    for x, v in trace:
        assert abs(v) <= LIMITS.max_velocity
        assert abs(v - v_prev) <= LIMITS.max_acceleration * STEP_S * (1 + 4 * EPS)
        assert x <= 0.5 + 2 * EPS * 0.5  # no overshoot, up to the rounding of the last step
        v_prev = v
    assert max(abs(v) for _x, v in trace) == LIMITS.max_velocity  # the speed limit was reached
    assert trace[-1][0] == pytest.approx(0.5, abs=1e-12)


def test_ramp_is_followed_with_the_lag() -> None:
    """A slow ramp (no limit binding) is followed with the first-order steady lag speed * tau."""
    act = LagActuator(LIMITS, 0.0)
    speed, dt = 0.1, STEP_S
    for k in range(1, 2001):
        act.advance(dt, speed * k * dt)
    ref = speed * 2.0
    # Zero-order hold of the reference over a step adds dt/2 of delay to the continuous lag.
    assert ref - act.position == pytest.approx(speed * (LIMITS.tau - 0.5 * dt), rel=1e-3)
    assert act.velocity == pytest.approx(speed, rel=1e-6)


def test_reference_and_start_are_clamped_to_the_range() -> None:
    act = LagActuator(LIMITS, 5.0)
    assert act.position == 1.0
    run(act, -7.0, 10.0)
    assert act.position == -1.0


def test_irregular_periods_integrate_the_same_whole_steps() -> None:
    """A late tick (one long period) and regular ticks give the same state once the same time has passed: the
    drive steps in fixed STEP_S whatever the caller's period; a part step waits for the next call."""
    a, b = LagActuator(LIMITS, 0.0), LagActuator(LIMITS, 0.0)
    a.advance(0.1, 0.3)
    for _ in range(40):
        b.advance(0.0025, 0.3)
    assert (a.position, a.velocity) == (b.position, b.velocity)
    c = LagActuator(LIMITS, 0.0)
    c.advance(0.5 * STEP_S, 0.3)
    assert c.position == 0.0
    c.advance(0.5 * STEP_S, 0.3)
    assert c.position > 0.0


@pytest.mark.parametrize('kwargs', [dict(lower=1.0, upper=0.0), dict(max_velocity=0.0), dict(tau=-1.0),
                                    dict(max_acceleration=math.nan)])
def test_drive_limits_refuse_nonsense(kwargs: dict[str, float]) -> None:
    values = dict(lower=-1.0, upper=1.0, max_velocity=1.0, max_acceleration=1.0, tau=0.1) | kwargs
    with pytest.raises(ValueError):
        DriveLimits(**values)


# ----------------------------------------------------------------------------- encoder

def test_encoder_quantizes_to_counts_and_adds_the_offset() -> None:
    enc = Encoder(counts_per_rev=4096, reducer_ratio=500.0, offset=0.01)
    res = 2.0 * math.pi / (4096 * 500.0)
    assert enc.resolution == res
    for x in np.linspace(-0.7, 0.9, 101):
        pos, vel, eff = enc.measure(float(x), 0.25, 1.5)
        counts = (pos - 0.01) / res
        assert abs(counts - round(counts)) <= 1e-6  # a whole number of counts (up to the offset's rounding)
        assert abs(pos - 0.01 - x) <= 0.5 * res * (1 + 1e-9)
        assert (vel, eff) == (0.25, 1.5)


def test_encoder_without_counts_or_noise_is_exact() -> None:
    assert Encoder().measure(0.123, -0.4, 2.0) == (0.123, -0.4, 2.0)


def test_encoder_noise_is_seeded_and_has_its_spread() -> None:
    a = Encoder(position_noise=1e-3, velocity_noise=2e-3, effort_noise=0.1, seed=3)
    b = Encoder(position_noise=1e-3, velocity_noise=2e-3, effort_noise=0.1, seed=3)
    samples = np.array([a.measure(0.0, 0.0, 0.0) for _ in range(4000)])
    assert np.array_equal(samples, np.array([b.measure(0.0, 0.0, 0.0) for _ in range(4000)]))
    # 4000 samples: the sample deviation is within 5% of sigma with probability far above 1 - 1e-6.
    assert samples.std(axis=0) == pytest.approx([1e-3, 2e-3, 0.1], rel=0.05)
    assert not np.array_equal(samples, np.array([Encoder(1, 1.0, 0.0, 1e-3, 2e-3, 0.1, seed=4).measure(0.0, 0.0, 0.0)
                                                 for _ in range(4000)]))
