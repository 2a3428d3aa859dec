"""Trajectory conversion and replanning cost: ``python -m benchmarks.trajectory_bench [--quick]`` (JSON).

- conversion: ``to_driven`` on a 10,000-point antenna trajectory (positions, velocities, accelerations in; efforts
  too out) against the numpy floor of the transcendental calls it needs, each once on the same 10,000 values: the
  position solve's (``benchmarks.sweep.floor_ufuncs``), then sin(gamma + delta), sin(delta - theta),
  sin(gamma + theta), cos(gamma + delta), cos(delta - theta) (the rates and second derivatives). CPU-time medians of
  interleaved rounds. Target: ratio <= 2.
- whole motion: serving a 10,000-point antenna trajectory message the way the node does, joined to a measured
  start (``antenna_motion`` with a ``Start``: the connecting segment's check included), against
  ``convert`` of the same message alone; CPU-time medians of interleaved rounds. Target: the join adds at most 1x
  the conversion's own time (ratio <= 2).
- replan continuity: mid-motion replans as the node sends them (the running trajectory's own points first), taken
  over by the controller model 0.3 to 150 ms after the node's now (0 within ARRIVAL_MARGIN_S, the plan's departure;
  a step beyond it); the new reference's offset from the one being followed at the takeover, in position (as
  seconds of motion at the current speed), velocity and acceleration (relative to their limits); median and worst.
- replanning: one ``plan_motion`` call (ruckig) from a mid-motion state, median microseconds, beside sampling that
  plan every 0.05 s; compare with the node's per-command callback (``benchmarks.node_bench``, ~150 us).
"""

from __future__ import annotations

import statistics
import time
from typing import Any

import numpy as np

from benchmarks import options, print_json
from benchmarks.cases import TURNANTENNA
from benchmarks.sweep import floor_inputs, floor_ufuncs
from benchmarks.timing import Case, interleaved
from fourbar_ros.config.antenna_config import default_config
from fourbar_ros.interface.joint_trajectory import DurationFields, PointFields
from fourbar_ros.interface.stamps import from_ns, seconds_to_ns
from fourbar_ros.interface.topics import ANTENNA_JOINT
from fourbar_ros.motion.limits import JointLimits
from fourbar_ros.motion.planner import JointMotionState, driven_angles, plan_motion, trajectory_points
from fourbar_ros.motion.trajectory import antenna_trajectory, to_driven
from fourbar_ros.rules.antenna_trajectory import convert
from fourbar_ros.rules.controller_motion import ControllerPoint, controller_reference
from fourbar_ros.rules.motion_plan import Motion, plan_command, planned_points
from fourbar_ros.rules.serve import antenna_motion
from fourbar_ros.rules.takeover import ARRIVAL_MARGIN_S, Start, continued, motion_start

POINTS = 10_000


def conversion(rounds: int) -> dict[str, Any]:
    """CPU seconds of the conversion and of its transcendental floor, and their ratio."""
    cfg = default_config()
    t = np.linspace(0.0, 20.0, POINTS)
    mid, amp = 0.5 * (cfg.theta_min + cfg.theta_max), 0.5 * (cfg.theta_max - cfg.theta_min)
    w = 2.0 * np.pi / 20.0
    traj = antenna_trajectory(cfg, t, mid + amp * np.sin(w * t), amp * w * np.cos(w * t),
                              -amp * w * w * np.sin(w * t))
    gamma, delta = (np.asarray(a) for a in cfg.linkage.rocker_angles(traj.theta, cfg.branch))
    theta = traj.theta
    solve_inputs = floor_inputs(TURNANTENNA, theta)
    x, u, v = gamma + delta, delta - theta, gamma + theta

    def floor() -> object:
        return (floor_ufuncs(solve_inputs), np.sin(x), np.sin(u), np.sin(v), np.cos(x), np.cos(u))

    times = interleaved([Case('conversion', lambda: to_driven(cfg, traj), 1), Case('floor', floor, 1)], rounds)
    conv, fl = times['conversion'][0], times['floor'][0]
    return {'points': POINTS, 'conversion_s': conv, 'floor_s': fl, 'ratio': conv / fl, 'ratio_target': 2.0,
            'conversion_wall_s': times['conversion'][1], 'floor_wall_s': times['floor'][1]}


