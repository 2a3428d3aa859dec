"""The node's diagnostic status as plain values: level, message and key/value pairs. No ROS.

Levels, keys and the float format: docs/reference/diagnostics.md."""

from __future__ import annotations

import enum
import math
from dataclasses import asdict, dataclass
from typing import NamedTuple

from fourbar_ros.config.antenna_config import AntennaConfig
from fourbar_ros.core.antenna import LinkageState
from fourbar_ros.core.loads import motor_torque
from fourbar_ros.rules.policy import Decision, Outcome

#: More commands lost than this since the previous status raise the level to WARN (any loss does).
LOST_WARN_THRESHOLD = 0


class Level(enum.IntEnum):
    """diagnostic_msgs/DiagnosticStatus levels."""

    OK = 0
    WARN = 1
    ERROR = 2


@dataclass
class Counters:
    """Running counts the node reports; they prove which work was done or skipped."""

    commands_received: int = 0
    commands_accepted: int = 0
    commands_clamped: int = 0
    commands_rejected_not_finite: int = 0
    commands_rejected_out_of_limits: int = 0
    commands_rejected_out_of_reach: int = 0
    commands_not_solved: int = 0  # served, but nobody subscribed to joint_states or input_torque
    joint_states_published: int = 0
    input_torque_published: int = 0
    input_torque_skipped: int = 0
    markers_published: int = 0
    markers_skipped: int = 0  # marker timer ticks with no subscriber or nothing new to draw
    diagnostics_published: int = 0
    diagnostics_skipped: int = 0
    parameter_changes_accepted: int = 0
    parameter_changes_rejected: int = 0  # every refusal: rclpy's (undeclared, type, range, read-only) and ours
    commands_lost: int = 0  # published to us but never taken: gaps in the publishers' sequence numbers
    commands_malformed: int = 0  # payloads that are not a little-endian CDR Float64 (skipped)

    def record(self, outcome: Outcome) -> None:
        """Count one command by its outcome."""
        self.commands_received += 1
        if outcome is Outcome.ACCEPTED:
            self.commands_accepted += 1
        elif outcome is Outcome.CLAMPED:
            self.commands_clamped += 1
        elif outcome is Outcome.REJECTED_NOT_FINITE:
            self.commands_rejected_not_finite += 1
        elif outcome is Outcome.REJECTED_OUT_OF_REACH:
            self.commands_rejected_out_of_reach += 1
        else:
            self.commands_rejected_out_of_limits += 1

    def as_dict(self) -> dict[str, int]:
        """Counter name -> value."""
        return asdict(self)


class SequenceGaps:
    """Counts commands lost between publishers and the subscription from the rmw's publication sequence numbers.

    Each publisher numbers its messages 1, 2, 3, ... (the DDS writer's sequence number, passed up in the
    message info); a number that skips ahead means the messages between were never taken: dropped by a
    full keep-last queue on either side, or undeserializable. The message info does not say which publisher
    sent a message, so numbers are matched to *tracks*: each goes to the track whose last number is the
    largest below it, or starts a new track (a new or restarted publisher, whose first number above 1 counts the
    ones before it as lost). With one publisher this is exact; with several interleaved ones it is exact while none
    loses messages, and an estimate otherwise. At most ``max_tracks`` tracks are kept (least recently used dropped).
    """

    def __init__(self, max_tracks: int = 16) -> None:
        self._lasts: list[int] = []  # one per track, least recently used first
        self._max_tracks = max_tracks

    def observe(self, seq: int) -> int:
        """Record sequence number ``seq``; return how many numbers it skipped (newly lost messages)."""
        lasts = self._lasts
        best = -1
        for i, last in enumerate(lasts):
            if last < seq and (best < 0 or last > lasts[best]):
                best = i
        if best < 0:
            if len(lasts) >= self._max_tracks:
                del lasts[0]
            lasts.append(seq)
            return seq - 1  # a publisher numbers from 1: a first number above 1 means earlier ones never came
        lost = seq - lasts[best] - 1
        del lasts[best]
        lasts.append(seq)
        return lost


class Summary(NamedTuple):
    """One diagnostic status: level, one-line message, (key, value) pairs."""

    level: Level
    message: str
    values: list[tuple[str, str]]


