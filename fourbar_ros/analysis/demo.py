"""The demo's analysis of a closed-loop recording: series, summary figures and plot (no ROS: read with ``rosbags``).

Times in s from the first recorded command, angles rad (degrees for display), driven-joint speeds rad/s at the
rocker, torques N m at the motor (``loads.motor_torque``). The demo: docs/tutorial.md."""

from __future__ import annotations

import bisect
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from fourbar_ros.config.antenna_config import AntennaConfig
from fourbar_ros.core.antenna import Branch, Driven
from fourbar_ros.core.completion import complete
from fourbar_ros.core.errors import FourBarError
from fourbar_ros.core.loads import motor_torque, poses
from fourbar_ros.interface.stamps import ns_to_seconds, to_ns
from fourbar_ros.interface.topics import (
    ANTENNA_ANGLE,
    BROADCASTER_JOINT_STATES,
    COMMAND,
    DIAGNOSTICS,
    INPUT_TORQUE,
    JOINT_STATES,
    trajectory_topic,
)
from fourbar_ros.rules.completion import completed_names
from fourbar_ros.rules.policy import Outcome, Policy, Served, serve
from fourbar_ros.rules.simulated_drive import effort_at

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
#: A recording as ``read_messages`` gives it: topic -> [(receive time ns, message), ...].
Messages = Mapping[str, Sequence[tuple[int, Any]]]


class DemoError(FourBarError):
    """The recording cannot be analysed (no command, no measurement)."""


@dataclass(frozen=True)
class DemoTopics:
    """The recorded topics' names."""

    command: str
    measured: str  #: the simulated actuator's measured driven joint (joint_state_broadcaster's local topic)
    joint_states: str  #: the node's complete joint states
    antenna_angle: str
    input_torque: str
    trajectory: str
    diagnostics: str

    def all(self) -> tuple[str, ...]:
        """Every name, in recording order."""
        return (self.command, self.measured, self.joint_states, self.antenna_angle, self.input_torque,
                self.trajectory, self.diagnostics)


def demo_topics(trajectory_controller: str) -> DemoTopics:
    """The recorded topics in the root namespace, where the demo runs its nodes."""
    return DemoTopics(f'/{COMMAND.name}', f'/{BROADCASTER_JOINT_STATES.name}', f'/{JOINT_STATES.name}',
                      f'/{ANTENNA_ANGLE.name}', f'/{INPUT_TORQUE.name}',
                      f'/{trajectory_topic(trajectory_controller).name}', DIAGNOSTICS.name)


@dataclass(frozen=True)
class Series:
    """Samples of one quantity: times (s from the first command) and values (units as named where used)."""

    t: FloatArray
    value: FloatArray


@dataclass(frozen=True)
class Measured:
    """The simulated actuator's joint_states: driven joint position (rad), velocity (rad/s), effort (N m at the
    driven rocker) and the header stamps (ns) the completion carries over. Timed by these stamps (when measured,
    on the same clock as the recording's receive times), not by when they arrived."""

    position: Series
    velocity: FloatArray
    effort: FloatArray
    stamp_ns: IntArray


@dataclass(frozen=True)
class Completed:
    """fourbar_node's complete joint_states, the joints it completes: the other rocker and the coupler joint,
    positions (rad) and velocities (rad/s; NaN where a message has none), with the measurement stamps (ns) they
    carry."""

    stamp_ns: IntArray
    other: FloatArray
    coupler: FloatArray
    other_rate: FloatArray
    coupler_rate: FloatArray


@dataclass(frozen=True)
class Recording:
    """A closed-loop run as time series."""

    command: Series  #: served antenna angle commands (rad)
    commands_recorded: int
    rejected: int
    clamped: int
    measured: Measured
    antenna: Series  #: the node's measured antenna angle (rad), timed by the measurement it completes (see below)
    antenna_matched: int  #: antenna_angle messages equal to the core's completion of a recorded measurement
    antenna_recorded: int  #: antenna_angle messages in the recording
    completed: Completed
    planned: Series  #: the driven joint's planned position (rad), each trajectory up to the next one's start
    planned_velocity: FloatArray  #: rad/s, at the planned samples
    planned_effort: FloatArray  #: N m at the driven rocker (the feed-forward), at the planned samples
    input_torque: Series  #: N m at the driven rocker
    trajectories: int
    diagnostics: int


