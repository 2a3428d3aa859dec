"""fourbar_drive_bridge: a Python drive (``DriveBackend``) on the topics of the topic-based hardware plugin.

Commands (sensor_msgs/JointState) in, through ``fourbar_ros.drive.rules``, to the backend; its readings out as
joint states at ``state_rate`` Hz; diagnostics once a second. With ``hardware_component`` set, the bridge asks the
controller manager (``controller_manager``, its node name) to activate that component after a reading in range
(``rules.Activation``). docs/how-to/drive-bridge.md.
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
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState

from fourbar_ros.config.antenna_config import AntennaConfig, default_config, load_config
from fourbar_ros.config.robot_model import driven_angle
from fourbar_ros.core.errors import one_line
from fourbar_ros.drive.backend import DriveBackend, SimulatedBackend
from fourbar_ros.drive.rules import ACTIVE, WATCHDOG_TIMEOUT_S, Activation, DriveLimits, DriveRules
from fourbar_ros.motion.limits import JointLimits
from fourbar_ros.rules.diagnostics import status_name
from fourbar_ros.runtime.executor import MessageInfoCallback
from fourbar_ros.runtime.problem_log import ProblemLog

NODE_NAME = 'fourbar_drive_bridge'
#: The ``backend`` parameter's value for the in-memory drive.
SIMULATED = 'simulated'
#: The plugin's own defaults (its hardware parameters ``joint_commands_topic`` and ``joint_states_topic``).
COMMANDS_TOPIC, STATES_TOPIC = '/robot_joint_commands', '/robot_joint_states'
DIAGNOSTICS_PERIOD_S = 1.0
#: rmw's "no sequence number" (RMW_MESSAGE_INFO_SEQUENCE_NUMBER_UNSUPPORTED, the largest uint64).
SEQUENCE_UNSUPPORTED = 2**64 - 1
_RELIABLE: Callable[..., Any] = QoSProfile  # rclpy's constructor is unannotated


class BackendError(ValueError):
    """A parameter of the bridge (its ``backend`` above all) that names nothing usable (one line)."""


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
            ('state_rate', 100.0), ('watchdog_timeout', WATCHDOG_TIMEOUT_S), ('hardware_component', ''),
            ('controller_manager', 'controller_manager'))}
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
        self.activation: Activation | None = None
        if p['hardware_component']:
            self._manage(str(p['hardware_component']), str(p['controller_manager']).rstrip('/'))

    def _manage(self, component: str, manager: str) -> None:
        """Activate ``component`` of the controller manager ``manager`` after a reading in range (rules.Activation):
        its activity (reliable, transient local, as the manager publishes it) and its set_hardware_component_state.
        controller_manager_msgs is imported here only: the bridge without a component needs no ros2_control."""
        try:  # untyped messages: Any
            activity: Any = importlib.import_module('controller_manager_msgs.msg').ControllerManagerActivity
            service: Any = importlib.import_module('controller_manager_msgs.srv').SetHardwareComponentState
            self._lifecycle_state: Any = importlib.import_module('lifecycle_msgs.msg').State
        except ImportError as exc:
            raise BackendError(f'hardware_component {component!r} needs controller_manager_msgs (ros2_control): '
                               f'{one_line(exc)}') from None
        self.activation = Activation(self.rules.limits, self.joint, component)
        self._request_type = service
        self._set_state = self.create_client(service, f'{manager}/set_hardware_component_state')
        on_activity = self.problems.guard.wrap('activity', MessageInfoCallback(self._on_activity))
        self.create_subscription(
            activity, f'{manager}/activity', on_activity,
            _RELIABLE(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL))

    def _on_activity(self, msg: Any, info: dict[str, Any]) -> None:
        assert self.activation is not None
        sequence = info.get('publication_sequence_number')
        if sequence is not None and not 0 < sequence < SEQUENCE_UNSUPPORTED:
            sequence = None
        states = [c.state.label for c in msg.hardware_components if c.name == self.activation.component]
        line = self.activation.on_activity(sequence, states[0] if states else None)
        if line is not None:
            self._info(line)

    def _activate(self, position: float) -> None:
        """Ask the manager for the component active; its answer is logged (rules.Activation.on_response)."""
        assert self.activation is not None
        request = self._request_type.Request()
        request.name = self.activation.component
        state = self._lifecycle_state
        request.target_state = state(id=state.PRIMARY_STATE_ACTIVE, label=ACTIVE)
        future = self._set_state.call_async(request)
        result: Callable[[], Any] = future.result
        failure: Callable[[], Any] = future.exception
        when_done: Callable[[Callable[[object], None]], None] = future.add_done_callback

        def done(_: object) -> None:
            assert self.activation is not None
            response = result() if failure() is None else None
            ok, label = (bool(response.ok), str(response.state.label)) if response is not None else (False, '')
            line = self.activation.on_response(ok, label)
            if line is not None and ok:
                self._info(line)
            elif line is not None:
                self.problems.error('activation', line)
        when_done(self.problems.guard.wrap('activation', done))

    def _log(self, level: str, line: str) -> None:
        get_logger: Callable[[], Any] = self.get_logger  # rclpy's logger accessor is unannotated
        logger = get_logger()
        (logger.error if level == 'error' else logger.warning)(line)

    def _info(self, line: str) -> None:
        get_logger: Callable[[], Any] = self.get_logger  # rclpy's logger accessor is unannotated
        get_logger().info(line)

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
            if self.activation is not None:
                self._after_reading(report.position)
        held = self.rules.held
        self._write(self.rules.on_tick(now), held)

    def _after_reading(self, position: float) -> None:
        assert self.activation is not None
        subscribed: Callable[[], int] = self.states.get_subscription_count
        ready: Callable[[], bool] = self._set_state.service_is_ready
        action = self.activation.on_reading(position, subscribed() > 0 and ready(), self._now())
        if action == ACTIVE:
            self._activate(position)
        elif action is not None:
            self.problems.error('activation', action)

    def diagnostic_status(self) -> DiagnosticStatus:
        """The bridge's status: WARN with no reading yet or held, values its counters."""
        status = DiagnosticStatus()
        status.name = status_name(self.get_fully_qualified_name(), 'drive')
        status.hardware_id = self.joint
        status.message = self.rules.status
        status.level = DiagnosticStatus.WARN if self.rules.report is None or self.rules.held else DiagnosticStatus.OK
        activation = self.activation
        if activation is not None and activation.refused and activation.manager_state != ACTIVE:
            status.level, status.message = DiagnosticStatus.ERROR, activation.refused
        values = [('backend', self.backend_name), *((k, str(v)) for k, v in asdict(self.rules.counters).items()),
                  ('read_errors', str(self.read_errors)), ('write_errors', str(self.write_errors)),
                  *self.problems.guard.diagnostic_values()]
        if activation is not None:
            values += [('hardware_component', activation.component),
                       ('hardware_state', activation.manager_state or 'not heard'),
                       ('activations', str(activation.activations)), ('activation', activation.last_line)]
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
