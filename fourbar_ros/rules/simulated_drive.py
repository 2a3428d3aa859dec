"""The simulated actuator's behaviour, without ROS: the trajectory controller, the drive, the encoder.

``TrajectoryFollower`` imitates joint_trajectory_controller, ``LagActuator`` the drive, ``Encoder`` what the
hardware reports; angles are the driven joint's (rad), times s. What it imitates: docs/how-to/ros2-control.md."""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from fourbar_ros.config.antenna_config import AntennaConfig
from fourbar_ros.config.controllers import TrajectoryControllerSettings
from fourbar_ros.core.loads import pose
from fourbar_ros.interface.stamps import seconds_to_ns
from fourbar_ros.rules.controller_contract import (
    ContractRule,
    PointLike,
    Refusal,
    TrajectoryPointLike,
    check_trajectory,
)
from fourbar_ros.rules.controller_motion import ControllerPoint, Reference, controller_reference

#: Most points one trajectory may hold (more is refused, so memory stays bounded).
MAX_TRAJECTORY_POINTS = 100_000
#: Most accepted trajectories waiting for an update, the oldest dropped beyond (memory stays bounded: each may hold
#: MAX_TRAJECTORY_POINTS); an update takes only the latest that arrived before it, so a dropped one would rarely be
#: followed.
MAX_PENDING = 16
#: Integration step (s) of the drive: fixed, so a late timer tick changes nothing but when the state is read.
STEP_S = 0.001


class TrajectoryError(ValueError):
    """A trajectory the actuator refuses (one line naming the point and why)."""


class Setpoint(NamedTuple):
    """Position (rad), velocity (rad/s) and acceleration (rad/s^2) of the reference at one time."""

    position: float
    velocity: float
    acceleration: float


class Waypoint(NamedTuple):
    """One trajectory point of the driven joint: time from the trajectory's start (s), position (rad), and
    velocity (rad/s) and acceleration (rad/s^2) where the message gives them (else None)."""

    time: float
    position: float | None  # None: integrated from the velocities (allow_integration_in_goal_trajectories)
    velocity: float | None
    acceleration: float | None


def _column(values: Sequence[float], index: int, width: int, field: str, k: int, required: bool) -> float | None:
    """The joint's entry of one point's array; None if the array is empty and may be."""
    if len(values) == 0 and not required:
        return None
    if len(values) != width:
        raise TrajectoryError(f'point {k}: {len(values)} {field} for {width} joint names')
    value = float(values[index])
    if not math.isfinite(value):
        raise TrajectoryError(f'point {k}: {field}[{index}] is {value!r}')
    return value


def waypoints(joint_names: Sequence[str], joint: str, points: Sequence[PointLike],
              max_points: int = MAX_TRAJECTORY_POINTS, integrate: bool = False) -> list[Waypoint]:
    """The driven joint's waypoints of a JointTrajectory the contract accepted (``TrajectoryFollower.receive``).

    Stricter than the controller where the simulation needs it: raises ``TrajectoryError`` for a non-finite value,
    more than ``max_points`` points (memory stays bounded), or ``joint`` missing or named twice. With ``integrate``
    (``allow_integration_in_goal_trajectories``) a point may leave its position out (it is integrated from the
    velocities, ``rules.controller_motion``).
    """
    count = sum(1 for name in joint_names if name == joint)
    if count != 1:
        raise TrajectoryError(f'joint {joint!r} is {"missing" if count == 0 else "named twice"} '
                              f'(joint_names: {list(joint_names)})')
    if len(points) > max_points:
        raise TrajectoryError(f'{len(points)} points; at most {max_points} are taken')
    index, width = list(joint_names).index(joint), len(joint_names)
    out: list[Waypoint] = []
    last = -math.inf
    for k, p in enumerate(points):
        t = p.time_from_start.sec + 1e-9 * p.time_from_start.nanosec
        if not t > last or t < 0.0:
            raise TrajectoryError(f'point {k}: time_from_start {t!r} s does not increase (previous {last!r} s)')
        position = _column(p.positions, index, width, 'positions', k, required=not integrate)
        out.append(Waypoint(t, position, _column(p.velocities, index, width, 'velocities', k, required=False),
                            _column(p.accelerations, index, width, 'accelerations', k, required=False)))
        last = t
    return out


