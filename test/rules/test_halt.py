"""The halt's rules without ROS: the halt state (``rules.halt.Halt``), the time-optimal stop (``motion.planner.
plan_stop``) and the brake served from a running motion (``rules.serve.serve_brake``) in trajectory and forward
mode."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fourbar_ros.config.antenna_config import default_config
from fourbar_ros.interface.stamps import seconds_to_ns
from fourbar_ros.motion.errors import TrajectoryError
from fourbar_ros.motion.limits import JointLimits, worst_violation
from fourbar_ros.motion.planner import PLAN_SHRINKS, JointMotionState, driven_angles, plan_motion, plan_stop
from fourbar_ros.rules.halt import HALTED_LINE, Halt
from fourbar_ros.rules.motion_plan import Motion, checked_setpoints, plan_command
from fourbar_ros.rules.outgoing import actuation_contract
from fourbar_ros.rules.serve import ActuationCounters, Drive, Outgoing, Refused, serve_brake, serve_command
from fourbar_ros.rules.takeover import ARRIVAL_MARGIN_S

CFG = default_config()
LIMITS = JointLimits.from_config(CFG)
NS = 1_000_000_000
START_NS = 1_700_000_000_000_000_000


def q_of(theta: float) -> float:
    return float(driven_angles(CFG, np.array([theta]))[0])


# --------------------------------------------------------------------------- the halt state

def test_a_halt_is_taken_once_counted_and_cleared_only_by_resume() -> None:
    h = Halt()
    assert h.values(0)[0] == ('halted', 'no') and h.since(0) == '' and h.resume() == ''
    assert h.resumes == 0  # nothing to clear: not counted
    assert h.halt('by the ~/halt service', 2 * NS)
    assert not h.halt('by the ~/halt topic', 3 * NS)  # already halted: the first one stands
    assert (h.why, h.halts, h.repeated) == ('by the ~/halt service', 1, 1)
    assert h.since(4_500_000_000) == 'by the ~/halt service, 2.500 s ago'
    line = h.dropped_line('command theta = 0.1 rad')
    assert line == f'command theta = 0.1 rad dropped: {HALTED_LINE} (halted by the ~/halt service)'
    assert HALTED_LINE == 'halted: call ~/resume' and '\n' not in line
    assert dict(h.values(4_500_000_000)) == {'halted': 'yes: by the ~/halt service, 2.500 s ago', 'halts': '1',
                                              'halts_repeated': '1', 'halt_resumes': '0', 'halt_dropped': '1'}
    assert h.resume() == 'by the ~/halt service' and h.resumes == 1 and not h.why
    assert h.halt('by the ~/halt topic', 5 * NS) and h.halts == 2


# --------------------------------------------------------------------------- the time-optimal stop

#: States within the limits, the way a running motion passes them: cruising, accelerating, braking, either way.
STATES = [JointMotionState(0.85, 0.06, 0.0), JointMotionState(0.85, 0.03, 0.19), JointMotionState(0.85, -0.06, 0.1),
          JointMotionState(0.85, 0.05, -0.19), JointMotionState(0.85, -0.001, -0.15), JointMotionState(0.85)]


@pytest.mark.parametrize('start', STATES, ids=str)
def test_the_stop_comes_to_rest_no_later_than_any_motion_to_rest_there(start: JointMotionState) -> None:
    """The stop ends at rest (to ruckig's rounding) at its stopping position; a position plan to that same position
    (which must end at rest too) takes no less time: the stop is time-optimal. Within the limits' margins: the
    profile's speed, acceleration and jerk at every phase boundary and between."""
    stop = plan_stop(start, LIMITS)
    assert stop.state_at(0.0) == start
    end = stop.state_at(stop.duration)
    assert abs(end.velocity) <= 1e-15 and abs(end.acceleration) <= 1e-15, end
    if stop.duration > 0.0:
        there = plan_motion(start, end.position, LIMITS)
        assert there.duration >= stop.duration * (1.0 - 1e-9), (there.duration, stop.duration)
    t = np.union1d(np.linspace(0.0, stop.duration, 401), stop.switch_times())
    _, v, a = stop.sample(t)
    # every start lies within the planner's margins, so the stop keeps them (to ruckig's ~1e-13 relative rounding)
    assert np.max(np.abs(v)) <= PLAN_SHRINKS[0] * LIMITS.at_rocker(1) * (1 + 1e-12)
    assert np.max(np.abs(a)) <= PLAN_SHRINKS[1] * LIMITS.at_rocker(2) * (1 + 1e-12)
    lo, hi = stop.position_range()  # never ruckig's velocity-interface extrema (their minimum reads 0.0)
    assert lo <= min(start.position, end.position) and hi >= max(start.position, end.position)
    # none of these turns back (the speed never changes sign on the way): the stop spans start to end, no more
    assert hi - lo <= abs(end.position - start.position) + 1e-12, (lo, hi, start, end)


def test_a_stop_from_rest_is_no_motion_and_a_non_finite_state_is_refused() -> None:
    assert plan_stop(JointMotionState(0.85), LIMITS).duration == 0.0
    with pytest.raises(TrajectoryError, match='non-finite'):
        plan_stop(JointMotionState(0.85, math.nan), LIMITS)


# --------------------------------------------------------------------------- the brake from a running motion

def running(mode: str) -> tuple[Outgoing, int]:
    """A served command from theta_min to theta_max (a motion of seconds) in ``mode``, and a time (ns) when it
    cruises."""
    contract = actuation_contract(CFG, mode)
    out = serve_command(CFG, contract, Drive(None, JointMotionState(q_of(CFG.theta_min)), START_NS), CFG.theta_max,
                        START_NS, ActuationCounters())
    assert isinstance(out, Outgoing), out
    return out, out.motion.start_ns + seconds_to_ns(0.4 * out.motion.duration)


def test_in_trajectory_mode_the_brake_repeats_the_running_points_to_the_takeover_and_stops_short() -> None:
    first, now = running('trajectory')
    motion = first.motion
    traj = motion.trajectory
    assert traj is not None
    counters = ActuationCounters()
    measured = motion.state_at(now)
    out = serve_brake(CFG, actuation_contract(CFG, 'trajectory'), Drive(motion, measured, now), now, counters)
    assert isinstance(out, Outgoing) and out.stamp_ns == first.stamp_ns == motion.start_ns, out
    brake = out.motion.trajectory
    assert brake is not None and counters.brakes_planned == 1 and counters.commands_planned == 0
    # The running trajectory's points, bit for bit, from the one the now falls in up to the first at least
    # ARRIVAL_MARGIN_S ahead: the departure; from there the stop.
    t_now = (now - motion.start_ns) / NS
    k0 = int(np.searchsorted(traj.times, t_now, side='right')) - 1
    k1 = int(np.searchsorted(traj.times, t_now + ARRIVAL_MARGIN_S, side='left'))
    n = k1 - k0 + 1
    assert np.array_equal(brake.times[:n], traj.times[k0:k1 + 1])
    assert np.array_equal(brake.positions[:n], traj.positions[k0:k1 + 1])
    assert brake.velocities is not None and traj.velocities is not None
    assert np.array_equal(brake.velocities[:n], traj.velocities[k0:k1 + 1])
    depart = JointMotionState(float(traj.positions[k1]), float(traj.velocities[k1]), float(traj.accelerations[k1]))
    stop = plan_stop(depart, LIMITS)
    q_rest, q_target = float(brake.positions[-1]), q_of(CFG.theta_max)
    assert q_rest == pytest.approx(stop.state_at(stop.duration).position, abs=1e-12)
    assert depart.position < q_rest < q_target  # on the way, short of the target
    assert brake.times[-1] == pytest.approx(traj.times[k1] + stop.duration, abs=1e-3)  # the points' own spacing
    assert worst_violation(brake, LIMITS, CFG) is None  # the points and the quintics between them


def test_in_forward_mode_the_brake_streams_on_the_running_grid_from_its_next_setpoint() -> None:
    first, now = running('forward')
    motion = first.motion
    assert first.setpoints is not None
    period_ns = seconds_to_ns(1.0 / CFG.control_rate)
    published_ns = motion.start_ns + (now - motion.start_ns) // period_ns * period_ns  # the latest due at now
    counters = ActuationCounters()
    out = serve_brake(CFG, actuation_contract(CFG, 'forward'), Drive(motion, motion.state_at(now), now, published_ns),
                      now, counters)
    assert isinstance(out, Outgoing) and out.setpoints is not None, out
    assert out.motion.start_ns == published_ns + period_ns  # the running stream's next setpoint, on its grid
    head = first.setpoints.positions[: (published_ns - motion.start_ns) // period_ns + 1]
    joined = np.concatenate([head, out.setpoints.positions])
    times = np.arange(joined.size) / CFG.control_rate
    checked_setpoints(CFG, type(out.setpoints)(times, joined))  # the joined stream within every limit
    q_rest = float(out.setpoints.positions[-1])
    assert float(head[-1]) < q_rest < q_of(CFG.theta_max)
    assert counters.brakes_planned == 1


def test_no_brake_without_a_state_to_brake_from() -> None:
    traj = actuation_contract(CFG, 'trajectory')
    none = serve_brake(CFG, traj, Drive(), START_NS, ActuationCounters())
    assert isinstance(none, Refused) and none.key == 'brake no start', none
    # forward mode, measured moving with no stream running: the node has no setpoint of its own to brake from, and
    # none is started from a state the controller does not hold (it holds its last setpoint)
    forward = actuation_contract(CFG, 'forward')
    moving = JointMotionState(q_of(0.0), 0.05)
    out = serve_brake(CFG, forward, Drive(None, moving, START_NS, None), START_NS, ActuationCounters())
    assert isinstance(out, Refused) and out.key == 'brake unsettled' and 'measured moving' in out.line, out


def test_in_forward_mode_the_stream_is_braked_on_its_grid_however_far_the_drive_lags_it() -> None:
    # The drive measured moving 10 replan tolerances behind the running stream (a loaded machine): the controller
    # passes on each setpoint as it comes, so the brake continues the stream from its next setpoint, as on it.
    first, now = running('forward')
    period_ns = seconds_to_ns(1.0 / CFG.control_rate)
    published_ns = first.motion.start_ns + (now - first.motion.start_ns) // period_ns * period_ns
    on = first.motion.state_at(now)
    braked = []
    for measured in (on, JointMotionState(on.position - 10 * CFG.replan_tolerance, on.velocity)):
        out = serve_brake(CFG, actuation_contract(CFG, 'forward'), Drive(first.motion, measured, now, published_ns),
                          now, ActuationCounters())
        assert isinstance(out, Outgoing) and out.setpoints is not None, out
        braked.append((out.motion.start_ns, out.setpoints.positions.tolist()))
    assert braked[0] == braked[1]


def test_with_no_measurement_the_brake_starts_from_the_running_motion() -> None:
    first, now = running('trajectory')
    counters = ActuationCounters()
    out = serve_brake(CFG, actuation_contract(CFG, 'trajectory'), Drive(first.motion), now, counters)
    assert isinstance(out, Outgoing) and out.stamp_ns == first.motion.start_ns, out
    assert (counters.brakes_planned, counters.brakes_from_measured) == (1, 0), counters


@pytest.mark.parametrize('age_ms', [0, 10, -5], ids=['now', '10ms_old', 'stamped_ahead'])
def test_off_every_motion_the_brake_starts_from_the_measured_state_brought_to_its_start(age_ms: int) -> None:
    """Measured moving well off the running trajectory (a faulty count, another sender): the brake is the
    time-optimal stop from the measured position and velocity at acceleration 0, brought at that velocity from the
    measurement's stamp (one ahead of now: now) to ARRIVAL_MARGIN_S after now, the trajectory's time 0 and stamp;
    short of the old target, within the limits."""
    first, now = running('trajectory')
    motion = first.motion
    measured_ns = now - age_ms * 1_000_000
    on = motion.state_at(measured_ns)
    assert on.velocity > 0.9 * PLAN_SHRINKS[0] * LIMITS.at_rocker(1), on  # cruising
    measured = JointMotionState(on.position - 3 * CFG.replan_tolerance, on.velocity)  # behind, as after a slip
    counters = ActuationCounters()
    out = serve_brake(CFG, actuation_contract(CFG, 'trajectory'), Drive(motion, measured, measured_ns), now, counters)
    assert isinstance(out, Outgoing), out
    assert (counters.brakes_planned, counters.brakes_from_measured) == (1, 1), counters
    origin = now + seconds_to_ns(ARRIVAL_MARGIN_S)
    assert out.stamp_ns == out.motion.start_ns == origin, (out.stamp_ns, origin)
    brake = out.motion.trajectory
    assert brake is not None and brake.velocities is not None and brake.accelerations is not None
    at = min(measured_ns, now)
    q0 = measured.position + measured.velocity * (origin - at) * 1e-9
    assert brake.times[0] == 0.0
    assert brake.positions[0] == pytest.approx(q0, abs=1e-12), (brake.positions[0], q0)
    assert brake.velocities[0] == pytest.approx(measured.velocity, abs=1e-12)
    assert abs(brake.accelerations[0]) <= 1e-12, brake.accelerations[0]
    stop = plan_stop(JointMotionState(q0, measured.velocity, 0.0), LIMITS)
    q_rest = float(brake.positions[-1])
    assert q_rest == pytest.approx(stop.state_at(stop.duration).position, abs=1e-12)
    assert abs(brake.velocities[-1]) <= 1e-9 and abs(brake.accelerations[-1]) <= 1e-9, brake
    assert q0 < q_rest < q_of(CFG.theta_max)  # on the way, short of the old target
    assert worst_violation(brake, LIMITS, CFG) is None  # the points and the quintics between them


def test_plan_command_and_the_stop_agree_where_the_command_brakes_hardest() -> None:
    """At the start of the command's own braking the stop is no longer than the rest of the command: the command
    ends in no less time than the fastest stop from its state."""
    q0 = q_of(CFG.theta_min)
    plan = plan_command(CFG, JointMotionState(q0), CFG.theta_max)
    motion = Motion(START_NS, plan=plan)
    for frac in (0.2, 0.5, 0.8, 0.95):
        t_ns = START_NS + seconds_to_ns(frac * plan.duration)
        stop = plan_stop(motion.state_at(t_ns), LIMITS)
        assert stop.duration <= plan.duration - frac * plan.duration + 1e-9, (frac, stop.duration)
        assert stop.state_at(stop.duration).position <= q_of(CFG.theta_max) + 1e-12


def test_with_no_motion_a_drive_measured_moving_brakes_from_its_measured_state() -> None:
    """Another sender's motion, or one the node forgot (the controller switched): the stop from the measured state,
    ARRIVAL_MARGIN_S ahead."""
    measured = JointMotionState(0.85, -0.05)
    counters = ActuationCounters()
    out = serve_brake(CFG, actuation_contract(CFG, 'trajectory'), Drive(None, measured, START_NS), START_NS, counters)
    assert isinstance(out, Outgoing) and out.motion.trajectory is not None, out
    assert out.stamp_ns == START_NS + seconds_to_ns(ARRIVAL_MARGIN_S) and counters.brakes_from_measured == 1
    q0 = 0.85 - 0.05 * ARRIVAL_MARGIN_S
    stop = plan_stop(JointMotionState(q0, -0.05), LIMITS)
    assert float(out.motion.trajectory.positions[-1]) == pytest.approx(stop.state_at(stop.duration).position,
                                                                       abs=1e-12)
    assert worst_violation(out.motion.trajectory, LIMITS, CFG) is None


def test_after_the_motions_end_a_drive_settling_on_it_is_held_there() -> None:
    """The motion ended and the drive is measured still moving within replan_tolerance of its end (landing): the
    brake starts on the motion, at rest at its end: a hold there (no stop of its own to plan)."""
    first, _ = running('trajectory')
    end_ns = first.motion.start_ns + seconds_to_ns(first.motion.duration) + NS
    q_end = first.motion.state_at(end_ns).position
    measured = JointMotionState(q_end - 0.5 * CFG.replan_tolerance, 0.01)
    out = serve_brake(CFG, actuation_contract(CFG, 'trajectory'), Drive(first.motion, measured, end_ns), end_ns,
                      ActuationCounters())
    assert isinstance(out, Outgoing) and out.motion.trajectory is not None, out
    traj = out.motion.trajectory
    assert traj.velocities is not None
    assert np.all(traj.positions == q_end) and np.all(traj.velocities == 0.0), traj


def test_a_stop_from_the_measured_state_that_would_leave_the_range_is_refused_in_one_line() -> None:
    """Measured moving at full speed toward the upper end, closer than its stopping distance: no brake (the
    controller's running motion, which ends within the range, goes on), one line saying where the stop would go."""
    first, now = running('trajectory')
    upper = q_of(CFG.theta_max)
    measured = JointMotionState(upper - 0.005, PLAN_SHRINKS[0] * LIMITS.at_rocker(1))
    counters = ActuationCounters()
    out = serve_brake(CFG, actuation_contract(CFG, 'trajectory'), Drive(first.motion, measured, now), now, counters)
    assert isinstance(out, Refused) and out.key == 'brake beyond the range', out
    assert 'beyond [' in out.line and '\n' not in out.line, out.line
    assert (counters.brakes_planned, counters.brakes_from_measured) == (0, 0), counters