#: The paced replay asks the driven joint for this fraction of its speed limit, on average, between two commands.
PACE_FRACTION = 0.8
#: Shortest time (s) between two replayed commands.
MIN_PERIOD_S = 0.01


def served(values: Sequence[float], cfg: AntennaConfig) -> Served:
    """What the node serves of ``values`` (rad): ``rules.policy.serve`` with the configured limits and policy."""
    return serve(np.asarray(values, dtype=np.float64), cfg.theta_min, cfg.theta_max, Policy(cfg.out_of_limits),
                 cfg.linkage.reach())


def served_driven(values: Sequence[float], cfg: AntennaConfig) -> FloatArray:
    """The driven joint's angle (rad) at each command the node serves."""
    gamma, delta, _ = poses(cfg, served(values, cfg).theta)
    return gamma if cfg.driven is Driven.GAMMA else delta


def pace(values: Sequence[float], cfg: AntennaConfig) -> float:
    """Seconds between replayed commands so that the largest step between two served commands, taken in that
    time, asks the driven joint for PACE_FRACTION of its speed limit (motor_speed_limit / |reducer_ratio|); at
    least MIN_PERIOD_S."""
    q = served_driven(values, cfg)
    step = float(np.max(np.abs(np.diff(q)))) if q.size > 1 else 0.0
    return max(step / (PACE_FRACTION * cfg.motor_speed_limit / cfg.reduction), MIN_PERIOD_S)


def _column(values: Sequence[float], index: int) -> float:
    return float(values[index]) if len(values) > index else math.nan


def _planned(trajectories: Sequence[tuple[int, Any]], joint: str, t0: int) -> tuple[Series, FloatArray, FloatArray]:
    """The planned motion of ``joint`` as the controller follows it: each trajectory (its points timed from its
    header stamp, else from its arrival) from its arrival, with the last point before it, up to the next one's
    arrival, when that one takes over (times in s from ``t0`` ns). A trajectory continuing the running one repeats
    its points under its stamp: the arrival, not the stamp, says where one ends and the next begins."""
    arrivals = [t for t, _ in trajectories]
    t_out: list[float] = []
    q_out: list[float] = []
    v_out: list[float] = []
    e_out: list[float] = []
    for k, (arrival, msg) in enumerate(trajectories):
        if joint not in msg.joint_names:
            continue
        j = list(msg.joint_names).index(joint)
        start = to_ns(msg.header.stamp) or arrival
        end = arrivals[k + 1] if k + 1 < len(arrivals) else math.inf
        times = [start + to_ns(p.time_from_start)
                 for p in msg.points]
        first = max(bisect.bisect_right(times, arrival) - 1, 0)  # the point at or before the arrival
        for at, p in zip(times[first:], msg.points[first:], strict=True):
            if at > end:
                break
            t_out.append(ns_to_seconds(at - t0))
            q_out.append(float(p.positions[j]))
            v_out.append(_column(p.velocities, j))
            e_out.append(_column(p.effort, j))
    return Series(np.array(t_out), np.array(q_out)), np.array(v_out), np.array(e_out)


