"""The plant as a drive (``PlantBackend``) on a fake clock: stepped to the clock in whole timesteps; an open-loop
stepper reports its count, which stays when the rotor slips while the truth moves by whole electrical cycles; an
encoder reports the true angle to a count; the antenna's accelerometer gives theta at rest."""

from __future__ import annotations

import itertools
import math
import random

import pytest

pytest.importorskip('mujoco', reason='the MuJoCo plant needs the mujoco package (the plant extra)')

from support.mujoco_log import mujoco_warnings

from fourbar_ros.config.antenna_config import default_config
from fourbar_ros.config.robot_model import driven_angle
from fourbar_ros.core.loads import pose
from fourbar_ros.drive.backend import DriveBackend
from fourbar_ros.drive.rules import DriveLimits, DriveRules
from fourbar_ros.motion.planner import JointMotionState
from fourbar_ros.plant.backend import MICROSTEPS, PlantBackend, stepper_drive
from fourbar_ros.plant.mjcf import DriveModel
from fourbar_ros.rules.model_check import imu_theta
from fourbar_ros.rules.motion_plan import plan_command

CFG = default_config()  # config/antenna.yaml's values: no antenna weight, load_torque 3.5 N m, ratio 500
RATIO = CFG.reducer_ratio
TEETH = DriveModel().stepper_teeth
CYCLE = 2.0 * math.pi / TEETH  # rad at the motor: one electrical cycle
MICROSTEP = CYCLE / 4.0 / MICROSTEPS / RATIO  # rad at the rocker
PERIOD = 1.0 / CFG.control_rate  # s between the bridge's reads and writes


class FakeClock:
    """Seconds the test sets."""

    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now

    def run(self, backend: PlantBackend, seconds: float) -> None:
        """Read every PERIOD for ``seconds``, as the bridge does."""
        for _ in range(round(seconds / PERIOD)):
            self.now += PERIOD
            backend.read()


def make(**kwargs: object) -> tuple[PlantBackend, FakeClock]:
    clock = FakeClock()
    backend = PlantBackend(CFG, clock=clock, **kwargs)  # type: ignore[arg-type]
    backend.enable()
    return backend, clock


def test_it_is_a_drive_backend_built_from_the_configuration_alone() -> None:
    backend = PlantBackend(CFG)  # what the bridge's backend:=module:Class does
    assert isinstance(backend, DriveBackend)
    assert backend.drive.stepper_torque == CFG.motor_torque_limit
    assert backend.wind_torque == -CFG.load_torque  # the design load


def test_the_design_load_is_held_with_margin_and_twice_it_is_not() -> None:
    """The default pull-out torque against the design load at the motor over the tilt range (stepper_drive's
    docstring states these figures)."""
    pull_out = stepper_drive(CFG).stepper_torque
    assert pull_out is not None
    need = [abs(pose(CFG, t).input_torque / RATIO) for t in (CFG.theta_min, 0.0, CFG.theta_max)]
    margins = [pull_out / n for n in need]
    assert min(margins) > 1.1 and round(min(margins), 2) == 1.18 and round(max(margins), 2) == 1.95, margins
    assert all(2.0 * n > pull_out for n in need)


def test_the_plant_is_stepped_to_the_clock_in_whole_timesteps() -> None:
    backend, clock = make()
    dt = backend.plant.timestep
    assert backend.simulated_time == 0.0
    clock.now += 0.0255
    backend.read()
    assert round(backend.simulated_time / dt) == 25  # the half step waits for the next call
    clock.now += 0.0010
    backend.read()
    assert round(backend.simulated_time / dt) == 26
    backend.read()  # the same clock: no step
    assert round(backend.simulated_time / dt) == 26
    clock.now += 5.0  # a call 5 s late steps at most max_catch_up (1 s), the rest counted as lost
    backend.read()
    assert round(backend.simulated_time / dt) == 1026
    assert math.isclose(backend.lost_time, 4.0, rel_tol=1e-9), backend.lost_time


def test_the_open_loop_count_is_the_start_to_a_microstep_and_writes_round_to_microsteps() -> None:
    start = driven_angle(CFG)
    backend, clock = make()
    position, velocity, effort = backend.read()
    assert velocity is None and effort is None
    assert abs(position - start) <= 0.5 * MICROSTEP  # the nearest microstep
    count = backend.count
    assert position == count * (CYCLE / 4.0 / MICROSTEPS) / RATIO + CFG.driven_joint_offset
    backend.write(position + 0.4 * MICROSTEP)
    clock.run(backend, 0.1)
    assert backend.count == count and backend.read()[0] == position
    backend.write(position + 0.6 * MICROSTEP)
    clock.run(backend, 0.1)
    assert backend.count == count + 1
    assert math.isclose(backend.read()[0] - position, MICROSTEP, rel_tol=1e-9)


