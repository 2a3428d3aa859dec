"""The model of what joint_trajectory_controller (Jazzy) does with a trajectory over time, and what the node's
actuation makes of it: the whole motion from the measured state within the limits, replans that continue the
reference, an end at rest as the controller judges it, and the settings the model does not follow refused."""

from __future__ import annotations

import itertools
import math
import statistics
from dataclasses import replace

import numpy as np
import pytest
from support.trajectory_points import antenna_points

from fourbar_ros.config.antenna_config import ConfigError, config_from_values, default_config
from fourbar_ros.config.controllers import trajectory_controller
from fourbar_ros.interface.stamps import seconds_to_ns, to_ns
from fourbar_ros.interface.topics import ANTENNA_JOINT
from fourbar_ros.motion.limits import JointLimits
from fourbar_ros.motion.planner import JointMotionState, driven_angles
from fourbar_ros.motion.trajectory import DrivenTrajectory
from fourbar_ros.rules.antenna_trajectory import CannotReachError, TrajectoryProblem, problem_of
from fourbar_ros.rules.controller_contract import FLOAT_EPSILON, check_trajectory
from fourbar_ros.rules.controller_motion import (
    ControllerPoint,
    Reference,
    controller_reference,
    motion_settings_problem,
    segment_coefficients,
)
from fourbar_ros.rules.motion_plan import Motion, plan_command, planned_points
from fourbar_ros.rules.outgoing import (
    END_AHEAD_S,
    actuation_contract,
    held_to_arrival,
    outgoing_refusal,
    point_fields,
)
from fourbar_ros.rules.serve import ActuationCounters, Drive, Outgoing, antenna_motion, serve_command
from fourbar_ros.rules.takeover import ARRIVAL_MARGIN_S, Start, continued, motion_start, outgoing_stamp

CFG = default_config()
RETIME = config_from_values({'limit_policy': 'retime'})
LIMITS = JointLimits.from_config(CFG)
JTC = trajectory_controller('', CFG.trajectory_controller)
PERIOD = 0.01  # s: the controller manager's update_rate of 100 Hz
EPS = float(np.finfo(np.float64).eps)


def q_of(theta: float) -> float:
    return float(driven_angles(CFG, np.array([theta]))[0])


def controller_points(traj: DrivenTrajectory) -> list[ControllerPoint]:
    v, a = traj.velocities, traj.accelerations
    return [ControllerPoint(float(t), float(traj.positions[i]), None if v is None else float(v[i]),
                            None if a is None else float(a[i])) for i, t in enumerate(traj.times)]


def whole_motion(traj: DrivenTrajectory, stamp: float | None, takeover: float, measured: JointMotionState,
                 ) -> Reference:
    """The reference the controller follows for ``traj`` (times from its stamp, s relative to the node's now; None:
    a zero stamp) taken over at ``takeover`` s from ``measured``."""
    return controller_reference(True, controller_points(traj), stamp, takeover, measured.position,
                                measured.velocity, PERIOD)


def worst_ratio(ref: Reference) -> float:
    """The largest of the reference's motor speed, acceleration and jerk over their limits (the speed alone for
    linear segments)."""
    return max(LIMITS.ratio * value / LIMITS.motor(order) for order, value in ref.extremes().items())


# ----------------------------------------------------------------------------- the model, against the controller

def _jtc_cubic(p0: float, v0: float, p1: float, v1: float, T: float, t: float) -> float:
    """``interpolate_between_points``'s cubic, as the controller writes it (coefficients over T's powers)."""
    c2 = (-3.0 * p0 + 3.0 * p1 - 2.0 * v0 * T - v1 * T) / T**2
    c3 = (2.0 * p0 - 2.0 * p1 + v0 * T + v1 * T) / T**3
    return p0 + v0 * t + c2 * t**2 + c3 * t**3