def recording(messages: Messages, topics: DemoTopics, cfg: AntennaConfig) -> Recording:
    """The time series of a recording of ``topics``. Raises DemoError without a command or a measurement."""
    commands = messages.get(topics.command, [])
    if not commands:
        raise DemoError(f'no command recorded on {topics.command}')
    t0 = commands[0][0]

    def seconds(rows: Sequence[tuple[int, Any]]) -> FloatArray:
        return np.array([ns_to_seconds(t - t0) for t, _ in rows], dtype=np.float64)

    answered = served([m.data for _, m in commands], cfg)
    rejected = sum(n for outcome, n in answered.outcomes.items() if outcome.rejected)
    driven = cfg.driven_joint
    other_name, coupler_name = completed_names(cfg)
    measured_rows = [row for row in messages.get(topics.measured, []) if driven in row[1].name]
    completed_rows = [row for row in messages.get(topics.joint_states, []) if other_name in row[1].name]
    if not measured_rows:
        raise DemoError(f'no measured {driven!r} recorded on {topics.measured}')

    def field(rows: Sequence[tuple[int, Any]], name: str, attr: str) -> FloatArray:
        return np.array([_column(getattr(m, attr), list(m.name).index(name)) for _, m in rows], dtype=np.float64)

    measured_stamps = np.array([to_ns(m.header.stamp) for _, m in measured_rows], dtype=np.int64)
    measured_t = ns_to_seconds(measured_stamps - t0).astype(np.float64)
    measured_q = field(measured_rows, driven, 'position')

    planned, planned_velocity, planned_effort = _planned(messages.get(topics.trajectory, []), driven, t0)
    torques = messages.get(topics.input_torque, [])
    angles = messages.get(topics.antenna_angle, [])
    antenna, matched = _antenna_series(cfg, angles, seconds(angles), measured_q, measured_t)
    return Recording(
        command=Series(seconds(commands)[answered.index], answered.theta),
        commands_recorded=len(commands), rejected=rejected, clamped=answered.outcomes[Outcome.CLAMPED],
        measured=Measured(Series(measured_t, measured_q),
                          field(measured_rows, driven, 'velocity'), field(measured_rows, driven, 'effort'),
                          measured_stamps),
        antenna=antenna, antenna_matched=matched, antenna_recorded=len(angles),
        completed=Completed(np.array([to_ns(m.header.stamp) for _, m in completed_rows], dtype=np.int64),
                            field(completed_rows, other_name, 'position'),
                            field(completed_rows, coupler_name, 'position'),
                            field(completed_rows, other_name, 'velocity'),
                            field(completed_rows, coupler_name, 'velocity')),
        planned=planned, planned_velocity=planned_velocity, planned_effort=planned_effort,
        input_torque=Series(seconds(torques), np.array([m.data for _, m in torques], dtype=np.float64)),
        trajectories=len(messages.get(topics.trajectory, [])),
        diagnostics=len(messages.get(topics.diagnostics, [])))


def _antenna_series(cfg: AntennaConfig, angles: Sequence[tuple[int, Any]], received: FloatArray, q: FloatArray,
                    measured_t: FloatArray) -> tuple[Series, int]:
    """The antenna_angle messages (Float64: no stamp) timed by the measurement each completes: the latest recorded
    measurement stamped no later than the message was received whose completion by the core (``complete``, the
    node's scalar path) gives exactly its value. A message no measurement gives keeps its receive time, except
    before the first found (completions of measurements sent before the recording matched them): those are left
    out. Returns the series, sorted by time, and the number found.

    Matched by time, not in order: the recording can miss the first measurements while it has their completions,
    and at rest many measurements give the same value, so an in-order match would shift by one and lose a message
    where the value next changes."""
    branch = rocker_branch(cfg)
    stamps: dict[float, list[float]] = {}  # value -> the stamps (s) of the measurements completing to it, ascending
    for x, t in sorted(zip(q.tolist(), measured_t.tolist(), strict=True), key=lambda xt: xt[1]):
        stamps.setdefault(float(complete(cfg.linkage, float(x), cfg.driven, branch).theta), []).append(t)
    values = np.array([m.data for _, m in angles], dtype=np.float64)
    times = received.copy()
    matched, first = 0, None
    for k, v in enumerate(values.tolist()):
        candidates = stamps.get(float(v), [])
        n = bisect.bisect_right(candidates, float(received[k]))
        if n > 0:
            times[k] = candidates[n - 1]
            matched += 1
            first = k if first is None else first
    keep = slice(first or 0, None)
    times, values = times[keep], values[keep]
    order = np.argsort(times, kind='stable')
    return Series(times[order], values[order]), matched


def commanded_at(command: Series, t: FloatArray) -> FloatArray:
    """The latest served command (rad) at each time of ``t`` (s); NaN before the first."""
    i = np.searchsorted(command.t, t, side='right') - 1
    out = np.full(t.shape, np.nan)
    out[i >= 0] = command.value[i[i >= 0]]
    return out