def summarize(cfg: AntennaConfig, last: Decision | None, last_command: float | None,
              state: LinkageState | None, counters: Counters, states_computed: int,
              states_reused: int, lost_since_last: int = 0) -> Summary:
    """Build the status from the last command (raw, rad), its decision, the state at the served angle.

    ``lost_since_last``: commands lost since the previous status; more than ``LOST_WARN_THRESHOLD`` is a WARN.
    """
    values: list[tuple[str, str]] = []
    level, message = Level.OK, 'waiting for the first command'
    if last is not None and last_command is not None:
        values += [('last_command_rad', repr(last_command)), ('last_command_outcome', last.outcome.value)]
        if last.outcome is not Outcome.ACCEPTED:
            level, message = Level.WARN, last.reason
    if state is not None:
        theta = float(state.theta)
        tau_in = float(state.input_torque)
        tau_motor = motor_torque(cfg, tau_in)
        reach = cfg.linkage.reach()
        reach_margin = reach.theta_max - abs(theta)
        if reach.theta_gap > 0.0:
            reach_margin = min(reach_margin, abs(theta) - reach.theta_gap)
        out_margin = cfg.output_torque_limit - abs(tau_in)
        motor_margin = cfg.motor_torque_limit - abs(tau_motor)
        transmission = float(state.transmission_angle)
        values += [
            ('theta_rad', repr(theta)), ('theta_deg', repr(math.degrees(theta))),
            ('gamma_rad', repr(float(state.gamma))), ('delta_rad', repr(float(state.delta))),
            ('theta_min_margin_rad', repr(theta - cfg.theta_min)),
            ('theta_max_margin_rad', repr(cfg.theta_max - theta)),
            ('reach_margin_rad', repr(reach_margin)),
            ('transmission_angle_deg', repr(math.degrees(transmission))),
            ('mechanical_advantage', repr(float(state.mechanical_advantage))),
            ('input_torque_nm', repr(tau_in)), ('motor_torque_nm', repr(tau_motor)),
            ('output_torque_margin_nm', repr(out_margin)), ('motor_torque_margin_nm', repr(motor_margin)),
        ]
        if out_margin < 0.0 or motor_margin < 0.0:
            level = Level.ERROR
            message = (f'drive cannot hold the load at theta={theta:.6g} rad: rocker torque {tau_in:.6g} N m '
                       f'(limit {cfg.output_torque_limit:g}), motor torque {tau_motor:.6g} N m '
                       f'(limit {cfg.motor_torque_limit:g})')
        elif level is Level.OK and abs(transmission - 0.5 * math.pi) > 0.5 * math.pi - cfg.transmission_angle_min:
            level = Level.WARN
            message = f'poor transmission angle {math.degrees(transmission):.4g} deg'
        elif level is Level.OK:
            message = 'ok'
    if lost_since_last > LOST_WARN_THRESHOLD and level is not Level.ERROR:
        lost = (f'{lost_since_last} commands lost since the previous status ({counters.commands_lost} in all): '
                'they came faster than the node takes them and a queue dropped the oldest')
        message = lost if level is Level.OK else f'{message}; {lost}'
        level = Level.WARN
    values += [(k, str(v)) for k, v in counters.as_dict().items()]
    values += [('states_computed', str(states_computed)), ('states_reused', str(states_reused))]
    return Summary(level, message, values)


#: The task part of fourbar_node's status name.
DIAGNOSTIC_TASK = 'antenna tilt linkage'


def status_name(node: str, task: str = DIAGNOSTIC_TASK) -> str:
    """A status's name from the node's fully qualified name: diagnostic_updater's ``<node name>: <task>`` with the
    namespace before it and no leading slash (``fourbar_node: <task>`` in /, ``tilt/fourbar_node: <task>`` in
    /tilt), so that two axes' statuses stay apart on one /diagnostics."""
    return f'{node.lstrip("/")}: {task}'


def command_rate(commands: int, seconds: float) -> list[tuple[str, str]]:
    """The command rate over the window since the previous status, under diagnostic_updater's frequency keys.

    ``commands`` received in ``seconds`` of the steady clock (wall time, also under sim time).
    """
    hz = commands / seconds if seconds > 0.0 else 0.0
    return [('Events in window', str(commands)), ('Duration of window (s)', repr(seconds)),
            ('Actual frequency (Hz)', repr(hz))]