def whole_motion(rounds: int) -> dict[str, Any]:
    """CPU seconds of serving a 10,000-point antenna trajectory joined to a measured start, and of converting it
    alone, and their ratio."""
    cfg = default_config()
    t = np.linspace(0.5, 20.5, POINTS)  # a half-cosine sweep over most of the tilt range, at rest at both ends
    low, span, w = cfg.theta_min + 0.01, cfg.theta_max - cfg.theta_min - 0.02, np.pi / 20.0
    theta, theta_dot = low + 0.5 * span * (1.0 - np.cos(w * (t - 0.5))), 0.5 * span * w * np.sin(w * (t - 0.5))
    mid = float(theta[0])
    points = [PointFields([float(theta[i])], [float(theta_dot[i])], [], [], DurationFields(*from_ns(seconds_to_ns(ti))))
              for i, ti in enumerate(t.tolist())]
    start = Start(JointMotionState(float(driven_angles(cfg, np.array([mid]))[0])), 0)
    names = [ANTENNA_JOINT]
    times = interleaved([Case('serve', lambda: antenna_motion(cfg, False, names, points, 0, 0, start), 1),
                         Case('convert', lambda: convert(cfg, names, points, False), 1)], rounds)
    serve, conv = times['serve'][0], times['convert'][0]
    return {'points': POINTS, 'serve_s': serve, 'convert_s': conv, 'ratio': serve / conv, 'ratio_target': 2.0}


def replan_continuity(replans: int) -> dict[str, Any]:
    """Offsets of the new reference from the followed one at the controller's takeover, per takeover delay."""
    cfg = default_config()
    limits = JointLimits.from_config(cfg)
    q0 = float(driven_angles(cfg, np.array([cfg.theta_min]))[0])
    plan = plan_command(cfg, JointMotionState(q0), cfg.theta_max)
    first = planned_points(cfg, plan)

    def reference(traj: Any, takeover: float) -> Any:
        pts = [ControllerPoint(float(t), float(traj.positions[i]), float(traj.velocities[i]),
                               float(traj.accelerations[i])) for i, t in enumerate(traj.times)]
        return controller_reference(True, pts, 0.0, takeover, 0.0, 0.0, 1.0 / cfg.control_rate)

    followed = reference(first, 0.0)
    motion = Motion(0, trajectory=first)
    out: dict[str, Any] = {'lead_s': ARRIVAL_MARGIN_S}
    for delay in (0.0003, 0.003, 0.013, 0.040, 0.099, 0.150):  # the last beyond ARRIVAL_MARGIN_S
        pos, vel, acc = [], [], []
        for now_s in np.linspace(0.3, 0.9 * plan.duration, replans):
            now = seconds_to_ns(float(now_s))
            start = motion_start(cfg, motion, motion.state_at(now), now, ARRIVAL_MARGIN_S)
            assert start is not None
            second = continued(start, planned_points(cfg, plan_command(cfg, start.state, 0.0)))
            t = float(now_s) + delay
            (p0, v0, a0), (p1, v1, a1) = followed.sample(t), reference(second, t).sample(t)
            pos.append(abs(p1 - p0) / max(abs(v0), 1e-12))
            vel.append(abs(v1 - v0) / limits.at_rocker(1))
            acc.append(abs(a1 - a0) / limits.at_rocker(2))
        out[f'takeover_{delay * 1e3:g}ms'] = {
            'position_offset_s_of_motion_median': statistics.median(pos), 'position_offset_s_of_motion_max': max(pos),
            'velocity_offset_of_limit_max': max(vel), 'acceleration_offset_of_limit_max': max(acc)}
    return out


def replanning(calls: int) -> dict[str, Any]:
    """Median microseconds of one plan_motion call from a moving state, and of sampling that plan."""
    cfg = default_config()
    limits = JointLimits.from_config(cfg)
    q = driven_angles(cfg, np.array([cfg.theta_min, cfg.theta_max]))
    start = JointMotionState(float(q[0]) + 0.01, 0.5 * limits.at_rocker(1), 0.1 * limits.at_rocker(2))
    plan_s, sample_s = [], []
    for i in range(calls):
        target = float(q[1]) - 1e-4 * (i % 7)  # distinct targets: no result can be reused
        c0 = time.process_time()
        plan = plan_motion(start, target, limits)
        c1 = time.process_time()
        trajectory_points(cfg, limits, plan, 0.05)
        c2 = time.process_time()
        plan_s.append(c1 - c0)
        sample_s.append(c2 - c1)
    return {'calls': calls, 'plan_median_us': 1e6 * statistics.median(plan_s),
            'points_at_0.05s_median_us': 1e6 * statistics.median(sample_s), 'plan_duration_s': plan.duration,
            'compare_with': 'node per-command callback, ~150 us (benchmarks/node_bench.py)'}


def run(quick: bool) -> dict[str, Any]:
    """For ``python -m benchmarks.run``."""
    return {'conversion': conversion(7 if quick else 21), 'whole_motion': whole_motion(5 if quick else 15),
            'replan_continuity': replan_continuity(7 if quick else 25),
            'replanning': replanning(200 if quick else 2000)}


if __name__ == '__main__':
    raise SystemExit(print_json(run(options(None, __doc__).quick)))