def antenna_of(cfg: AntennaConfig, q: FloatArray) -> FloatArray:
    """The antenna angle (rad) of driven-joint angles ``q`` (rad), by the core's exact completion."""
    if q.size == 0:
        return q.copy()
    return np.asarray(complete(cfg.linkage, q, cfg.driven, rocker_branch(cfg), on_invalid='nan').theta)


def rocker_branch(cfg: AntennaConfig) -> Branch:
    """The completion's branch (``from_rocker``'s sense) of the configured assembly, as the node takes it."""
    return cfg.measured_branch


@dataclass(frozen=True)
class Summary:
    """The demo's figures. Errors are commanded minus measured antenna angle (rad)."""

    final_error: float
    worst_error: float
    worst_error_t: float  #: s
    speed_limit: float  #: rad/s at the driven rocker: motor_speed_limit / |reducer_ratio|
    peak_speed_measured: float  #: rad/s
    peak_speed_planned: float  #: rad/s (NaN without planned velocities)
    torque_limit: float  #: N m at the motor
    peak_motor_torque: float  #: N m, over input_torque, the planned feed-forward and the measured effort
    completion_position: float  #: rad, largest |node - core| over the completed positions
    completion_velocity: float  #: rad/s, the same for the velocities
    completed_paired: int  #: completed messages matched to a measurement by stamp
    completed_unpaired: int
    effort_rest: float  #: N m at the driven rocker: max |measured effort - input_torque| at rest (NaN: none)
    effort_rest_count: int
    effort_motion: float  #: N m, the same over the other paired measurements (NaN: none)
    effort_motion_count: int
    #: N m, max |measured effort - the load model's torque at the measured angle| over those (NaN: none)
    effort_motion_model: float
    effort: EffortCheck  #: the comparison measurement by measurement, which those figures sum up

    @property
    def speed_margin(self) -> float:
        """1 - peak / limit over the measured and planned speeds (negative: over the limit)."""
        peak = np.nanmax([self.peak_speed_measured, self.peak_speed_planned])
        return 1.0 - float(peak) / self.speed_limit

    @property
    def torque_margin(self) -> float:
        """1 - peak / limit of the motor torque (negative: over the limit)."""
        return 1.0 - self.peak_motor_torque / self.torque_limit


def _peak(values: FloatArray) -> float:
    finite = values[np.isfinite(values)]
    return float(np.max(np.abs(finite))) if finite.size else math.nan


def completion_deviation(rec: Recording, cfg: AntennaConfig) -> tuple[float, float, int, int]:
    """Largest |node - core| of the completed positions (rad) and velocities (rad/s), each completed message
    against ``core.completion.complete`` of the measurement with its stamp; and the paired and unpaired counts.

    Completions stamped outside the recorded measurements' stamps are left out: the recording started after their
    measurements, or ended before it took them (the two topics' messages are taken in no fixed order)."""
    by_stamp = {int(s): i for i, s in enumerate(rec.measured.stamp_ns)}
    branch = rocker_branch(cfg)
    position, velocity, paired = 0.0, 0.0, 0
    c = rec.completed
    first, last = int(rec.measured.stamp_ns.min()), int(rec.measured.stamp_ns.max())
    considered = 0
    for k, stamp in enumerate(c.stamp_ns):
        if not first <= stamp <= last:
            continue
        considered += 1
        i = by_stamp.get(int(stamp))
        if i is None:
            continue
        paired += 1
        q, q_rate = float(rec.measured.position.value[i]), float(rec.measured.velocity[i])
        core = complete(cfg.linkage, q, cfg.driven, branch, q_rate=q_rate if math.isfinite(q_rate) else None)
        position = max(position, abs(c.other[k] - float(core.other)), abs(c.coupler[k] - float(core.coupler_joint)))
        if core.other_rate is not None and core.coupler_joint_rate is not None:
            velocity = max(velocity, abs(c.other_rate[k] - float(core.other_rate)),
                           abs(c.coupler_rate[k] - float(core.coupler_joint_rate)))
    return position, velocity, paired, considered - paired