def _jtc_quintic(p0: float, v0: float, a0: float, p1: float, v1: float, a1: float, T: float, t: float) -> float:
    c3 = (-20.0 * p0 + 20.0 * p1 - 3.0 * a0 * T**2 + a1 * T**2 - 12.0 * v0 * T - 8.0 * v1 * T) / (2.0 * T**3)
    c4 = (30.0 * p0 - 30.0 * p1 + 3.0 * a0 * T**2 - 2.0 * a1 * T**2 + 16.0 * v0 * T + 14.0 * v1 * T) / (2.0 * T**4)
    c5 = (-12.0 * p0 + 12.0 * p1 - a0 * T**2 + a1 * T**2 - 6.0 * v0 * T - 6.0 * v1 * T) / (2.0 * T**5)
    return p0 + v0 * t + 0.5 * a0 * t**2 + c3 * t**3 + c4 * t**4 + c5 * t**5


def test_segments_are_the_controllers_polynomials() -> None:
    """The model's power-basis segments (in s = t/T) give what the controller's formulas (in t) give: the same
    polynomial, so within the rounding of the two evaluations (a few ulps of the terms summed)."""
    rng = np.random.default_rng(3)
    for _ in range(300):
        p0, p1, v0, v1, a0, a1 = rng.uniform(-1.0, 1.0, 6)
        T = float(rng.uniform(0.005, 3.0))
        cubic = segment_coefficients(T, ControllerPoint(0.0, p0, v0), ControllerPoint(T, p1, v1))
        quintic = segment_coefficients(T, ControllerPoint(0.0, p0, v0, a0), ControllerPoint(T, p1, v1, a1))
        linear = segment_coefficients(T, ControllerPoint(0.0, p0), ControllerPoint(T, p1, v1))
        scale = (1.0 + abs(v0) + abs(v1)) * max(T, 1.0) + (abs(a0) + abs(a1)) * max(T, 1.0) ** 2
        for t in np.linspace(0.0, T, 7):
            s = t / T
            powers = s ** np.arange(6)
            assert abs(cubic @ powers - _jtc_cubic(p0, v0, p1, v1, T, t)) <= 64 * EPS * scale
            assert abs(quintic @ powers - _jtc_quintic(p0, v0, a0, p1, v1, a1, T, t)) <= 256 * EPS * scale
            assert abs(linear @ powers - (p0 + (p1 - p0) * s)) <= 4 * EPS * (abs(p0) + abs(p1))


def test_the_lead_in_starts_at_the_measured_state_with_zero_filled_derivatives() -> None:
    first = [ControllerPoint(0.5, 0.3, 0.1, 0.2)]
    # A velocity state interface: the measured velocity; the acceleration zero-filled; quintic.
    ref = controller_reference(True, first, None, 2.0, 0.1, 0.05, PERIOD)
    assert ref.lead_in and ref.degrees == (5,) and ref.knots.tolist() == [2.0, 2.5]
    assert ref.sample(2.0) == pytest.approx((0.1, 0.05, 0.0), abs=4 * EPS)
    assert ref.sample(2.5 - 1e-12) == pytest.approx((0.3, 0.1, 0.2), abs=1e-9)
    assert ref.sample(2.5) == (0.3, 0.1, 0.0)  # from the last point on: held, as given
    # None: the velocity zero-filled too (the drive may be moving: the controller does not know).
    ref = controller_reference(False, first, None, 2.0, 0.1, 0.05, PERIOD)
    assert ref.sample(2.0) == pytest.approx((0.1, 0.0, 0.0), abs=4 * EPS)
    # A first point of positions only: a linear lead-in whatever the state has.
    ref = controller_reference(True, [ControllerPoint(0.5, 0.3)], None, 2.0, 0.1, 0.05, PERIOD)
    assert ref.degrees == (1,) and ref.sample(2.25)[:2] == pytest.approx((0.2, 0.4), abs=4 * EPS)


