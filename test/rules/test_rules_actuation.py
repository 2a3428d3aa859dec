"""The actuator modes' rules without ROS: what an antenna trajectory message becomes (or why it is refused, one
problem per case), the plans and setpoints of plain commands, and the running motion's state for replanning."""

from __future__ import annotations

import itertools
import math
import threading
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest
from support.trajectory_points import Duration, Point
from support.trajectory_points import antenna_points as pts

from fourbar_ros.config.antenna_config import default_config
from fourbar_ros.core.errors import FourBarError
from fourbar_ros.interface.stamps import seconds_to_ns
from fourbar_ros.interface.topics import ANTENNA_JOINT
from fourbar_ros.motion.limits import JointLimits, worst_violation
from fourbar_ros.motion.planner import PLAN_SHRINK, JointMotionState, Plan, driven_angles
from fourbar_ros.motion.splines import segment_extremes
from fourbar_ros.rules.antenna_trajectory import TrajectoryProblem, convert, problem_of
from fourbar_ros.rules.controller_contract import ContractRule
from fourbar_ros.rules.controller_motion import ControllerPoint, segment_coefficients
from fourbar_ros.rules.motion_plan import (
    Motion,
    driven_range,
    plan_command,
    planned_points,
    planned_setpoints,
    trajectory_setpoints,
)
from fourbar_ros.rules.outgoing import actuation_contract
from fourbar_ros.rules.serve import ActuationCounters, Drive, Outgoing, Refused, serve_antenna_trajectory, serve_command
from fourbar_ros.rules.takeover import ARRIVAL_MARGIN_S, Start, Unsettled, motion_start, rest_speed

CFG = default_config()
LIMITS = JointLimits.from_config(CFG)


def test_a_trajectory_converts_with_every_point_within_the_limits() -> None:
    out = convert(CFG, [ANTENNA_JOINT], pts([0.0, 1.0, 2.0], [0.0, 0.02, 0.03], [0.0, 0.015, 0.0]))
    d = out.trajectory
    assert d.velocities is not None and d.accelerations is None  # cubic in, cubic out
    assert worst_violation(d, LIMITS, CFG) is None
    assert out.bound <= CFG.trajectory_tolerance and not out.retimed
    kept = np.isin(d.times, [0.0, 1.0, 2.0])
    # The same vectorized solve on other arrays: equal, but under --ulp-jitter each call's transcendentals may be
    # moved by an ulp, which the solve's few operations carry to a few ulps of the angle (< 1 rad).
    np.testing.assert_allclose(d.positions[kept], driven_angles(CFG, np.array([0.0, 0.02, 0.03])), rtol=0,
                               atol=8 * np.finfo(float).eps)


CASES = {
    TrajectoryProblem.EMPTY: ([ANTENNA_JOINT], []),
    TrajectoryProblem.TOO_MANY_POINTS: ([ANTENNA_JOINT], pts([0.01 * i for i in range(CFG.max_trajectory_points + 1)],
                                                             [0.0] * (CFG.max_trajectory_points + 1))),
    TrajectoryProblem.WRONG_JOINT: (['tilt'], pts([0.0], [0.0])),
    TrajectoryProblem.NOT_FINITE: ([ANTENNA_JOINT], pts([0.0, 1.0], [0.0, math.inf])),
    TrajectoryProblem.TIME_NOT_INCREASING: ([ANTENNA_JOINT], pts([1.0, 0.5], [0.0, 0.01])),
    TrajectoryProblem.OUT_OF_REACH: ([ANTENNA_JOINT], pts([0.0, 1.0], [0.0, CFG.theta_min - 1e-6])),
    TrajectoryProblem.OVER_LIMITS: ([ANTENNA_JOINT], pts([0.0, 0.01], [CFG.theta_min, CFG.theta_max])),
    TrajectoryProblem.INVALID: ([ANTENNA_JOINT], [Point([0.0, 1.0])]),
}


@pytest.mark.parametrize('problem', list(CASES), ids=lambda p: p.value)
def test_each_bad_trajectory_is_one_line_of_its_problem(problem: TrajectoryProblem) -> None:
    names, points = CASES[problem]
    with pytest.raises(FourBarError) as err:
        convert(CFG, names, points)
    assert problem_of(err.value) is problem
    assert '\n' not in str(err.value)


