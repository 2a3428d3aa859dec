"""The actuator modes' completion: the measured driven joint in, the whole linkage out (fourbar_node composes it).

Measurements are read raw and each output is published only while subscribed; what the outputs hold is
``fourbar_ros.rules.completion``. Topics: docs/reference/topics.md; counters: docs/reference/diagnostics.md; why:
docs/explanation/node.md."""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import Any

from rclpy.node import Node
from rclpy.qos import QoSProfile
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64

from fourbar_ros.config.antenna_config import AntennaConfig
from fourbar_ros.core.errors import FourBarError, one_line
from fourbar_ros.interface.cdr import MalformedCdrError, read_joint_state_arrays, read_joint_state_head
from fourbar_ros.interface.stamps import to_ns
from fourbar_ros.interface.topics import ANTENNA_ANGLE, ANTENNA_RATE, LOAD_TORQUE, MEASURED_JOINT_STATES, Topic
from fourbar_ros.rules.completion import CompletionRule, Skipped, driven_index, driven_measurement
from fourbar_ros.rules.diagnostics import Level
from fourbar_ros.runtime.problem_log import ProblemLog
from fourbar_ros.runtime.publishers import publish, subscription_count


@dataclass
class MeasurementCounters:
    """Counts of the completion, reported in diagnostics."""

    measurements_completed: int = 0
    measurements_refused_not_finite: int = 0
    measurements_ignored_no_driven_joint: int = 0
    measurements_ignored_mismatched_lengths: int = 0
    measurements_ignored_malformed: int = 0  # payloads that are not a little-endian CDR JointState
    measurements_out_of_range: int = 0
    measurements_not_completed: int = 0  # the core could not complete it (a change point)
    measurements_own_skipped: int = 0  # completed JointStates (the node's own) on the same topic