def test_stamps_anchor_the_points_but_the_lead_in_starts_at_the_takeover() -> None:
    pts = [ControllerPoint(0.1, 1.0, 0.0, 0.0), ControllerPoint(0.3, 2.0, 0.0, 0.0)]
    # Stamped 0.5 s after the takeover: the lead-in runs from the takeover to stamp + 0.1 s, it does not wait.
    ref = controller_reference(True, pts, 0.5, 0.0, 0.0, 0.0, PERIOD)
    assert ref.lead_in and ref.knots.tolist() == [0.0, 0.6, 0.8]
    assert 0.0 < ref.sample(0.3)[0] < 1.0
    # Stamped in the past so that the first point is due: no lead-in, the segment holding the takeover goes on.
    ref = controller_reference(True, pts, -0.2, 0.0, 5.0, 0.0, PERIOD)
    assert not ref.lead_in and ref.knots.tolist() == pytest.approx([-0.1, 0.1], abs=1e-15)
    assert ref.sample(0.0)[0] == pytest.approx(1.5, abs=1e-12)  # not the measured 5.0
    # A zero stamp: the origin is the takeover; a first point at time 0 is due there (no lead-in).
    ref = controller_reference(True, [ControllerPoint(0.0, 1.0, 0.0, 0.0), *pts[1:]], None, 3.0, 5.0, 0.0, PERIOD)
    assert not ref.lead_in and ref.sample(3.0)[0] == 1.0


def test_velocity_only_points_are_integrated_and_the_end_is_held() -> None:
    pts = [ControllerPoint(1.0, None, 0.2), ControllerPoint(2.0, None, 0.0)]
    ref = controller_reference(True, pts, None, 0.0, 1.0, 0.0, PERIOD)
    # Trapezoids: 1.0 + (0 + 0.2) / 2 * 1 s, then + (0.2 + 0) / 2 * 1 s.
    assert ref.sample(1.0)[0] == pytest.approx(1.1, abs=1e-15)
    assert ref.sample(2.0)[0] == pytest.approx(1.2, abs=1e-15) and ref.hold == pytest.approx((1.2, 0.0))
    assert ref.sample(50.0) == (ref.hold[0], 0.0, 0.0)


def test_each_update_commands_the_reference_one_period_ahead() -> None:
    ref = controller_reference(True, [ControllerPoint(1.0, 1.0, 0.0, 0.0)], None, 0.0, 0.0, 0.0, PERIOD)
    assert ref.command(0.3) == ref.sample(0.3 + PERIOD)[0] != ref.sample(0.3)[0]


@pytest.mark.parametrize('key, value', [('interpolation_method', 'none'), ('interpolate_from_desired_state', True),
                                        ('open_loop_control', True), ('speed_scaling', True), ('cmd_timeout', 1.0)])
def test_settings_that_change_the_motion_are_refused_naming_the_key(key: str, value: object) -> None:
    settings = replace(JTC, **{key: value})
    problem = motion_settings_problem(settings)
    assert problem is not None and key.split('_scaling', maxsplit=1)[0] in problem
    assert motion_settings_problem(JTC) is None


@pytest.mark.parametrize(('commands', 'states', 'checked'), [
    (('position',), ('position', 'velocity'), False), (('position', 'effort'), ('position',), False),
    (('position', 'effort'), ('position', 'velocity'), True),
    (('position', 'velocity'), ('position', 'velocity'), True),
])
def test_the_stopped_velocity_tolerance_is_refused_only_where_the_controller_checks_it(
        commands: tuple[str, ...], states: tuple[str, ...], checked: bool) -> None:
    # The controller computes a velocity error (and checks it at the goal) with a velocity state interface and a
    # velocity or effort command interface; elsewhere another tolerance changes nothing.
    settings = replace(JTC, command_interfaces=commands, state_interfaces=states, stopped_velocity_tolerance=0.05)
    problem = motion_settings_problem(settings)
    assert (problem is not None and 'stopped_velocity_tolerance' in problem) is checked, problem
    assert motion_settings_problem(replace(settings, stopped_velocity_tolerance=0.01)) is None