def test_retime_policy_slows_a_fast_trajectory_down_instead() -> None:
    names, points = CASES[TrajectoryProblem.OVER_LIMITS]
    out = convert(replace(CFG, limit_policy='retime'), names, points)
    assert out.retimed and worst_violation(out.trajectory, LIMITS, CFG) is None
    # Times as a Duration carries them: whole nanoseconds.
    assert (np.round(out.trajectory.times * 1e9) / 1e9 == out.trajectory.times).all()


def test_counters_name_every_problem_and_contract_rule() -> None:
    keys = ActuationCounters().as_dict()
    assert all(f'trajectories_rejected_{p.value}' in keys for p in TrajectoryProblem)
    assert all(f'contract_refused_{r.value}' in keys for r in ContractRule)


def test_planned_points_and_setpoints_are_within_the_limits_and_reach_the_target() -> None:
    q = driven_angles(CFG, np.array([CFG.theta_min, 0.05]))
    plan = plan_command(CFG, JointMotionState(float(q[0])), 0.05)
    points = planned_points(CFG, plan)
    assert worst_violation(points, LIMITS, CFG) is None
    assert points.positions[-1] == pytest.approx(float(q[1]), abs=1e-12)
    stream = planned_setpoints(CFG, plan)
    assert (LIMITS.ratio * np.abs(np.diff(stream.positions)) / np.diff(stream.times)
            <= PLAN_SHRINK * LIMITS.motor_speed * (1 + 1e-12)).all()


def test_a_replan_from_the_running_motion_starts_at_its_state() -> None:
    q = driven_angles(CFG, np.array([CFG.theta_min]))
    plan = plan_command(CFG, JointMotionState(float(q[0])), CFG.theta_max)
    start_ns = 1_700_000_000_123_456_789  # a realistic clock: integer ns keep the elapsed time exact
    on_plan = Motion(start_ns, plan=plan)
    on_points = Motion(start_ns, trajectory=planned_points(CFG, plan))
    now = start_ns + 1_234_567_891
    a, b = on_plan.state_at(now), on_points.state_at(now)
    # The sent points' quintics reproduce the plan's cubic pieces (phase boundaries are points, times whole ns):
    # the two agree to rounding, far below the motion (1e-2 rad, rad/s).
    assert (b.position, b.velocity) == pytest.approx((a.position, a.velocity), abs=1e-9)
    assert b.acceleration == pytest.approx(a.acceleration, abs=1e-7)
    replan = plan_command(CFG, a, 0.0)
    assert replan.state_at(0.0) == a  # ruckig starts at exactly the state it is given
    assert on_plan.done(start_ns + round(plan.duration * 1e9) + 1)
    assert on_points.state_at(start_ns + 10**12) == JointMotionState(float(on_points.trajectory.positions[-1]))


def mid_motion() -> tuple[float, Plan, int, Motion, int]:
    """The motion from theta_min to theta_max, at half its duration: (start rad, plan, start ns, motion, now ns)."""
    q = float(driven_angles(CFG, np.array([CFG.theta_min]))[0])
    plan = plan_command(CFG, JointMotionState(q), CFG.theta_max)
    start_ns = 1_700_000_000_000_000_000
    return q, plan, start_ns, Motion(start_ns, plan=plan), start_ns + round(0.5 * plan.duration * 1e9)