class Trajectory:
    """A trajectory taken over at ``start`` (s, on the node's clock) from the state measured there, as the
    controller follows it (``rules.controller_motion.Reference``: the lead-in, the segments, the hold); times
    inside are relative to ``start``, so they keep their precision."""

    def __init__(self, start: float, reference: Reference) -> None:
        self.start = start
        self.reference = reference

    def sample(self, now: float) -> Setpoint:
        """The reference at time ``now`` (s): its value at the takeover before it, the held last point after."""
        return Setpoint(*self.reference.sample(now - self.start))

    @property
    def end(self) -> float:
        """Time (s, node clock) of the last point."""
        return self.start + float(self.reference.knots[-1])


@dataclass
class FollowerCounters:
    """What the trajectory follower did."""

    accepted: int = 0
    refused: dict[ContractRule, int] = field(default_factory=lambda: dict.fromkeys(ContractRule, 0))
    refused_not_finite: int = 0  #: stricter than the controller, which takes NaN as given
    tolerance_holds: int = 0  #: held after a trajectory-tolerance violation
    goal_time_holds: int = 0  #: held after goal_time past the last point outside the goal tolerance

    def as_dict(self) -> dict[str, int]:
        """Counter name -> value, one ``trajectories_refused_<rule>`` per contract rule."""
        out = {'trajectories_accepted': self.accepted, 'trajectories_refused_not_finite': self.refused_not_finite,
               'tolerance_holds': self.tolerance_holds, 'goal_time_holds': self.goal_time_holds}
        out.update({f'trajectories_refused_{r.value}': n for r, n in self.refused.items()})
        return out