def test_a_controllers_file_with_interpolation_none_stops_the_node_at_startup(tmp_path: object) -> None:
    from pathlib import Path

    from fourbar_ros.config.controllers import controllers_path
    text = controllers_path('').read_text(encoding='utf-8').replace('interpolation_method: splines',
                                                                     'interpolation_method: none')
    path = Path(str(tmp_path)) / 'controllers.yaml'
    path.write_text(text, encoding='utf-8')
    cfg = config_from_values({'mode': 'trajectory', 'controllers_file': str(path)})
    with pytest.raises(ConfigError, match='interpolation_method'):
        actuation_contract(cfg)


# ----------------------------------------------------------------------------- what the node sends

def test_a_one_point_trajectory_is_given_the_time_its_whole_motion_needs() -> None:
    """"theta 0.1 rad at 50 ms" from rest at 0: the controller would interpolate from the drive to the point in
    50 ms (tens of times the speed limit). Under retime it is connected from the measured state and delayed until its
    whole motion, as the controller will play it from the measured state, is within every limit; under reject it is
    refused under its own problem."""
    rest = JointMotionState(q_of(0.0))
    start = motion_start(RETIME, None, rest, 0, ARRIVAL_MARGIN_S)
    assert start == Start(rest, seconds_to_ns(ARRIVAL_MARGIN_S))  # the controller holds the drive until then
    points = antenna_points([0.05], [0.1], [0.0])
    as_is = controller_reference(True, [ControllerPoint(0.05, q_of(0.1), 0.0)], None, PERIOD, rest.position, 0.0,
                                 PERIOD)
    assert worst_ratio(as_is) > 10.0  # what the controller would have done with the message as given
    out = antenna_motion(RETIME, False, [ANTENNA_JOINT], points, 0, 0, start)
    assert out.retimed and out.trajectory.positions[-1] == q_of(0.1)
    stamp = None if out.stamp_ns == 0 else 0.0
    for takeover in (1e-4, PERIOD, 3 * PERIOD):  # wherever the controller takes it over
        ref = whole_motion(out.trajectory, stamp, takeover, rest)
        assert worst_ratio(ref) <= 1.0, takeover
    with pytest.raises(CannotReachError) as refused:
        antenna_motion(CFG, False, [ANTENNA_JOINT], points, 0, 0, Start(rest, 0))
    assert problem_of(refused.value) is TrajectoryProblem.CANNOT_REACH_IN_TIME