def test_a_replan_leaves_the_running_motion_for_the_measured_state_beyond_the_tolerance() -> None:
    q, plan, start_ns, motion, now = mid_motion()
    model = motion.state_at(now)
    tol = CFG.replan_tolerance
    near = JointMotionState(model.position + 0.5 * tol, 0.001)
    assert motion_start(CFG, motion, near, now, 0.0) == Start(model, now)
    # Trajectory mode continues a running trajectory at its first point a lead or more ahead, and sends the points
    # before it (from the one at or before now) first: the controller stays on the very segments it follows.
    lead = ARRIVAL_MARGIN_S
    sent = Motion(start_ns, trajectory=planned_points(CFG, plan))
    start = motion_start(CFG, sent, near, now, lead)
    assert start is not None and start.before is not None and start.origin_ns == start_ns
    t = (now - start_ns) * 1e-9
    times = sent.trajectory.times  # type: ignore[union-attr]
    assert start.before.times[0] <= t < start.before.times[1] and start.at >= t + lead > start.before.times[-1]
    k = int(np.flatnonzero(times == start.at)[0])
    assert start.state == JointMotionState(float(sent.trajectory.positions[k]),  # type: ignore[union-attr]
                                           float(sent.trajectory.velocities[k]),  # type: ignore[union-attr, index]
                                           float(sent.trajectory.accelerations[k]))  # type: ignore[union-attr, index]
    # Held at the start (a refused trajectory, or a hold after a tolerance violation): the measured state.
    held = JointMotionState(q)
    # (in trajectory mode ARRIVAL_MARGIN_S ahead: the controller holds the drive until the motion's beginning)
    ahead = now + seconds_to_ns(ARRIVAL_MARGIN_S)
    assert motion_start(CFG, motion, held, now, lead) == Start(held, ahead, from_measured=True)
    assert motion_start(CFG, motion, held, now, 0.0) == Start(held, now, from_measured=True)
    assert motion_start(CFG, motion, None, now, 0.0) == Start(model, now)  # nothing measured: the motion
    # After the motion's end: a drive measured where it started is off it (the measured position, at rest).
    done = start_ns + round(plan.duration * 1e9) + 1
    assert motion_start(CFG, motion, held, done, lead) == Start(held, done + seconds_to_ns(ARRIVAL_MARGIN_S),
                                                                 from_measured=True)
    assert motion_start(CFG, motion, held, done, 0.0) == Start(held, done, from_measured=True)
    assert motion_start(CFG, None, None, now, lead) is None
    # The plan from the held state starts there: the drive is sent no step.
    assert plan_command(CFG, held, 0.0).state_at(0.0) == held


def test_a_late_measurement_is_compared_with_the_motion_when_measured() -> None:
    q, _, _, motion, now = mid_motion()
    late = round(0.6e9)  # a measurement 0.6 s old, as arrived under load
    then = motion.state_at(now - late)
    # The drive on its motion, measured 0.6 s ago: at mid-motion the motion has since moved on by more than the
    # tolerance, and the measurement was on it when taken: the motion goes on.
    assert abs(motion.state_at(now).position - then.position) > CFG.replan_tolerance
    on_it = JointMotionState(then.position, then.velocity)
    assert motion_start(CFG, motion, on_it, now, 0.0, now - late) == Start(motion.state_at(now), now)
    # Taken as measured now (no stamp, a stamp from the future), the same measurement is off the motion, moving:
    # nothing the node knows says where the drive is going, so nothing is planned from it.
    for stamp in (None, now + 1):
        assert isinstance(motion_start(CFG, motion, on_it, now, 0.0, stamp), Unsettled)
    # Off the motion when measured, moving: the same.
    off = JointMotionState(then.position - 2 * CFG.replan_tolerance, 0.01)
    assert isinstance(motion_start(CFG, motion, off, now, 0.0, now - late), Unsettled)
    # A held drive (at rest) is where it was measured, however late the measurement.
    held = JointMotionState(q)
    assert motion_start(CFG, motion, held, now, 0.0, now - late) == Start(held, now, from_measured=True)


def test_after_a_motions_end_a_late_measurement_on_it_starts_at_its_end_at_rest() -> None:
    """The controller holds a motion's end: a new command just after it, with the latest measurement taken while
    the drive still moved (late under load), starts from the end at rest in either mode, never from the measured
    speed carried on."""
    _, plan, start_ns, motion, _ = mid_motion()
    end_ns = start_ns + round(plan.duration * 1e9)
    end = motion.state_at(end_ns)
    assert end.velocity == 0.0 and end.acceleration == 0.0
    for lag_s, after_s in itertools.product((0.1, 0.3, 0.5), (0.01, 0.05)):
        now = end_ns + round(after_s * 1e9)
        stamp = now - round(lag_s * 1e9)
        measured = motion.state_at(stamp)
        assert measured.velocity != 0.0 or stamp >= end_ns
        for lead in (0.0, ARRIVAL_MARGIN_S):
            origin = now + seconds_to_ns(lead)
            assert motion_start(CFG, motion, measured, now, lead, stamp) == Start(JointMotionState(end.position),
                                                                                   origin), (lag_s, after_s, lead)