def test_a_smooth_move_is_followed_and_the_count_reaches_the_goal() -> None:
    """A move within the motor's limits (0.01 rad at the rocker in 1 s, cosine: 7.9 rad/s and 25 rad/s^2 peak at
    the motor, under 31 rad/s and 100 rad/s^2) under the design load: no slip; the count ends at the goal to a
    microstep; the truth lags it by the load's electrical angle, asin(load / pull-out) / teeth at the motor."""
    with mujoco_warnings() as warnings:
        backend, clock = make()
        begin = backend.read()[0]
        amplitude, duration = 0.01, 1.0
        for i in range(1, round(duration / PERIOD) + 1):
            clock.now += PERIOD
            backend.read()
            backend.write(begin + 0.5 * amplitude * (1.0 - math.cos(math.pi * i * PERIOD / duration)))
        clock.run(backend, 0.5)
    assert not warnings, warnings
    assert backend.slipped_cycles == 0
    goal = begin + amplitude
    position = backend.read()[0]
    assert abs(position - goal) <= 0.5 * MICROSTEP
    backend.plant.forward()
    load = pose(CFG, backend.theta).input_torque / RATIO  # N m at the motor
    lag = -math.asin(load / CFG.motor_torque_limit) / TEETH / RATIO  # rad at the rocker
    assert math.isclose(backend.true_rocker_angle - position, lag, rel_tol=1e-3), (backend.true_rocker_angle,
                                                                                   position, lag)


#: The node's moves for the uneven delivery below: from level to the range's top end, then over the whole range to
#: its bottom end (rad of theta), each with its seed.
MOVES = [(0.0, CFG.theta_max, 1), (CFG.theta_max, CFG.theta_min, 2)]


@pytest.mark.parametrize(('start', 'end', 'seed'), MOVES)
def test_the_node_s_move_delivered_unevenly_through_the_bridge_s_rules_does_not_slip(start: float, end: float,
                                                                                     seed: int) -> None:
    """The node's plan to ``end`` sampled every PERIOD, as the controller commands it, each command arriving 0 to
    6 ms after its time (in order: 4 to 16 ms apart), through the bridge's rules (a reading every PERIOD, 3 ms
    into it), under the design load: the rotor never slips, no command is clamped (the drive follows within the
    bridge's bound) and the count rests on the plan's end to half a microstep."""
    rnd = random.Random(seed)
    backend, clock = make(position=driven_angle(CFG, start))
    rules = DriveRules(DriveLimits.from_config(CFG))
    rules.on_reading(clock.now, backend.read())
    plan = plan_command(CFG, JointMotionState(backend.read()[0], 0.0), end)
    events, arrive, t0 = [], 0.0, clock.now
    for k in range(math.ceil(plan.duration / PERIOD) + 50):  # on past the end: the controller holds its last point
        arrive = max(arrive, t0 + k * PERIOD + rnd.uniform(0.0, 0.006))
        events += [(arrive, plan.state_at(k * PERIOD).position), (t0 + k * PERIOD + 0.003, None)]
    slipped = 0
    with mujoco_warnings() as warnings:
        for at, command in sorted(events, key=lambda e: e[0]):
            clock.now = at
            if command is None:
                rules.on_reading(at, backend.read())
            elif (target := rules.on_command(at, command)) is not None:
                backend.write(target)
            slipped = max(slipped, abs(backend.slipped_cycles))
        for _ in range(50):
            clock.now += PERIOD
            rules.on_reading(clock.now, backend.read())
    assert not warnings, warnings
    seen = f'{start!r} -> {end!r} rad: slipped up to {slipped} cycles, {rules.counters.clamped} commands clamped'
    assert slipped == 0 and rules.counters.clamped == 0, seen
    goal = plan.state_at(plan.duration).position
    assert abs(backend.read()[0] - goal) <= 0.5 * MICROSTEP, (backend.read()[0], goal)