class TrajectoryFollower:
    """joint_trajectory_controller for the joint ``joint`` with ``settings`` (module docstring). ``reference(now,
    position, velocity)`` is its update: the position reference (rad) at ``now`` (s) given the measured state."""

    def __init__(self, settings: TrajectoryControllerSettings, joint: str, position: float,
                 period: float = 0.0) -> None:
        """``period``: the update period (s); each update commands the reference that far ahead."""
        self.settings = settings
        self.period = period
        self.joint = joint
        self.counters = FollowerCounters()
        self._hold = Setpoint(position, 0.0, 0.0)
        self._trajectory: Trajectory | None = None
        #: the trajectory followed up to the latest takeover (None: a hold, at rest)
        self.previous: Trajectory | None = None
        #: (arrival ns, stamp ns, points) of each accepted trajectory, oldest first, until an update takes it
        self._pending: deque[tuple[int, int, tuple[Waypoint, ...]]] = deque(maxlen=MAX_PENDING)
        tol = settings.tolerance(joint)
        self._path_tolerance, self._goal_tolerance = tol.trajectory, tol.goal
        self._velocity_state = 'velocity' in settings.state_interfaces
        self.holding_reason: str | None = None
        #: called with each trajectory's reference as the controller takes it over (tests check its whole motion)
        self.on_takeover: Callable[[Reference], None] | None = None

    def receive(self, joint_names: Sequence[str], points: Sequence[TrajectoryPointLike], stamp_ns: int,
                now_ns: int) -> Refusal | None:
        """Take a JointTrajectory (stamp and arrival time in ns on this clock); None when accepted, else why it is
        refused (the running trajectory then goes on)."""
        refusal = check_trajectory(self.settings, joint_names, points, stamp_ns, now_ns)
        if refusal is not None:
            self.counters.refused[refusal.rule] += 1
            return refusal
        try:
            taken = waypoints(joint_names, self.joint, points,
                              integrate=self.settings.allow_integration_in_goal_trajectories)
        except TrajectoryError as exc:
            self.counters.refused_not_finite += 1
            return Refusal(ContractRule.FIELD_SIZE, str(exc))
        self._pending.append((now_ns, stamp_ns, tuple(taken)))
        self.counters.accepted += 1
        return None

    def hold(self, position: float) -> None:
        """Stop following and hold ``position`` (rad): a forward command, or a hold of the controller's own."""
        self._hold = Setpoint(position, 0.0, 0.0)
        self._trajectory = None
        self._pending.clear()

    @property
    def trajectory(self) -> Trajectory | None:
        """The trajectory followed now (None: a hold)."""
        return self._trajectory

    @property
    def waiting(self) -> int:
        """How many accepted trajectories no update has taken over yet."""
        return len(self._pending)

    def reference(self, now: float, position: float, velocity: float) -> Setpoint:
        """The controller's update at ``now`` (s) with the measured position (rad) and velocity (rad/s): the
        command it writes, the reference one update period ahead. The latest trajectory that arrived by ``now`` is
        taken over here, from the state measured here (the ones before it are never followed, as the controller's
        realtime buffer keeps only the latest)."""
        newest = None
        while self._pending and self._pending[0][0] <= seconds_to_ns(now):
            newest = self._pending.popleft()
        if newest is not None:
            _, stamp_ns, points = newest
            stamp = None if stamp_ns == 0 else stamp_ns * 1e-9 - now
            reference = controller_reference(
                self._velocity_state, [ControllerPoint(*p) for p in points], stamp, 0.0, position, velocity,
                self.period)
            self.previous, self._trajectory = self._trajectory, Trajectory(now, reference)
            if self.on_takeover is not None:
                self.on_takeover(reference)
            self.holding_reason = None
            self._check(now, position, first=True)
        elif self._trajectory is not None:
            self._check(now, position, first=False)
        return self._trajectory.sample(now + self.period) if self._trajectory is not None else self._hold

    def _check(self, now: float, position: float, first: bool) -> None:
        traj = self._trajectory
        assert traj is not None
        error = abs(position - traj.sample(now).position)
        before_last = now < traj.end
        if (before_last or first) and 0.0 < self._path_tolerance < error:
            self.counters.tolerance_holds += 1
            self.holding_reason = (f'{self.joint} is {error:.3g} rad off the trajectory (tolerance '
                                   f'{self._path_tolerance:g} rad): holding position')
            self.hold(position)
        elif (not before_last and 0.0 < self._goal_tolerance < error and self.settings.goal_time > 0.0
              and now - traj.end > self.settings.goal_time):
            self.counters.goal_time_holds += 1
            self.holding_reason = (f'{self.joint} is {error:.3g} rad from the goal {self.settings.goal_time:g} s '
                                   f'after the last point (goal tolerance {self._goal_tolerance:g} rad): holding')
            self.hold(position)


@dataclass(frozen=True)
class DriveLimits:
    """The simulated drive: position range (rad), speed (rad/s), acceleration (rad/s^2), lag time constant (s)."""

    lower: float
    upper: float
    max_velocity: float
    max_acceleration: float
    tau: float

    def __post_init__(self) -> None:
        for name in ('lower', 'upper', 'max_velocity', 'max_acceleration', 'tau'):
            if not math.isfinite(getattr(self, name)):
                raise ValueError(f'{name} must be finite')
        if not self.lower < self.upper:
            raise ValueError(f'lower {self.lower!r} must be below upper {self.upper!r}')
        if not (self.max_velocity > 0.0 and self.max_acceleration > 0.0 and self.tau > 0.0):
            raise ValueError('max_velocity, max_acceleration and tau must be positive')


def braking_speed(error: float, acceleration: float, step: float) -> float:
    """The fastest speed (rad/s) from which steps of ``step`` s, each slower by ``acceleration * step``, stop
    within ``error`` rad (its magnitude).

    In units of a h (speed) and a h^2 (distance): from speed u the steps cover u + (u - 1) + ... + (u - m) with
    m = floor(u), which rises from m (m + 1) / 2 to (m + 1) (m + 2) / 2 as u goes from m to m + 1. Taking m the
    largest integer with m (m + 1) / 2 <= E (E = |error| / (a h^2)) and solving (m + 1) u - m (m + 1) / 2 = E
    gives u. The speed after one step, u - 1, is then exactly the braking speed of the error left (E - u):
    braking stays feasible under the acceleration limit all the way, so the drive never overshoots.
    """
    unit = acceleration * step
    e = abs(error) / (unit * step)
    m = math.floor(0.5 * (math.sqrt(1.0 + 8.0 * e) - 1.0))
    return unit * (e + 0.5 * m * (m + 1)) / (m + 1)