def test_forward_mode_after_a_motions_end_streams_on_from_the_held_setpoint() -> None:
    """Forward mode: the controller holds the last setpoint. A command 10 ms after the stream's end, the latest
    measurement taken 0.3 s before while the drive still moved: the new stream starts at the held setpoint (to the
    rounding of the plan's end against its last sample: 2 ulps), and its first step is within the speed limit over
    one period (a speed carried on from the measurement put it 8.4 mrad off, 14x the limit)."""
    fwd = actuation_contract(CFG, 'forward')
    q0 = float(driven_angles(CFG, np.array([CFG.theta_min]))[0])
    start_ns = 1_700_000_000_000_000_000
    first = serve_command(CFG, fwd, Drive(None, JointMotionState(q0), start_ns), 0.0, start_ns, ActuationCounters())
    assert isinstance(first, Outgoing) and first.setpoints is not None, first
    motion, held = first.motion, float(first.setpoints.positions[-1])
    now = start_ns + round(motion.duration * 1e9) + round(0.01e9)
    stamp = now - round(0.3e9)
    measured = motion.state_at(stamp)
    assert measured.velocity > 0.0
    out = serve_command(CFG, fwd, Drive(motion, measured, stamp), CFG.theta_max, now, ActuationCounters())
    assert isinstance(out, Outgoing) and out.setpoints is not None, out
    assert abs(float(out.setpoints.positions[0]) - held) <= 2 * math.ulp(held)
    step = abs(float(out.setpoints.positions[1]) - held) * CFG.control_rate
    assert step <= LIMITS.at_rocker(1), step


def test_a_measurement_from_before_the_running_motion_started_leaves_it_alone() -> None:
    """A motion planned from the measured state starts ARRIVAL_MARGIN_S after its command. A measurement stamped
    before that start shows the drive on the previous motion, e.g. still moving toward the far end. Taken on its
    own, it would look far off the new motion's first state. It is no news: the running motion goes on. From the
    start on, the same position is off the motion: moving, nothing is planned from it; at rest, from there."""
    q, _, _, _, _ = mid_motion()
    planned_at = 1_800_000_000_000_000_000
    motion = Motion(planned_at + seconds_to_ns(ARRIVAL_MARGIN_S), plan=plan_command(CFG, JointMotionState(q), 0.0))
    now = planned_at + round(0.5e9)
    before = JointMotionState(q + 3 * CFG.replan_tolerance, -0.05)  # on the previous motion, 1.4 s before now
    assert motion_start(CFG, motion, before, now, 0.0, now - round(1.4e9)) == Start(motion.state_at(now), now)
    # Older still (a stream that stalled, 100 s): no news either.
    assert motion_start(CFG, motion, before, now, 0.0, now - 100 * 10**9) == Start(motion.state_at(now), now)
    after = motion.start_ns + 1
    assert isinstance(motion_start(CFG, motion, before, now, 0.0, after), Unsettled)
    resting = JointMotionState(before.position)
    assert motion_start(CFG, motion, resting, now, 0.0, after) == Start(resting, now, from_measured=True)


def test_a_drive_measured_just_past_an_end_starts_at_the_end_at_rest_whatever_its_speed() -> None:
    lower, upper = driven_range(CFG)
    tol, rest = CFG.measured_range_tolerance, rest_speed(CFG)
    now = 10**9
    for end, outward in ((lower, -1.0), (upper, 1.0)):
        for past, v in itertools.product((math.ulp(end), 0.5 * tol, tol), (2e-4, -2e-4, 0.0, 0.05, -0.05)):
            measured = JointMotionState(end + outward * past, v)
            assert motion_start(CFG, None, measured, now, 0.0) == Start(JointMotionState(end), now, clamped=True), \
                (end, past, v)
        # Just inside: at rest where measured; moving faster than rest_speed, nothing is planned from it.
        inside = end - outward * 0.5 * tol
        assert motion_start(CFG, None, JointMotionState(inside, rest), now, 0.0) == Start(JointMotionState(inside),
                                                                                           now)
        assert isinstance(motion_start(CFG, None, JointMotionState(inside, 2 * rest), now, 0.0), Unsettled)
        # Further past than the tolerance: as measured (the plan refuses what cannot stop within the range).
        beyond = end + outward * 2 * tol
        assert motion_start(CFG, None, JointMotionState(beyond), now, 0.0) == Start(JointMotionState(beyond), now)