def test_a_wind_beyond_pull_out_slips_the_truth_by_whole_cycles_and_the_count_stays() -> None:
    """No steady wind, then a gust of three design loads for 0.3 s (about 2.7 pull-out torques at the motor), then
    calm: the count a controller reads is where it was; the rotor rests whole electrical cycles off, so the
    rocker, unloaded in a detent, is cycles * CYCLE / ratio off the count (the rest of the motion decays as
    exp(-316 t), far below 1e-9 rad after 1 s)."""
    with mujoco_warnings() as warnings:
        backend, clock = make(wind_torque=0.0)
        before = backend.read()[0]
        clock.run(backend, 0.2)
        assert backend.slipped_cycles == 0
        backend.gust(-3.0 * CFG.load_torque, 0.3)
        clock.run(backend, 0.15)
        assert backend.wind_torque == -3.0 * CFG.load_torque
        clock.run(backend, 1.15)
    assert not warnings, warnings
    assert backend.wind_torque == 0.0
    position, velocity, effort = backend.read()
    assert (position, velocity, effort) == (before, None, None)  # the open loop's count: it lies
    cycles = backend.slipped_cycles
    assert cycles < 0, 'the way the wind pushed it'
    truth_off = backend.true_rocker_angle - position
    assert abs(truth_off - cycles * CYCLE / RATIO) < 1e-9, (truth_off, cycles)


def test_an_encoder_reports_the_true_angle_to_a_count_and_sees_the_slip() -> None:
    counts = 2 ** 16
    resolution = 2.0 * math.pi / counts
    backend, clock = make(encoder_counts=counts, wind_torque=0.0)
    position, velocity, effort = backend.read()
    assert position == round(backend.true_rocker_angle / resolution) * resolution
    assert velocity == 0.0 and effort is None  # a stepper's driver measures no torque
    backend.gust(-3.0 * CFG.load_torque, 0.3)
    readings = []
    for _ in range(150):
        clock.now += PERIOD
        reading = backend.read()
        readings.append((backend.simulated_time, *reading))
    assert backend.slipped_cycles < 0
    for (t0, p0, _, _), (t1, p1, v1, _) in itertools.pairwise(readings):
        assert v1 == (p1 - p0) / (t1 - t0)  # differenced over the simulated time between reads
    position = readings[-1][1]
    assert abs(position - backend.true_rocker_angle) <= 0.5 * resolution
    assert abs(position - backend.commanded_position) > 0.5 * CYCLE / RATIO  # unlike the count, it sees the slip


@pytest.mark.parametrize('theta', [CFG.theta_min, 0.0, CFG.theta_max])
def test_the_accelerometer_gives_theta_at_rest(theta: float) -> None:
    """At rest the accelerometer reads gravity's reaction in the antenna's axes, so imu_theta is theta. What it
    reads besides is the site's acceleration, at most (ab + h) (sum |joint acceleration| + (sum |joint speed|)^2)
    (the site lies within ab + h of A), which tilts the reading by at most that over g; plus atan2's rounding
    (1e-15 rad)."""
    backend, clock = make(position=driven_angle(CFG, theta))
    clock.run(backend, 1.0)
    a = backend.antenna_acceleration()
    data = backend.plant.data
    reach = CFG.rocker_ab_length + CFG.coupler_length
    bound = reach * (sum(abs(data.qacc)) + sum(abs(data.qvel)) ** 2) / CFG.gravity + 1e-15
    assert abs(math.hypot(*a) - CFG.gravity) < bound * CFG.gravity + 1e-12
    measured = imu_theta(*a)
    assert isinstance(measured, float)
    assert abs(measured - backend.theta) <= bound, (measured, backend.theta, bound)
    assert abs(backend.theta - theta) < 1e-4  # where it was put (the microstep and the load's lag aside)


def test_the_servo_reports_its_motor_encoder_and_torque() -> None:
    """With the servo (no stepper) the drive reports the motor's angle through the reducer and its torque times
    the ratio: at rest the design load's input_torque (the plant's drive torque, 5.3e-6 relative, its how-to)."""
    backend, clock = make(drive=DriveModel())
    clock.run(backend, 1.0)
    position, velocity, effort = backend.read()
    assert position == backend.plant.motor_angle / RATIO + CFG.driven_joint_offset
    assert velocity is not None and abs(velocity) < 1e-9
    backend.plant.forward()
    core = pose(CFG, backend.theta).input_torque
    assert effort is not None and abs(effort - core) < 1e-5 * abs(core), (effort, core)