def test_a_stamped_trajectory_that_cannot_be_reached_in_time_is_refused_under_either_policy() -> None:
    rest = JointMotionState(q_of(0.0))
    points = antenna_points([0.0, 1.0], [0.1, 0.1], [0.0, 0.0])
    for cfg in (CFG, RETIME):
        with pytest.raises(CannotReachError):
            antenna_motion(cfg, False, [ANTENNA_JOINT], points, 10**9 // 20, 0, Start(rest, 0))
    # Stamped far enough ahead, the same points are reached in time and nothing is retimed.
    out = antenna_motion(CFG, False, [ANTENNA_JOINT], points, 30 * 10**9, 0, Start(rest, 0))
    assert not out.retimed and worst_ratio(whole_motion(out.trajectory, 0.0, PERIOD, rest)) <= 1.0


def test_a_one_point_trajectory_as_the_motion_being_followed_has_a_state_at_every_time() -> None:
    """A motion holding a single point (a trajectory sent without a connection) answers state_at before, at and
    after its point, as the controller holds it."""
    one = antenna_motion(CFG, False, [ANTENNA_JOINT], antenna_points([0.5], [0.05]), 0, 0).trajectory
    assert len(one) == 1
    motion = Motion(10**9, trajectory=one)
    for t in (0, 10**9, 10**9 + 10**8, 10**10):
        assert motion.state_at(t).position == float(one.positions[0])


def test_an_end_at_rest_to_rounding_is_accepted_and_sent_as_exactly_zero() -> None:
    """A sine profile's last velocity is 5e-18 rad/s: the controller takes |v| <= FLT_EPSILON as at rest."""
    t = np.linspace(0.0, 2.0, 21)
    theta = 0.05 * np.sin(0.5 * math.pi * t / 2.0)
    theta_dot = 0.05 * 0.25 * math.pi * np.cos(0.5 * math.pi * t / 2.0)
    assert 0.0 < abs(theta_dot[-1]) < 1e-16
    out = antenna_motion(CFG, False, [ANTENNA_JOINT], antenna_points(list(t), list(theta), list(theta_dot)),
                                   0, 0)
    assert out.trajectory.velocities is not None and out.trajectory.velocities[-1] == 0.0
    fields = point_fields(out.trajectory, False)
    assert check_trajectory(JTC, [CFG.driven_joint], fields, 0, 0) is None
    moving = list(theta_dot)
    moving[-1] = 1e-3
    with pytest.raises(Exception, match='above float epsilon'):
        antenna_motion(CFG, False, [ANTENNA_JOINT], antenna_points(list(t), list(theta), moving), 0, 0)
    assert float(np.finfo(np.float32).eps) == FLOAT_EPSILON


def test_a_measured_start_just_outside_the_range_starts_at_its_end() -> None:
    """An encoder rounds to whole counts: a drive parked at an end of the range reads up to half a count beyond it
    (3.1e-6 rad at the joint for 4096 counts through 500:1). The motion starts at that end, counted; further out
    than measured_range_tolerance, it starts where measured (and the planner refuses what leaves the range)."""
    lower, upper = sorted(driven_angles(CFG, np.array([CFG.theta_min, CFG.theta_max])))
    count = 2.0 * math.pi / (4096 * 500)
    for end, outward in ((float(lower), -1.0), (float(upper), 1.0)):
        read = end + outward * 0.5 * count
        start = motion_start(CFG, None, JointMotionState(read, outward * 1e-5), 0, 0.0)
        assert start is not None and start.clamped and start.state == JointMotionState(end, 0.0)
        plan = plan_command(CFG, start.state, 0.0)  # planned: not refused as leaving the range
        assert plan.state_at(0.0).position == end
        far = motion_start(CFG, None, JointMotionState(end + outward * 2 * CFG.measured_range_tolerance), 0, 0.0)
        assert far is not None and not far.clamped


# ----------------------------------------------------------------------------- replans

#: Takeover delays (s) after the node's now: planning, delivery and up to one update period, from 0.3 ms to just
#: under ARRIVAL_MARGIN_S (a loaded 2-core machine took 9 to 54 ms, up to 170 ms in rare stalls).
DELAYS = (0.0003, 0.001, 0.003, 0.006, 0.01, 0.013, 0.03, 0.06, 0.099, 0.17, 0.249)


def test_a_replan_continues_the_reference_the_controller_follows() -> None:
    """Mid-motion, a new command's trajectory (stamped at the node's now, its first point the running motion's
    state now, the new plan from ARRIVAL_MARGIN_S on) is taken over by the controller at a delay: the new reference
    there equals the one being followed, in position, velocity and acceleration (the controller continues on the
    segment holding the takeover: no lead-in from the measured state)."""
    q0 = q_of(CFG.theta_min)
    plan = plan_command(CFG, JointMotionState(q0), CFG.theta_max)
    first = planned_points(CFG, plan)
    assert outgoing_stamp(CFG, Start(JointMotionState(q0), 10**12), first, 10**12) == 10**12  # at the node's now
    followed = controller_reference(True, controller_points(first), 0.0, 0.004, q0, 0.0, PERIOD)
    motion = Motion(0, trajectory=first)
    offsets = []
    for now_s in np.linspace(0.5, 0.8 * plan.duration, 7):
        now = round(now_s * 1e9)
        at_now = motion.state_at(now)
        start = motion_start(CFG, motion, at_now, now, ARRIVAL_MARGIN_S)
        assert start is not None and start.before is not None
        second = continued(start, planned_points(CFG, plan_command(CFG, start.state, 0.0)))
        assert start.origin_ns == 0 and outgoing_stamp(CFG, start, second, now) == 0  # the running one's stamp
        for delay in DELAYS:
            takeover = now_s + delay
            new = controller_reference(True, controller_points(second), 0.0, takeover, 0.0, 0.0, PERIOD)
            assert not new.lead_in and worst_ratio(new) <= 1.0 + 1e-9
            old_p, old_v, old_a = followed.sample(takeover)
            new_p, new_v, new_a = new.sample(takeover)
            speed = abs(old_v)
            offsets.append(abs(new_p - old_p) / speed)  # s of motion at the current speed
            # Velocity and acceleration continuous: within the rounding of the quintics through the samples
            # (relative 1e-9 of the limits).
            assert abs(new_v - old_v) <= 1e-9 * LIMITS.at_rocker(1), (now_s, delay)
            assert abs(new_a - old_a) <= 1e-6 * LIMITS.at_rocker(2), (now_s, delay)
    assert statistics.median(offsets) <= 0.002  # at most 2 ms of motion (it is ~0: the same reference)
    assert max(offsets) <= 1e-6, max(offsets)


def test_a_command_in_the_last_margin_of_a_motion_continues_it_held_until_it_arrives() -> None:
    """A command arriving when the running motion ends within ARRIVAL_MARGIN_S: the new trajectory continues the
    running one in its time base (the running one's stamp) to its end, holds it there at rest, and departs
    ARRIVAL_MARGIN_S after now; taken over at any delay under the margin, the reference goes on as followed (a plan
    from the running motion's state now, taken over late, would find it moved on: a step)."""
    origin = 10**12
    q0 = q_of(CFG.theta_min)
    first = planned_points(CFG, plan_command(CFG, JointMotionState(q0), CFG.theta_max))
    end = float(first.times[-1])
    followed = controller_reference(True, controller_points(first), 0.0, 0.004, q0, 0.0, PERIOD)
    contract = actuation_contract(CFG, 'trajectory')
    held = 0
    for before_end, step in itertools.product((0.01, 0.1, 0.24), (1e-3, 1e-6, 0.0)):
        now = origin + seconds_to_ns(end - before_end)
        drive = Drive(Motion(origin, trajectory=first))
        out = serve_command(CFG, contract, drive, CFG.theta_max - step, now, ActuationCounters())
        assert isinstance(out, Outgoing), out
        second = out.motion.trajectory
        assert out.stamp_ns == origin and second is not None
        elapsed = (now - origin) * 1e-9
        assert float(second.times[-1]) >= elapsed + ARRIVAL_MARGIN_S - 1e-9, (before_end, step)
        held += bool(np.any(np.abs(second.times - (elapsed + ARRIVAL_MARGIN_S)) <= 1e-9))  # the departure
        for delay in DELAYS:
            takeover = (now - origin) * 1e-9 + delay
            new = controller_reference(True, controller_points(second), 0.0, takeover, 0.0, 0.0, PERIOD)
            assert not new.lead_in
            (old_p, old_v, old_a), (new_p, new_v, new_a) = followed.sample(takeover), new.sample(takeover)
            # The same segments, or the new plan from the running one's last point at rest: within the rounding of
            # the quintics through the samples (relative 1e-9 of the limits; 1e-6 for the acceleration).
            assert abs(new_p - old_p) <= 1e-12, (before_end, delay)
            assert abs(new_v - old_v) <= 1e-9 * LIMITS.at_rocker(1), (before_end, delay)
            assert abs(new_a - old_a) <= 1e-6 * LIMITS.at_rocker(2), (before_end, delay, old_a, new_a)
    assert held == 9, held  # every one departs from the end, held


def test_a_motion_ending_soon_goes_out_held_to_a_late_arrival() -> None:
    """A command that does not move the drive on, in the last margin of the running motion: the motion ends
    ARRIVAL_MARGIN_S after now, so a delivery later than that (seen under load) would find it ended and the controller
    would refuse it. It goes out with one more point holding the end at rest END_AHEAD_S after now: the contract
    takes it at every delivery delay up to then, and the reference is the motion's, then its end."""
    origin = 10**12
    q0 = q_of(CFG.theta_min)
    first = planned_points(CFG, plan_command(CFG, JointMotionState(q0), CFG.theta_max))
    now = origin + seconds_to_ns(float(first.times[-1]) - 0.1)
    contract = actuation_contract(CFG, 'trajectory')
    out = serve_command(CFG, contract, Drive(Motion(origin, trajectory=first)), CFG.theta_max, now, ActuationCounters())
    assert isinstance(out, Outgoing) and out.stamp_ns == origin, out
    model = out.motion.trajectory
    assert model is not None
    sent = out.points
    assert len(sent) == len(model) + 1 and sent[-1].positions == sent[-2].positions, sent[-2:]
    assert to_ns(sent[-1].time_from_start) == now + seconds_to_ns(END_AHEAD_S) - origin
    bare = sent[:-1]
    elapsed = (now - origin) * 1e-9
    wire = [ControllerPoint(to_ns(p.time_from_start) * 1e-9, p.positions[0], p.velocities[0], p.accelerations[0])
            for p in sent]
    for delay in (0.0, 0.1, ARRIVAL_MARGIN_S + 0.05, 0.6, END_AHEAD_S - 0.01):
        arrival = now + seconds_to_ns(delay)
        assert outgoing_refusal(contract, CFG.driven_joint, sent, origin, arrival) is None, delay
        # Without the held point a delivery later than the motion's end is refused.
        late = outgoing_refusal(contract, CFG.driven_joint, bare, origin, arrival)
        assert (late is None) == (delay <= ARRIVAL_MARGIN_S), (delay, late)
        # The same quintics through the same points, then one between two equal points at rest: the reference
        # from the held points is the motion's and then its end, to the rounding of a quintic's evaluation.
        takeover = elapsed + delay
        held = controller_reference(True, wire, 0.0, takeover, 0.0, 0.0, PERIOD)
        planned = controller_reference(True, wire[:-1], 0.0, takeover, 0.0, 0.0, PERIOD)
        for t in np.linspace(takeover, elapsed + END_AHEAD_S + 0.5, 200):
            assert held.sample(float(t))[0] == pytest.approx(planned.sample(float(t))[0], abs=1e-12), (delay, t)
    # A zero stamp starts on arrival, and an end still moving is not held: both go out as planned.
    assert held_to_arrival(bare, 0, now) == bare
    moving = [*bare[:-1], bare[-1]._replace(velocities=[0.01])]
    assert held_to_arrival(moving, origin, now) == moving


def test_a_stamped_trajectory_ending_before_the_takeover_is_refused() -> None:
    """A stamped trajectory ending within ARRIVAL_MARGIN_S of the node's now could end before the controller takes
    it over (the controller refuses a trajectory whose end is past on arrival): refused as ends_in_past."""
    now = 10**12
    points = antenna_points([0.0, 0.5], [0.0, 0.0], [0.0, 0.0])
    soon = now - 500_000_000 + round(0.5 * ARRIVAL_MARGIN_S * 1e9)  # ends half the margin from now
    with pytest.raises(Exception) as refused:
        antenna_motion(CFG, False, [ANTENNA_JOINT], points, soon, now,
                                 Start(JointMotionState(q_of(0.0)), now))
    assert problem_of(refused.value) is TrajectoryProblem.ENDS_IN_PAST  # type: ignore[arg-type]
    later = now - 500_000_000 + round(2.0 * ARRIVAL_MARGIN_S * 1e9)
    out = antenna_motion(CFG, False, [ANTENNA_JOINT], points, later, now,
                                   Start(JointMotionState(q_of(0.0)), now))
    assert out.stamp_ns == now
