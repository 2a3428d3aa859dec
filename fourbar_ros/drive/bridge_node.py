"""fourbar_drive_bridge: a Python drive (``DriveBackend``) on the topics of the topic-based hardware plugin.

Commands (sensor_msgs/JointState) in, through ``fourbar_ros.drive.rules``, to the backend; its readings out as
joint states at ``state_rate`` Hz; diagnostics once a second. docs/how-to/drive-bridge.md.
"""

from __future__ import annotations

import importlib
import math
import time
from collections.abc import Callable
from dataclasses import asdict
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.clock import Clock
from rclpy.clock_type import ClockType
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState

from fourbar_ros.config.antenna_config import AntennaConfig, default_config, load_config
from fourbar_ros.config.robot_model import driven_angle
from fourbar_ros.core.errors import one_line
from fourbar_ros.drive.backend import DriveBackend, SimulatedBackend
from fourbar_ros.drive.rules import WATCHDOG_TIMEOUT_S, DriveLimits, DriveRules
from fourbar_ros.motion.limits import JointLimits
from fourbar_ros.runtime.problem_log import ProblemLog

NODE_NAME = 'fourbar_drive_bridge'
#: The ``backend`` parameter's value for the in-memory drive.
SIMULATED = 'simulated'
#: The plugin's own defaults (its hardware parameters ``joint_commands_topic`` and ``joint_states_topic``).
COMMANDS_TOPIC, STATES_TOPIC = '/robot_joint_commands', '/robot_joint_states'
DIAGNOSTICS_PERIOD_S = 1.0
_RELIABLE: Callable[..., Any] = QoSProfile  # rclpy's constructor is unannotated


class BackendError(ValueError):
    """A ``backend`` parameter that names nothing usable (one line)."""


def load_backend(spec: str, cfg: AntennaConfig, simulated_position: float) -> DriveBackend:
    """The backend ``spec`` names: SIMULATED (at ``simulated_position`` rad, NaN: the model's initial value), or
    'module:Class', called with the configuration."""
    if spec == SIMULATED:
        position = driven_angle(cfg) if math.isnan(simulated_position) else simulated_position
        return SimulatedBackend(position, JointLimits.from_config(cfg).at_rocker(1))
    module_name, _, name = spec.partition(':')
    try:
        factory: Callable[[AntennaConfig], Any] = getattr(importlib.import_module(module_name), name)
        backend = factory(cfg)
    except Exception as exc:
        raise BackendError(f'backend {spec!r}: {type(exc).__name__}: {one_line(exc)}') from None
    if not isinstance(backend, DriveBackend):
        raise BackendError(f'backend {spec!r} has not enable(), read(), write(position) and disable()')
    return backend


class DriveBridge(Node):
    """The bridge node; ``backend`` given (tests) replaces the one the parameter names."""

    def __init__(self, backend: DriveBackend | None = None, clock: Callable[[], float] = time.monotonic,
                 **kwargs: Any) -> None:
        super().__init__(NODE_NAME, **kwargs)
        p = {name: self.declare_parameter(name, value).value for name, value in (
            ('config_file', ''), ('backend', SIMULATED), ('simulated_position', math.nan),
            ('joint_commands_topic', COMMANDS_TOPIC), ('joint_states_topic', STATES_TOPIC),
            ('state_rate', 100.0), ('watchdog_timeout', WATCHDOG_TIMEOUT_S))}
        cfg = load_config(p['config_file']) if p['config_file'] else default_config()
        if not (p['state_rate'] > 0.0 and p['watchdog_timeout'] > 0.0):
            raise BackendError('state_rate and watchdog_timeout must be > 0')
        self.joint = cfg.driven_joint
        self.rules = DriveRules(DriveLimits.from_config(cfg, float(p['watchdog_timeout'])))
        self.backend = backend or load_backend(str(p['backend']), cfg, float(p['simulated_position']))
        self.backend_name = type(self.backend).__name__
        self._now = clock
        self.read_errors = self.write_errors = 0
        self.problems = ProblemLog(self._log)
        guard = self.problems.guard
        self.backend.enable()
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.states = self.create_publisher(JointState, p['joint_states_topic'], 10)
        self.diagnostics = self.create_publisher(DiagnosticArray, '/diagnostics', 10)
        self.create_subscription(JointState, p['joint_commands_topic'], guard.wrap('command', self._on_command),
                                 _RELIABLE(depth=10, reliability=ReliabilityPolicy.RELIABLE))
        self.create_timer(1.0 / p['state_rate'], guard.wrap('state', self._on_state), clock=steady)
        self.create_timer(DIAGNOSTICS_PERIOD_S, guard.wrap('diagnostics', self._on_diagnostics), clock=steady)

    def _log(self, level: str, line: str) -> None:
        get_logger: Callable[[], Any] = self.get_logger  # rclpy's logger accessor is unannotated
        logger = get_logger()
        (logger.error if level == 'error' else logger.warning)(line)

    def _write(self, target: float | None, held_before: str) -> None:
        if self.rules.held and self.rules.held != held_before:
            self.problems.warn('held', f'drive held: {self.rules.held}')
        if target is None:
            return
        try:
            self.backend.write(target)
        except Exception as exc:  # the user's code: counted, the node goes on
            self.write_errors += 1
            self.problems.error('write', f'backend write failed ({self.write_errors} so far): {one_line(exc)}')

    def _on_command(self, msg: JointState) -> None:
        names = list(msg.name)
        i = names.index(self.joint) if self.joint in names else -1
        position = float(msg.position[i]) if 0 <= i < len(msg.position) else None
        held = self.rules.held
        self._write(self.rules.on_command(self._now(), position), held)

    def _on_state(self) -> None:
        now = self._now()
        try:
            report = self.rules.on_reading(now, self.backend.read())
        except Exception as exc:  # the user's code: counted, the watchdog still runs
            report = None
            self.read_errors += 1
            self.problems.error('read', f'backend read failed ({self.read_errors} so far): {one_line(exc)}')
        if report is not None:
            msg = JointState()
            msg.header.stamp = self.get_clock().now().to_msg()
            msg.name = [self.joint]
            msg.position = [report.position]
            msg.velocity = [report.velocity]
            msg.effort = [] if report.effort is None else [report.effort]
            self.states.publish(msg)
        held = self.rules.held
        self._write(self.rules.on_tick(now), held)

    def diagnostic_status(self) -> DiagnosticStatus:
        """The bridge's status: WARN with no reading yet or held, values its counters."""
        status = DiagnosticStatus()
        status.name = f'{NODE_NAME}: drive'
        status.hardware_id = self.joint
        status.message = self.rules.status
        status.level = DiagnosticStatus.WARN if self.rules.report is None or self.rules.held else DiagnosticStatus.OK
        values = [('backend', self.backend_name), *((k, str(v)) for k, v in asdict(self.rules.counters).items()),
                  ('read_errors', str(self.read_errors)), ('write_errors', str(self.write_errors)),
                  *self.problems.guard.diagnostic_values()]
        status.values = [KeyValue(key=k, value=v) for k, v in values]
        return status

    def _on_diagnostics(self) -> None:
        msg = DiagnosticArray()
        msg.header.stamp = self.get_clock().now().to_msg()
        msg.status = [self.diagnostic_status()]
        self.diagnostics.publish(msg)

    def close(self) -> None:
        """Disable the backend (once), then destroy the node."""
        try:
            self.backend.disable()
        except Exception as exc:
            self.problems.error('disable', f'backend disable failed: {one_line(exc)}')
        destroy: Callable[[], object] = self.destroy_node
        destroy()