class LagActuator:
    """The drive's true state (position rad, velocity rad/s), following a position reference."""

    def __init__(self, limits: DriveLimits, position: float, step: float = STEP_S) -> None:
        self.limits = limits
        self.step_s = step
        self.position = min(max(position, limits.lower), limits.upper)
        self.velocity = 0.0
        self._decay = math.exp(-step / limits.tau)
        self._pending = 0.0  # time (s) not yet integrated: less than one step

    def clamp(self, reference: float) -> float:
        """The reference within the drive's position range."""
        return min(max(reference, self.limits.lower), self.limits.upper)

    def advance(self, dt: float, reference: float) -> None:
        """Advance by ``dt`` s (in whole steps; the rest waits for the next call) towards ``reference`` (held over
        the interval; clamped to the range).

        Each step: the lag's own move, exact for a held reference, r + (x - r) exp(-h/tau); its mean speed then
        bounded by the braking speed, the speed limit and the acceleration limit, in that order.
        """
        lim, h = self.limits, self.step_s
        self._pending += max(dt, 0.0)
        steps = math.floor(self._pending / h)
        self._pending -= steps * h
        r = self.clamp(reference)
        dv = lim.max_acceleration * h
        for _ in range(steps):
            error = r - self.position
            want = error * (1.0 - self._decay) / h
            limit = min(braking_speed(error, lim.max_acceleration, h), lim.max_velocity)
            want = math.copysign(min(abs(want), limit), want)
            v = min(max(want, self.velocity - dv), self.velocity + dv)
            self.position = min(max(self.position + v * h, lim.lower), lim.upper)
            self.velocity = v


@dataclass
class Encoder:
    """Measured position = quantized(true + noise) + offset (rad); velocity and effort get their own noise.

    ``counts_per_rev`` counts per motor turn (0: no quantization) through ``reducer_ratio`` (motor turns per joint
    turn) give the joint's resolution 2 pi / (counts_per_rev ratio) rad. Noise standard deviations are in rad,
    rad/s and N m (0: none); ``seed`` makes the noise repeatable.
    """

    counts_per_rev: int = 0
    reducer_ratio: float = 1.0
    offset: float = 0.0
    position_noise: float = 0.0
    velocity_noise: float = 0.0
    effort_noise: float = 0.0
    seed: int = 0

    def __post_init__(self) -> None:
        self._rng = np.random.default_rng(self.seed)
        self.resolution = 2.0 * math.pi / (self.counts_per_rev * self.reducer_ratio) if self.counts_per_rev else 0.0

    def _noise(self, sigma: float) -> float:
        return float(self._rng.normal(0.0, sigma)) if sigma > 0.0 else 0.0

    def quantize(self, position: float) -> float:
        """``position`` (rad) rounded to the nearest whole count."""
        if not self.resolution:
            return position
        return round(position / self.resolution) * self.resolution

    def measure(self, position: float, velocity: float, effort: float) -> tuple[float, float, float]:
        """What the hardware reports for the true position (rad), velocity (rad/s) and effort (N m)."""
        return (self.quantize(position + self._noise(self.position_noise)) + self.offset,
                velocity + self._noise(self.velocity_noise), effort + self._noise(self.effort_noise))


def effort_at(cfg: AntennaConfig, q: float) -> float:
    """Torque (N m, in the sense of increasing q) the driven rocker needs at its angle ``q`` (rad) under the
    configured load: the antenna angle from the rocker (``from_rocker`` on ``cfg.measured_branch``, the configured
    assembly), then the statics.
    Raises the core's UnreachableError for an angle the rocker cannot take."""
    theta = float(cfg.linkage.from_rocker(q, cfg.driven, cfg.measured_branch).theta)
    return pose(cfg, theta).input_torque