#: A measurement is at rest when its driven-joint speed is at most this (rad/s): the linkage's damping and inertia
#: then add nothing visible to the static torque (the plant's hinge damping, 1e-2 N m s/rad, gives 1e-8 N m).
REST_SPEED = 1e-6


@dataclass(frozen=True)
class EffortCheck:
    """Each measurement after the first ``input_torque``: its time (s), measured effort minus the latest
    ``input_torque`` received by then (N m at the driven rocker), and whether it was at rest at the command in
    force: speed at most REST_SPEED and antenna angle (completed by the core) within trajectory_tolerance of it;
    and the effort minus the load model's torque at the measured angle (``effort_at``; N m, NaN off its reach):
    what the drive adds to the statics, the linkage's dynamics."""

    t: FloatArray
    difference: FloatArray
    at_rest: npt.NDArray[np.bool_]
    model_difference: FloatArray


def effort_check(rec: Recording, cfg: AntennaConfig) -> EffortCheck:
    """The measured effort against the node's predicted ``input_torque`` (``EffortCheck``)."""
    m, torque = rec.measured, rec.input_torque
    i = np.searchsorted(torque.t, m.position.t, side='right') - 1
    keep = (i >= 0) & np.isfinite(m.effort)
    t, idx = m.position.t[keep], i[keep]
    difference = m.effort[keep] - torque.value[idx]
    command = commanded_at(rec.command, t)
    near = np.abs(antenna_of(cfg, m.position.value[keep]) - command) <= cfg.trajectory_tolerance
    at_rest = near & (np.abs(m.velocity[keep]) <= REST_SPEED)
    model = np.array([_effort_at(cfg, float(q)) for q in m.position.value[keep]], dtype=np.float64)
    return EffortCheck(t, difference, at_rest, m.effort[keep] - model)


def _effort_at(cfg: AntennaConfig, q: float) -> float:
    try:
        return effort_at(cfg, q)
    except FourBarError:
        return math.nan


def summarize(rec: Recording, cfg: AntennaConfig) -> Summary:
    """The figures of a recording."""
    if rec.command.t.size == 0 or rec.antenna.t.size == 0:
        raise DemoError('no served command or no measured antenna angle to compare')
    after = rec.antenna.t >= rec.command.t[0]
    t = rec.antenna.t[after]
    error = commanded_at(rec.command, t) - rec.antenna.value[after]
    if error.size == 0:
        raise DemoError('no measured antenna angle after the first command')
    worst = int(np.argmax(np.abs(error)))
    torque = np.concatenate([rec.input_torque.value, rec.planned_effort, rec.measured.effort])
    position, velocity, paired, unpaired = completion_deviation(rec, cfg)
    check = effort_check(rec, cfg)
    rest, motion = np.abs(check.difference[check.at_rest]), np.abs(check.difference[~check.at_rest])
    return Summary(
        final_error=float(rec.command.value[-1] - rec.antenna.value[-1]),  # the last served, once settled
        worst_error=float(error[worst]), worst_error_t=float(t[worst]),
        speed_limit=cfg.motor_speed_limit / cfg.reduction,
        peak_speed_measured=_peak(rec.measured.velocity), peak_speed_planned=_peak(rec.planned_velocity),
        torque_limit=cfg.motor_torque_limit, peak_motor_torque=abs(motor_torque(cfg, _peak(torque))),
        completion_position=position, completion_velocity=velocity, completed_paired=paired,
        completed_unpaired=unpaired,
        effort_rest=_peak(rest), effort_rest_count=int(rest.size),
        effort_motion=_peak(motion), effort_motion_count=int(motion.size),
        effort_motion_model=_peak(check.model_difference[~check.at_rest]), effort=check)


def _deg(x: float) -> str:
    return f'{math.degrees(x):+.4f} deg'


#: What the simulated actuator's measured effort is, by its drive (``drive`` parameter).
DRIVE_EFFORT = {'mujoco': "the MuJoCo plant's reducer torque", 'lag': "the load model's torque at its angle"}


