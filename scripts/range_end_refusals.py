"""Count refusals of motions that end exactly at an end of the tilt range, through the node's own entries.

    python scripts/range_end_refusals.py [N] [SEED]

For N seeded random starts (default 300, seed 0) and each end (theta_min, theta_max): a command from the drive
at rest at a random driven position within the range (``serve_command``, forward and trajectory mode), and a
two-point antenna trajectory from a random theta to the end, at rest at both points, over 12 s, of each spline
kind (``serve_antenna_trajectory``, both modes). Every such target is reachable: each refusal is one too many.
Last, plans from a start moving at exactly the rocker's speed limit (rad/s) towards the end and away from it
(``plan_command``, then its points or setpoints): refusals for the limits, refusals for not stopping within the
range (right), and plans accepted whose path (2001 samples) passes the range by more than ``range_slack`` (wrong).
Prints one line per case: refusals out of N, and the first refusal's line.
"""

from __future__ import annotations

import sys
from types import SimpleNamespace

import numpy as np

from fourbar_ros.config.antenna_config import default_config
from fourbar_ros.core.errors import UnreachableError
from fourbar_ros.interface.stamps import from_ns, seconds_to_ns
from fourbar_ros.interface.topics import ANTENNA_JOINT
from fourbar_ros.motion.errors import LimitError
from fourbar_ros.motion.limits import JointLimits, range_slack
from fourbar_ros.motion.planner import JointMotionState
from fourbar_ros.rules.motion_plan import driven_range, plan_command, planned_points, planned_setpoints
from fourbar_ros.rules.outgoing import actuation_contract
from fourbar_ros.rules.serve import ActuationCounters, Drive, Refused, serve_antenna_trajectory, serve_command


def _point(t: float, theta: float, kind: int) -> SimpleNamespace:
    sec, nanosec = from_ns(seconds_to_ns(t))
    rates = [0.0] if kind >= 3 else []
    return SimpleNamespace(positions=[theta], velocities=rates, accelerations=[0.0] if kind == 5 else [],
                           time_from_start=SimpleNamespace(sec=sec, nanosec=nanosec))


def main(n: int = 300, seed: int = 0) -> None:
    cfg = default_config()
    lower, upper = driven_range(cfg)
    rng = np.random.default_rng(seed)
    rests = rng.uniform(lower, upper, n)
    starts = rng.uniform(cfg.theta_min, cfg.theta_max, n)
    now = 10**12
    for mode in ('forward', 'trajectory'):
        contract = actuation_contract(cfg, mode)
        for name, end in (('theta_min', cfg.theta_min), ('theta_max', cfg.theta_max)):
            cases = {'command': [serve_command(cfg, contract, Drive(measured=JointMotionState(float(q)),
                                                                          measured_ns=now),
                                               end, now, ActuationCounters()) for q in rests]}
            for kind, label in ((1, 'linear'), (3, 'cubic'), (5, 'quintic')):
                msgs = (SimpleNamespace(header=SimpleNamespace(stamp=SimpleNamespace(sec=0, nanosec=0)),
                                        joint_names=[ANTENNA_JOINT],
                                        points=[_point(0.0, float(th), kind), _point(12.0, end, kind)])
                        for th in starts)
                cases[f'{label} trajectory'] = [serve_antenna_trajectory(cfg, contract, Drive(), m, now,
                                                                         ActuationCounters()) for m in msgs]
            for what, outs in cases.items():
                refused = [o for o in outs if isinstance(o, Refused)]
                first = refused[0].line[:150] if refused else ''
                print(f'{mode:10s} {what:19s} to {name}: {len(refused):3d}/{n} refused  {first}')
    speed = JointLimits.from_config(cfg).at_rocker(1)
    slack = range_slack(lower, upper)
    for name, end, sign in (('theta_min', cfg.theta_min, -1.0), ('theta_max', cfg.theta_max, 1.0)):
        for way, direction in (('towards', sign), ('away', -sign)):
            for what, sampled in (('setpoints', planned_setpoints), ('points', planned_points)):
                over: list[str] = []
                cannot_stop = past = 0
                for q in rests:
                    try:
                        plan = plan_command(cfg, JointMotionState(float(q), direction * speed), end)
                        sampled(cfg, plan)
                    except UnreachableError:
                        cannot_stop += 1
                        continue
                    except LimitError as exc:
                        over.append(str(exc)[:100])
                        continue
                    path = plan.sample(np.linspace(0.0, plan.duration, 2001))[0]
                    past += bool(path.min() < lower - slack or path.max() > upper + slack)
                print(f'at speed limit {way:7s} {what:9s} to {name}: {len(over):3d}/{n} refused for the limits, '
                      f'{cannot_stop:3d} cannot stop, {past:3d} accepted passing the range  {over[0] if over else ""}')

if __name__ == '__main__':
    main(*(int(a) for a in sys.argv[1:3]))