def test_the_rest_speed_keeps_a_lead_in_from_it_within_the_jerk_limit() -> None:
    """rest_speed: a quintic lead-in from speed v to rest, over half ARRIVAL_MARGIN_S, peaks at 36 v / d^2 of jerk,
    which at rest_speed is the rocker's jerk limit (the peak sampled on 20001 points lies below it by rounding)."""
    d = 0.5 * ARRIVAL_MARGIN_S
    a = ControllerPoint(0.0, 0.9, rest_speed(CFG), 0.0)
    b = ControllerPoint(d, 0.9, 0.0, 0.0)
    c = segment_coefficients(d, a, b)[None, :]
    jerk = float(segment_extremes(np.array([0.0, d]), c, 3)[0])
    assert jerk <= LIMITS.at_rocker(3) * (1 + 1e-12)
    assert jerk >= LIMITS.at_rocker(3) * (1 - 1e-9)


def test_forward_setpoints_of_a_trajectory_follow_the_controllers_spline() -> None:
    out = convert(CFG, [ANTENNA_JOINT], pts([0.0, 1.0, 2.0], [0.0, 0.02, 0.03], [0.0, 0.015, 0.0])).trajectory
    stream = trajectory_setpoints(CFG, out)
    assert stream.times[0] == 0.0 and stream.times[-1] == out.times[-1]
    assert np.allclose(np.diff(stream.times)[:-1], 1.0 / CFG.control_rate, rtol=0, atol=1e-12)
    # At the points' own times the spline is the point (s = 0 of a segment: its first coefficient, exactly).
    at_points = np.isin(stream.times, out.times)
    assert at_points.sum() == len(out)
    assert np.array_equal(stream.positions[at_points], out.positions)
    # Between points: the Motion's scalar evaluation of the same spline, within rounding (~1e-15 rad).
    motion = Motion(0, trajectory=out)
    for t, p in zip(stream.times[::17], stream.positions[::17], strict=True):
        assert p == pytest.approx(motion.state_at(round(t * 1e9)).position, abs=1e-13)


def test_setpoint_streams_are_held_to_every_limit_by_their_divided_differences() -> None:
    from fourbar_ros.motion.errors import LimitError
    from fourbar_ros.motion.planner import Setpoints
    from fourbar_ros.rules.motion_plan import checked_setpoints

    q = driven_angles(CFG, np.array([CFG.theta_min, CFG.theta_max]))
    plan = plan_command(CFG, JointMotionState(float(q[0])), CFG.theta_max)
    stream = planned_setpoints(CFG, plan)  # samples of a jerk-limited profile: within every limit
    assert checked_setpoints(CFG, stream) is stream
    # A step of acceleration at the limit's speed: speed within, acceleration over.
    h = 1.0 / CFG.control_rate
    t = np.arange(20) * h
    v = 0.9 * LIMITS.at_rocker(1)
    p = float(q[0]) + np.where(t < 0.1, 0.0, v * (t - 0.1))
    with pytest.raises(LimitError, match='motor acceleration'):
        checked_setpoints(CFG, Setpoints(t, p))
    # A parabola at 0.9 of the acceleration limit whose acceleration switches sign: jerk over, the rest within.
    a = 0.9 * LIMITS.at_rocker(2)
    s = np.arange(40) * h
    late = s - 0.2
    p2 = float(q[0]) + np.where(s < 0.2, 0.5 * a * s * s, 0.5 * a * 0.04 + a * 0.2 * late - 0.5 * a * late ** 2)
    with pytest.raises(LimitError, match='motor jerk'):
        checked_setpoints(CFG, Setpoints(s, p2))