def summary_lines(rec: Recording, s: Summary, cfg: AntennaConfig, diagnostics: Mapping[str, str],
                  drive: str = 'lag') -> list[str]:
    """The demo's short report; ``drive``: the simulated actuator's (a key of DRIVE_EFFORT)."""
    speed_peak = float(np.nanmax([s.peak_speed_measured, s.peak_speed_planned]))
    return [
        f'command  {_deg(float(rec.command.value.min()))} .. {_deg(float(rec.command.value.max()))} '
        f'({rec.command.value.size} served of {rec.commands_recorded} sent; {rec.rejected} rejected, '
        f'{rec.clamped} clamped; node diagnostics: {diagnostics.get("commands_received", "?")} received, '
        f'{diagnostics.get("commands_planned", "?")} planned, {diagnostics.get("commands_not_planned", "?")} not)',
        f'tracking final {s.final_error:+.3g} rad (commanded - measured antenna angle; trajectory_tolerance '
        f'{cfg.trajectory_tolerance:g}), worst {_deg(s.worst_error)} at {s.worst_error_t:.2f} s',
        f'speed    peak {math.degrees(speed_peak):.3f} deg/s at the driven rocker (measured '
        f'{math.degrees(s.peak_speed_measured):.3f}, planned {math.degrees(s.peak_speed_planned):.3f}) of the '
        f'{math.degrees(s.speed_limit):.3f} deg/s limit ({cfg.motor_speed_limit:g} rad/s / {cfg.reduction:g}): '
        f'margin {100 * s.speed_margin:.1f}%',
        f'torque   peak {s.peak_motor_torque:.5f} N m at the motor of the {s.torque_limit:g} N m limit: '
        f'margin {100 * s.torque_margin:.1f}%',
        f'margin   worst {100 * min(s.speed_margin, s.torque_margin):.1f}% '
        f'({"speed" if s.speed_margin <= s.torque_margin else "torque"})',
        f'effort   measured - input_torque at the driven rocker: max |d| at rest {s.effort_rest:.3g} N m over '
        f'{s.effort_rest_count} measurements, in motion {s.effort_motion:.3g} N m over {s.effort_motion_count} '
        f'({s.effort_motion_model:.3g} N m off the load model at the measured angle; drive {drive}: '
        f'{DRIVE_EFFORT.get(drive, drive)})',
        f'counts   {rec.trajectories} trajectories, {rec.planned.t.size} planned points followed, '
        f'{rec.measured.position.t.size} measured joint_states, {rec.completed.stamp_ns.size} completed, '
        f'{rec.antenna_recorded} antenna_angle, {rec.input_torque.t.size} input_torque, {rec.diagnostics} diagnostics',
        f'check    completion vs core: max |d position| = {s.completion_position:.3g} rad, max |d velocity| = '
        f'{s.completion_velocity:.3g} rad/s over {s.completed_paired} measurements ({s.completed_unpaired} unpaired); '
        f'antenna_angle: {rec.antenna_matched} of {rec.antenna.t.size} equal to a measurement\'s',
    ]