class MeasuredCompletion:
    """Subscription, publishers, counters and diagnostic values of the completion."""

    def __init__(self, node: Node, cfg: AntennaConfig, joint_pub: Any, qos: Callable[[Topic], QoSProfile],
                 problems: ProblemLog,
                 on_measured: Callable[[float, float | None, int], None] | None = None,
                 on_completed: Callable[[int, float], None] | None = None) -> None:
        """``joint_pub``: the node's joint_states publisher; ``qos``: the profile of a topic;
        ``problems``: the node's log by problem kind;
        ``on_measured``: called with each measured driven joint that is finite and within reach: position rad,
        velocity rad/s (None: not measured), its header stamp (ns; 0: none); ``on_completed``: with each one
        completed: its stamp (ns) and position rad."""
        self._on_measured = on_measured
        self._on_completed = on_completed
        self.rule = CompletionRule(cfg)
        self.counters = MeasurementCounters()
        self._problems = problems
        self._timeout = cfg.measurement_timeout
        self._window = cfg.tracking_window
        pubs = (joint_pub, *(node.create_publisher(Float64, t.name, qos(t)) for t in (ANTENNA_ANGLE, ANTENNA_RATE,
                                                                                      LOAD_TORQUE)))
        # The good path calls them as single C calls (fourbar_ros.runtime.publishers).
        self._joints_heard, self._angle_heard, self._rate_heard, self._load_heard = map(subscription_count, pubs)
        self._send_joints, self._send_angle, self._send_rate, self._send_load = map(publish, pubs)
        on_measurement = problems.guard.wrap('sub_measured_joint_states', self.on_measurement)
        self._sub = node.create_subscription(JointState, MEASURED_JOINT_STATES.name, on_measurement,
                                             qos(MEASURED_JOINT_STATES), raw=True)
        self._own = 1 if self._sub.topic_name == joint_pub.topic_name else 0  # our own subscription matches it
        self._driven, self._names = self.rule.driven_joint, self.rule.names
        self._msg = JointState()
        self._msg.name = list(self._names)
        self._float = Float64()
        self._started = time.monotonic()
        self._last_time: float | None = None  # steady time (s) of the last measurement taken
        self._range_error: str | None = None  # the last out-of-range measurement, until a good one
        self.theta: float | None = None  # the last measured antenna angle, rad
        self._commanded: float | None = None
        self._tracking: deque[tuple[float, float]] = deque()  # (steady time s, |commanded - measured| rad)

    def set_commanded(self, theta: float) -> None:
        """The commanded antenna angle (rad), for the tracking error."""
        self._commanded = theta

    def on_measurement(self, raw: bytes) -> None:
        """Complete one measured JointState (its CDR bytes) and publish what has a subscriber."""
        counters = self.counters
        try:
            sec, nanosec, _, names, at = read_joint_state_head(raw)
            i = driven_index(names, self._names, self._driven)
            if isinstance(i, Skipped):
                self._skip(i, f'{MEASURED_JOINT_STATES.name} without {self._driven} (names {names}): ignored')
                return
            position, velocity, effort = read_joint_state_arrays(raw, at)
        except MalformedCdrError as exc:
            self._skip(Skipped.MALFORMED, f'{MEASURED_JOINT_STATES.name} payload of {len(raw)} bytes is not a '
                                          f'JointState ({exc}): ignored')
            return
        values = driven_measurement(i, len(names), position, velocity, effort)
        if values is not Skipped.MISMATCHED_LENGTHS:  # a measurement came, if a bad one
            self._last_time = now = time.monotonic()
        if isinstance(values, Skipped):
            self._skip(values, f'{MEASURED_JOINT_STATES.name} of {self._driven}: {len(names)} names, '
                               f'{len(position)} positions, {len(velocity)} velocities, {len(effort)} efforts; '
                               f'{self._driven} at {position[i] if i < len(position) else None!r}: '
                               f'{values.name.lower().replace("_", " ")}')
            return
        q, q_dot, tau = values
        rule = self.rule
        if not rule.in_reach(q):
            counters.measurements_out_of_range += 1
            self._range_error = rule.out_of_range(q)
            self._problems.error('measurement out of range', self._range_error)
            return
        out = self._msg
        stamp = out.header.stamp
        stamp.sec, stamp.nanosec = sec, nanosec  # the completed JointState carries the measurement's stamp
        stamp_ns = to_ns(stamp)
        if self._on_measured is not None:
            self._on_measured(q, q_dot, stamp_ns)
        joints = self._joints_heard() > self._own
        rate = self._rate_heard() > 0
        load = self._load_heard() > 0
        try:
            done = rule.one(q, q_dot if joints or rate else None, tau if load or joints else None)
        except FourBarError as exc:
            counters.measurements_not_completed += 1
            self._problems.error(f'completion {type(exc).__name__}',
                                 f'cannot complete {self._driven} = {q!r} rad: {one_line(exc)}')
            return
        self._range_error = None
        if joints:
            out.position = done.positions
            out.velocity = done.velocities
            out.effort = done.efforts
            self._send_joints(out)
        number = self._float
        if self._angle_heard() > 0:
            number.data = done.theta
            self._send_angle(number)
        if rate and done.theta_rate is not None:
            number.data = done.theta_rate
            self._send_rate(number)
        if load and done.load_torque is not None:
            number.data = done.load_torque
            self._send_load(number)
        counters.measurements_completed += 1
        self.theta = done.theta
        if self._on_completed is not None:
            self._on_completed(stamp_ns, q)
        if self._commanded is not None:
            tracking = self._tracking
            tracking.append((now, abs(self._commanded - done.theta)))
            while tracking[0][0] < now - self._window:
                tracking.popleft()

    def _skip(self, why: Skipped, line: str) -> None:
        """Count a measurement that is not completed under its key; log one throttled line (not for own ones)."""
        key = f'measurements_{why.value}'
        setattr(self.counters, key, getattr(self.counters, key) + 1)
        if why is not Skipped.OWN:
            self._problems.warn(f'measurement {why.value}', line)

    def diagnostics(self) -> tuple[Level, str, list[tuple[str, str]]]:
        """(level, message, key/value pairs) of the completion: ERROR while the last measurement was out of
        range, WARN after measurement_timeout s without one, OK otherwise."""
        now = time.monotonic()
        since = now - (self._last_time if self._last_time is not None else self._started)
        values = [(k, str(v)) for k, v in asdict(self.counters).items()]
        values.append(('measurement_age_s', repr(since) if self._last_time is not None else 'none'))
        if self.theta is not None:
            values.append(('measured_theta_rad', repr(self.theta)))
        if self._commanded is not None and self.theta is not None:
            while self._tracking and self._tracking[0][0] < now - self._window:
                self._tracking.popleft()
            worst = max((e for _, e in self._tracking), default=abs(self._commanded - self.theta))
            values += [('commanded_theta_rad', repr(self._commanded)),
                       ('tracking_error_rad', repr(self._commanded - self.theta)),
                       ('tracking_error_worst_rad', repr(worst))]
        if self._range_error is not None:
            return Level.ERROR, self._range_error, values
        if since > self._timeout:
            return (Level.WARN, f'no measurement of {self._driven} on {MEASURED_JOINT_STATES.name} for {since:.3g} s '
                    f'(measurement_timeout {self._timeout:g} s)', values)
        return Level.OK, 'ok', values
