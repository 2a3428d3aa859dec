"""The drive bridge's rules against the simulated backend: examples, then random sequences of commands, readings,
ticks and faults (hypothesis), checking what reaches the backend."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from fourbar_ros.config.antenna_config import default_config
from fourbar_ros.drive.backend import DriveBackend, SimulatedBackend
from fourbar_ros.drive.rules import DriveLimits, DriveRules
from fourbar_ros.motion.limits import JointLimits, range_slack
from fourbar_ros.rules.motion_plan import driven_range

CFG = default_config()
LIMITS = DriveLimits.from_config(CFG, watchdog_timeout=0.5)
LOW, HIGH = driven_range(CFG)
SPEED = JointLimits.from_config(CFG).at_rocker(1)
PERIOD = 1.0 / CFG.control_rate
MID = 0.5 * (LOW + HIGH)


class Clock:
    """A clock the test steps (s)."""

    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def test_limits_are_the_configurations() -> None:
    slack = range_slack(LOW, HIGH)
    assert (LIMITS.lower, LIMITS.upper) == (LOW - slack, HIGH + slack)
    assert LIMITS.max_step == SPEED * 3.0 / CFG.control_rate


def test_the_simulated_backend_is_a_drive_backend() -> None:
    assert isinstance(SimulatedBackend(MID, SPEED), DriveBackend)


def test_nothing_is_written_before_the_first_reading() -> None:
    rules = DriveRules(LIMITS)
    assert rules.on_command(0.0, MID) is None
    assert rules.counters.held_before_reading == 1 and rules.status == 'no reading yet'


def test_a_command_within_a_step_is_written_and_a_far_one_clamped() -> None:
    rules = DriveRules(LIMITS)
    rules.on_reading(0.0, (MID, None, None))
    assert rules.on_command(0.0, MID + 0.5 * LIMITS.max_step) == MID + 0.5 * LIMITS.max_step
    assert rules.on_command(0.0, HIGH) == MID + LIMITS.max_step
    assert rules.counters.clamped == 1 and rules.status == 'following commands'


@pytest.mark.parametrize('bad', [math.nan, math.inf, None, HIGH + 0.01, LOW - 0.01])
def test_a_bad_command_holds_the_moving_drive_at_its_reading(bad: float | None) -> None:
    rules = DriveRules(LIMITS)
    rules.on_reading(0.0, (MID, None, None))
    rules.on_command(0.0, MID + 0.001)
    rules.on_reading(0.01, (MID + 0.0005, None, None))
    assert rules.on_command(0.01, bad) == MID + 0.0005
    assert rules.on_command(0.02, bad) is None  # held already: written once
    assert rules.status.startswith('held: ')
    assert rules.counters.held_not_finite + rules.counters.held_out_of_range == 2


def test_the_watchdog_holds_a_moving_drive_and_says_so() -> None:
    rules = DriveRules(LIMITS)
    rules.on_reading(0.0, (MID, None, None))
    assert rules.on_tick(1.0) is None  # never moved: nothing to hold
    rules.on_reading(1.0, (MID, None, None))
    rules.on_command(1.0, MID + 0.001)
    assert rules.on_tick(1.5) is None
    rules.on_reading(1.5, (MID + 0.001, None, None))
    assert rules.on_tick(1.51) == MID + 0.001
    assert rules.status == 'held: no command for 0.5 s' and rules.counters.watchdog_holds == 1


def test_velocity_is_differenced_when_the_backend_has_none_and_never_nan() -> None:
    rules = DriveRules(LIMITS)
    first = rules.on_reading(0.0, (MID, None, None))
    assert first is not None and first.velocity == 0.0
    second = rules.on_reading(0.5, (MID + 0.01, math.nan, math.nan))
    assert second is not None and second.velocity == pytest.approx(0.02) and second.effort is None
    same_time = rules.on_reading(0.5, (MID + 0.02, None, 1.5))
    assert same_time is not None and same_time.velocity == 0.0 and same_time.effort == 1.5
    assert rules.on_reading(0.6, (math.nan, 0.0, 0.0)) is None and rules.counters.bad_readings == 1


def test_a_drive_far_outside_the_range_is_held() -> None:
    rules = DriveRules(LIMITS)
    rules.on_reading(0.0, (HIGH + 10 * LIMITS.max_step, None, None))
    assert rules.on_command(0.0, HIGH) is None and rules.counters.held_far_outside == 1
    rules.on_reading(0.0, (HIGH + 0.5 * LIMITS.max_step, None, None))
    assert rules.on_command(0.0, MID) == HIGH + 0.5 * LIMITS.max_step - LIMITS.max_step


COMMAND = st.one_of(st.floats(LOW - 0.05, HIGH + 0.05), st.sampled_from([math.nan, math.inf, -math.inf, None]))
STEP = st.one_of(
    st.tuples(st.just('command'), COMMAND),
    st.tuples(st.just('read'), st.none()),
    st.tuples(st.just('tick'), st.none()),
    st.tuples(st.just('wait'), st.floats(0.0, 1.0)),
    st.tuples(st.just('fault'), st.sampled_from(['nan', 'stuck', 'slip', 'clear'])),
)


@given(start=st.floats(LOW - 0.01, HIGH + 0.01), steps=st.lists(STEP, max_size=60),
       velocity=st.booleans())
def test_a_random_sequence_never_writes_a_bad_target(start: float, steps: list[tuple[str, object]],
                                                     velocity: bool) -> None:
    clock = Clock()
    drive = SimulatedBackend(start, SPEED, clock, reports_velocity=velocity)
    drive.enable()
    rules = DriveRules(LIMITS)
    last_command: float | None = None  # when the last target was written
    for kind, arg in steps:
        before = len(drive.writes)
        target: float | None = None
        report = rules.report
        if kind == 'command':
            target = rules.on_command(clock.now, arg)  # type: ignore[arg-type]
        elif kind == 'read':
            out = rules.on_reading(clock.now, drive.read())
            assert out is None or math.isfinite(out.velocity)
        elif kind == 'tick':
            moving = rules.moving
            target = rules.on_tick(clock.now)
            if moving and last_command is not None and clock.now - last_command > LIMITS.watchdog_timeout:
                assert not rules.moving and rules.held, 'the watchdog let a drive without commands move on'
        elif kind == 'wait':
            clock.now += float(arg)  # type: ignore[arg-type]
        else:
            drive.nan_reads, drive.stuck = arg == 'nan', arg == 'stuck'
            drive.slip = 0.01 if arg == 'slip' else 0.0
        if target is not None:
            assert report is not None, 'written before the first reading'
            assert LIMITS.in_range(target), f'{target} out of range'
            here = report.position
            assert here - LIMITS.max_step <= target <= here + LIMITS.max_step, 'faster than the speed limit'
            if kind == 'command':
                last_command = clock.now
            else:
                assert target == here  # a hold is the reading
            drive.write(target)
        assert len(drive.writes) - before == (target is not None)