def plot(rec: Recording, s: Summary, cfg: AntennaConfig, path: Path, title: str) -> Path:
    """Write a PNG: commanded, planned and measured antenna angle; tracking error; driven-joint speed against its
    limit; motor torque (planned feed-forward, measured effort, the node's input_torque) against its limit; measured
    effort minus input_torque and minus the load model at the rocker (``s.effort``); all against time."""
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    fig, (ax_angle, ax_error, ax_speed, ax_torque, ax_effort) = plt.subplots(
        5, 1, figsize=(8.5, 12.0), sharex=True, layout='constrained', height_ratios=(3, 1.6, 2, 2, 1.6))
    ax_angle.step(rec.command.t, np.degrees(rec.command.value), where='post', color='tab:red', lw=1.2,
                  label='commanded (antenna_angle_cmd)')
    ax_angle.plot(rec.planned.t, np.degrees(antenna_of(cfg, rec.planned.value)), color='tab:blue', ls='--', lw=1,
                  label='planned (joint_trajectory, completed by the core)')
    ax_angle.plot(rec.antenna.t, np.degrees(rec.antenna.value), color='k', lw=0.8,
                  label='measured (antenna_angle, completed by the node)')
    ax_angle.set_ylabel('antenna angle theta (deg)')
    ax_angle.legend(loc='lower center', fontsize=8)

    after = rec.antenna.t >= rec.command.t[0]
    t = rec.antenna.t[after]
    error = commanded_at(rec.command, t) - rec.antenna.value[after]
    ax_error.plot(t, np.degrees(error), color='k', lw=0.8, label='commanded - measured')
    ax_error.axhline(0.0, color='0.5', lw=0.6)
    ax_error.set_ylabel('tracking error (deg)')
    ax_error.legend(loc='upper right', fontsize=8,
                    title=f'final {s.final_error:+.2g} rad, worst {math.degrees(s.worst_error):+.2f} deg',
                    title_fontsize=8)

    limit = math.degrees(s.speed_limit)
    ax_speed.plot(rec.planned.t, np.degrees(rec.planned_velocity), color='tab:blue', ls='--', lw=1, label='planned')
    ax_speed.plot(rec.measured.position.t, np.degrees(rec.measured.velocity), color='k', lw=0.8,
                  label=f'measured ({cfg.driven_joint})')
    for sign in (1.0, -1.0):
        ax_speed.axhline(sign * limit, color='tab:red', ls=':', lw=1.2,
                         label=f'limit {cfg.motor_speed_limit:.4g} rad/s / {cfg.reduction:g}' if sign > 0 else None)
    ax_speed.set_ylim(-1.25 * limit, 1.25 * limit)
    ax_speed.set_ylabel('driven joint speed (deg/s)')
    ax_speed.legend(loc='lower left', fontsize=8, ncols=3)

    ax_torque.plot(rec.measured.position.t, motor_torque(cfg, rec.measured.effort), color='k', lw=0.8,
                   label='measured effort')
    ax_torque.plot(rec.planned.t, motor_torque(cfg, rec.planned_effort), color='tab:blue', ls='--', lw=1,
                   label='planned feed-forward')
    if rec.input_torque.t.size:
        ax_torque.step(rec.input_torque.t, motor_torque(cfg, rec.input_torque.value), where='post',
                       color='tab:orange', lw=1, label='input_torque (node)')
    ax_torque.axhline(cfg.motor_torque_limit, color='tab:red', ls=':', lw=1.2,
                      label=f'motor limit {cfg.motor_torque_limit:g} N m')
    ax_torque.set_ylim(0.0, 1.2 * max(cfg.motor_torque_limit, s.peak_motor_torque))
    ax_torque.set_ylabel(f'torque at the motor (N m)\n(rocker / ({cfg.reducer_ratio:g} x {cfg.reducer_efficiency:g}))')
    ax_torque.legend(loc='lower left', fontsize=8, ncols=2)

    check = s.effort
    ax_effort.plot(check.t, check.difference, color='k', lw=0.8, label='measured effort - input_torque')
    ax_effort.plot(check.t, check.model_difference, color='tab:blue', lw=0.8,
                   label='measured effort - load model at the measured angle')
    ax_effort.plot(check.t[check.at_rest], check.difference[check.at_rest], ls='none', marker='.', ms=3,
                   color='tab:green', label='at rest at the command')
    ax_effort.axhline(0.0, color='0.5', lw=0.6)
    ax_effort.set_ylabel('effort - input_torque\n(N m at the rocker)')
    ax_effort.set_xlabel('time since the first command (s)')
    ax_effort.legend(loc='upper left', fontsize=8, ncols=1,
                     title=f'max |d|: at rest {s.effort_rest:.2g} N m, in motion {s.effort_motion:.2g} N m',
                     title_fontsize=8)
    for ax in (ax_angle, ax_error, ax_speed, ax_torque, ax_effort):
        ax.grid(True, alpha=0.3)
    fig.suptitle(title, fontsize=10)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f'.{path.name}.tmp')
    fig.savefig(tmp, dpi=110, format='png')
    plt.close(fig)
    tmp.replace(path)
    return path