def test_each_input_has_one_entry_returning_what_goes_out_or_a_refusal() -> None:
    """A served command and an antenna trajectory message, each through its entry: what goes out (a trajectory
    stamped with its start, ARRIVAL_MARGIN_S ahead from the measured state, a short one too: it cannot end before
    it arrives; setpoints in forward mode) or a refusal, counted."""
    jtc, fwd = actuation_contract(CFG, 'trajectory'), actuation_contract(CFG, 'forward')
    now, counters = 10**12, ActuationCounters()
    rest = Drive(measured=JointMotionState(float(driven_angles(CFG, np.array([0.0]))[0])), measured_ns=now)
    assert serve_command(CFG, jtc, Drive(), 0.03, now, counters).key == 'command no start'  # type: ignore[union-attr]
    far, near = (serve_command(CFG, jtc, rest, theta, now, counters) for theta in (0.03, 1e-5))
    ahead = now + seconds_to_ns(ARRIVAL_MARGIN_S)
    assert isinstance(far, Outgoing) and far.stamp_ns == far.motion.start_ns == ahead and far.setpoints is None
    assert isinstance(near, Outgoing) and near.stamp_ns == ahead and near.motion.duration <= ARRIVAL_MARGIN_S
    stream = serve_command(CFG, fwd, rest, 0.03, now, counters)
    assert isinstance(stream, Outgoing) and stream.setpoints is not None and not stream.points
    msg = SimpleNamespace(header=SimpleNamespace(stamp=Duration()), joint_names=[ANTENNA_JOINT],
                          points=pts([0.0, 1.0], [0.0, 0.02], [0.0, 0.0]))
    sent = serve_antenna_trajectory(CFG, jtc, Drive(), msg, now, counters)
    assert isinstance(sent, Outgoing) and sent.stamp_ns == 0 and sent.motion.start_ns == now
    msg.joint_names = ['elbow']
    assert serve_antenna_trajectory(CFG, jtc, Drive(), msg, now, counters) == Refused(
        'antenna trajectory wrong_joint', "antenna trajectory refused (wrong_joint): joint_names ['elbow']: an "
        f'antenna trajectory has the one joint {ANTENNA_JOINT!r}')
    assert (counters.commands_planned, counters.commands_not_planned, counters.trajectories_sent) == (3, 1, 3)
    assert counters.rejected[TrajectoryProblem.WRONG_JOINT] == 1


def test_a_retimed_antenna_trajectory_starting_where_the_running_motion_rests_goes_out() -> None:
    """A zero-stamped antenna trajectory (limit_policy retime) whose first point, at time 0, is where the running
    one rests at its departure, to the bit (both converted alike): the connecting segment may take any time above
    0, and its search ends (it once halved towards 0 for ever: the node's callback never returned). Run on a
    thread, judged by a deadline."""
    cfg = replace(CFG, limit_policy='retime')
    jtc, now, counters = actuation_contract(cfg, 'trajectory'), 10**12, ActuationCounters()
    q0 = float(driven_angles(cfg, np.array([0.0]))[0])
    rest = Drive(measured=JointMotionState(q0), measured_ns=now)

    def zero_stamped(*points: Point) -> SimpleNamespace:
        return SimpleNamespace(header=SimpleNamespace(stamp=Duration()), joint_names=[ANTENNA_JOINT],
                               points=list(points))
    short = serve_antenna_trajectory(cfg, jtc, rest, zero_stamped(
        Point([0.0], [0.0], [0.0]), Point([1e-5], [0.0], [0.0], time_from_start=Duration(0, 100_000_000))),
        now, counters)  # ends before the next one departs, ARRIVAL_MARGIN_S after it
    assert isinstance(short, Outgoing), short
    then = zero_stamped(Point([1e-5], [0.0], [0.0]), Point([0.01], [0.0], [0.0], time_from_start=Duration(1)))
    answer: list[Outgoing | Refused] = []
    worker = threading.Thread(target=lambda: answer.append(serve_antenna_trajectory(
        cfg, jtc, Drive(motion=short.motion, measured=JointMotionState(q0), measured_ns=now), then,
        now + seconds_to_ns(0.2), counters)), daemon=True)
    worker.start()
    worker.join(60.0)
    assert answer, 'serve_antenna_trajectory did not return within 60 s'
    out = answer[0]
    assert isinstance(out, Outgoing), out
    assert out.points[-1].positions[0] == pytest.approx(float(driven_angles(cfg, np.array([0.01]))[0]), abs=1e-12)
