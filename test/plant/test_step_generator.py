"""The plant's step generator (pure): within its speed and acceleration limits at every timestep whatever the goals
and their timing; on a stream of goals arriving 4 to 16 ms apart it moves without a dead stop; it comes to rest on
the last goal, exactly, without passing it after an isolated goal."""

from __future__ import annotations

import math
import random

from hypothesis import given, settings
from hypothesis import strategies as st

from fourbar_ros.config.antenna_config import default_config
from fourbar_ros.plant.step_generator import ACCELERATION_FACTOR, StepGenerator

CFG = default_config()
SPEED = CFG.motor_speed_limit  # rad/s at the motor
ACCELERATION = ACCELERATION_FACTOR * CFG.motor_acceleration_limit  # rad/s^2 at the motor
PERIOD = 1.0 / CFG.control_rate  # s
DT = 1e-3  # s, the plant's timestep
MICROSTEP = 2.0 * math.pi / 50 / 4 / 16  # rad at the motor
#: Rounding room for the limits: the speed and the change are sums of a few numbers below 100 rad/s.
ROOM = 1e-12


def generator(position: float = 0.0) -> StepGenerator:
    return StepGenerator(position, SPEED, ACCELERATION, PERIOD, MICROSTEP)


def run(gen: StepGenerator, goals: list[tuple[float, float]], until: float) -> list[tuple[float, float, float]]:
    """Step from 0 s to ``until`` s, setting each (time s, goal rad) as its time comes: (t, position, speed) after
    each timestep; the limits are asserted at every one."""
    out, pending, t, before = [], sorted(goals, key=lambda g: g[0]), 0.0, gen.speed
    for k in range(round(until / DT)):
        t = k * DT
        while pending and pending[0][0] <= t:
            gen.set_goal(pending.pop(0)[1], t)
        gen.step(t, DT)
        assert abs(gen.speed) <= SPEED + ROOM, f'at {t:.3f} s: speed {gen.speed!r} rad/s over {SPEED!r}'
        assert abs(gen.speed - before) <= ACCELERATION * DT + ROOM, \
            f'at {t:.3f} s: speed {before!r} -> {gen.speed!r} rad/s in one {DT} s step, over {ACCELERATION!r} rad/s^2'
        before = gen.speed
        out.append((t + DT, gen.position, gen.speed))
    return out


def test_an_isolated_goal_is_reached_exactly_without_passing_it() -> None:
    # 3 rad at the motor: the generator speeds up to its limit and brakes onto the goal (its stopping speed bound).
    # The field is commanded in whole microsteps: its nearest one never passes the goal.
    gen = generator()
    path = run(gen, [(0.0, 3.0)], 2.0)
    farthest = max(p for _, p, _ in path)
    assert round(farthest / MICROSTEP) <= round(3.0 / MICROSTEP), f'passed the goal 3.0 rad: at {farthest!r} rad'
    assert gen.at_rest and gen.position == 3.0, (gen.position, gen.speed)


def test_a_stream_of_unevenly_arriving_goals_moves_without_a_dead_stop() -> None:
    # A cruise at 20 rad/s sampled every 10 ms, delivered 4 to 16 ms apart (in order): once up to speed the field
    # never drops below half of it (a generator that reached each goal within a period and waited stopped dead
    # whenever the next one came late); it ends on the last goal.
    rnd, speed, arrive, goals = random.Random(3), 20.0, 0.0, []
    for k in range(100):
        arrive = max(arrive, k * PERIOD + rnd.uniform(0.0, 0.006))
        goals.append((arrive, speed * k * PERIOD))
    gen = generator()
    path = run(gen, goals, 2.0)
    cruise = [v for t, _, v in path if 0.2 <= t <= 0.9]
    assert min(cruise) > 0.5 * speed, f'the field slowed to {min(cruise)!r} rad/s in the cruise at {speed} rad/s'
    assert gen.at_rest and gen.position == goals[-1][1]


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.sampled_from([0.0, 0.004, 0.010, 0.016, 0.030, 0.5]),
                          st.one_of(st.sampled_from([-100.0, 0.0, 100.0]), st.floats(-100.0, 100.0))),
                min_size=1, max_size=12))
def test_any_goals_stay_within_the_limits_and_end_on_the_last(steps: list[tuple[float, float]]) -> None:
    # Goals (rad at the motor) at gaps from none to 0.5 s: the limits hold at every step (asserted in run), and the
    # field rests exactly on the last goal in the time a stop from full speed and the longest move at full speed take.
    t, goals = 0.0, []
    for gap, goal in steps:
        t += gap
        goals.append((t, goal))
    settle = SPEED / ACCELERATION + 200.0 / SPEED + 1.0
    gen = generator()
    run(gen, goals, t + settle)
    assert gen.at_rest and gen.position == goals[-1][1], (gen.position, gen.speed, goals[-1])


def test_stop_holds_where_the_field_is() -> None:
    gen = generator()
    run(gen, [(0.0, 3.0)], 0.1)
    here = gen.position
    gen.stop()
    assert gen.at_rest and gen.position == here
    gen.step(0.1, DT)
    assert gen.position == here
