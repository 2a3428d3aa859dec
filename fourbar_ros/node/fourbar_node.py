"""fourbar_node: antenna angle commands in; joint states, input torque, diagnostics and markers out.

In the actuator modes the front end of a ros2_control drive (node.actuation, node.completion). It only adapts
messages and parameters: what a message becomes is fourbar_ros.rules. Topics: docs/reference/topics.md;
parameters: docs/reference/parameters.md; why: docs/explanation/node.md."""

from __future__ import annotations

import time
from collections.abc import Callable, Collection, Sequence
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock, ROSClock
from rclpy.clock_type import ClockType
from rclpy.exceptions import ParameterNotDeclaredException
from rclpy.impl.rcutils_logger import RcutilsLogger
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos_overriding_options import QoSOverridingOptions
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64
from visualization_msgs.msg import MarkerArray

from fourbar_ros.config.antenna_config import (
    AntennaConfig,
    ConfigError,
    config_from_values,
    declared_values,
    unknown_in_node_sections,
)
from fourbar_ros.config.params import PARAMETERS_BY_NAME, is_foreign
from fourbar_ros.config.robot_model import check_robot_model_kept
from fourbar_ros.core.antenna import LinkageState
from fourbar_ros.core.errors import FourBarError, one_line
from fourbar_ros.core.loads import Pose, pose_solver, solve
from fourbar_ros.interface.cdr import MalformedCdrError, read_float64
from fourbar_ros.interface.topics import (
    COMMAND,
    DIAGNOSTICS,
    INPUT_TORQUE,
    JOINT_STATES,
    MARKERS,
    NODE_NAME,
    SENSOR_NONE,
    Mode,
)
from fourbar_ros.node.actuation import Actuation
from fourbar_ros.node.completion import MeasuredCompletion
from fourbar_ros.node.markers import LinkageMarkers
from fourbar_ros.node.model_check import LiveModelCheck
from fourbar_ros.node.param_descriptors import declarations
from fourbar_ros.node.qos import qos
from fourbar_ros.node.timers import periodic_timer
from fourbar_ros.node.trajectory_goals import follow_joint_trajectory
from fourbar_ros.rules.diagnostics import Counters, Level, SequenceGaps, command_rate, status_name, summarize
from fourbar_ros.rules.marker_geometry import linkage_points
from fourbar_ros.rules.outgoing import actuation_contract, check_replan_tolerance
from fourbar_ros.rules.outputs import JointStateRule
from fourbar_ros.rules.policy import Decision, Outcome, Policy, decide
from fourbar_ros.rules.state_cache import StateCache
from fourbar_ros.runtime.executor import MessageInfoCallback
from fourbar_ros.runtime.problem_log import ProblemLog
from fourbar_ros.runtime.publishers import publish, subscription_count

WARN_THROTTLE_S = 1.0
#: Steady-clock delay (s) after which a node on sim time without /clock says so.
NO_CLOCK_WARN_S = 3.0


class FourBarNode(Node):
    """The antenna tilt node. Raises ConfigError from the constructor if its parameters are invalid."""

    def __init__(self, node_name: str = NODE_NAME, *, params_files: Sequence[str] = (),
                 command_line_names: Collection[str] = (), **kwargs: Any) -> None:
        """``params_files`` and ``command_line_names`` (``-p name:=...``) only say which unknown parameter
        names were addressed to this node (warned about) rather than to the whole robot (ignored)."""
        super().__init__(node_name, **kwargs)
        # rclpy's logger and destroy_node are unannotated: bind them to typed names once.
        get_logger: Callable[[], RcutilsLogger] = self.get_logger
        logger = get_logger()
        self._ros_clock = self.get_clock()
        self._warn: Callable[..., object] = logger.warning
        self.info: Callable[..., object] = logger.info
        self._error: Callable[..., object] = logger.error
        self._debug: Callable[..., object] = logger.debug
        self.problems = ProblemLog(self._log_problem, WARN_THROTTLE_S)
        #: the callback boundary: every callback is handed to rclpy through ``guard.wrap`` (never raises)
        self.guard = guard = self.problems.guard
        try:
            self._config = self._validated_overrides()
            contract = (None if self._config.mode == Mode.OPEN_LOOP.value
                        else actuation_contract(self._config, namespace=self.get_namespace()))
            if self._config.mode == Mode.TRAJECTORY.value and self._config.trajectory_interface == 'action':
                follow_joint_trajectory()  # refuses to start, in one line, where control_msgs is missing
            constructor_overrides: list[Parameter] = kwargs.get('parameter_overrides') or []
            explicit = set(command_line_names) | {p.name for p in constructor_overrides}
            for path in params_files:
                explicit.update(unknown_in_node_sections(path, self.get_name(), self.get_namespace()))
        except ConfigError:
            destroy_node(self)
            raise
        self._report_unknown_overrides(explicit)
        self.declare_parameters('', list(declarations(self._config.as_values())))
        self.actuation: Actuation | None = None  # set below in the actuator modes; parameter changes check it
        self.add_on_set_parameters_callback(guard.wrap('set_parameters', self._on_set_parameters, refused))
        self.add_post_set_parameters_callback(guard.wrap('after_set_parameters', self._after_set_parameters))
        self._pending: AntennaConfig | None = None

        self.counters = Counters()
        self.gaps = SequenceGaps()
        self._lost_reported = 0  # commands_lost at the previous diagnostics status
        #: (steady time in s, commands_received) at the previous diagnostics status: the command-rate window
        self._rate_window = (time.monotonic(), 0)
        self.cache: StateCache[Pose] = StateCache(pose_solver(self._config))
        self._last_command: float | None = None
        self._last_decision: Decision | None = None
        self._served: float | None = None
        #: (served theta rad, configuration generation, its pose): what the joint_state_rate timer republishes
        self._held: tuple[float, int, Pose] | None = None
        self._answered = False  # a per-command JointState went out since the last joint_state_rate tick
        self._generation = 0  # bumped by every configuration change
        self._marker_key: tuple[float, int, int] | None = None
        self._apply(self._config)

        qos_options = QoSOverridingOptions.with_default_policies()
        self._joint_pub = self.create_publisher(JointState, JOINT_STATES.name, qos(JOINT_STATES),
                                                qos_overriding_options=qos_options)
        self._torque_pub = self.create_publisher(Float64, INPUT_TORQUE.name, qos(INPUT_TORQUE),
                                                 qos_overriding_options=qos_options)
        self._marker_pub = self.create_publisher(MarkerArray, MARKERS.name, qos(MARKERS),
                                                 qos_overriding_options=qos_options)
        self._diag_pub = self.create_publisher(DiagnosticArray, DIAGNOSTICS.name, qos(DIAGNOSTICS))
        # A command's subscription counts and publishes as single C calls (fourbar_ros.runtime.publishers).
        self._joints_heard, self._torque_heard = map(subscription_count, (self._joint_pub, self._torque_pub))
        self._send_joints, self._send_torque = map(publish, (self._joint_pub, self._torque_pub))
        # Two parameters: rclpy then passes the message info, in the form each executor uses.
        self._command_sub = self.create_subscription(
            Float64, COMMAND.name, guard.wrap('sub_antenna_angle_cmd', MessageInfoCallback(self._on_command)),
            qos(COMMAND), qos_overriding_options=qos_options, raw=True)
        self._diag_timer = periodic_timer(self, self._config.diagnostics_period,
                                          guard.wrap('diagnostics_timer', self._on_diagnostics_timer))
        self._marker_timer = periodic_timer(self, self._config.marker_period,
                                            guard.wrap('marker_timer', self._on_marker_timer))
        # Actuator modes: served commands become motion (node/actuation.py); joint_states carries the measured
        # state, completed here (node/completion.py), never the commanded pose. One subscription to the measured
        # joint: the completion passes each good measurement on to the motion's start state.
        self._publishes_pose = self._config.mode == Mode.OPEN_LOOP.value
        self.completion: MeasuredCompletion | None = None
        self.model_check: LiveModelCheck | None = None  # an antenna sensor against the completed angle
        if not self._publishes_pose:
            assert contract is not None
            self.actuation = Actuation(self, lambda: self._config, self.problems, contract, subscribe_measured=False)
            if self._config.antenna_sensor_type != SENSOR_NONE:
                self.model_check = LiveModelCheck(self, self._config, lambda: self._config, qos, self.problems,
                                                  on_slip=self.actuation.on_slip)
            self.completion = MeasuredCompletion(
                self, self._config, self._joint_pub, qos, self.problems, on_measured=self.actuation.note_measured,
                on_completed=self._on_completed)
        if self._config.joint_state_rate > 0.0 and self._publishes_pose:
            self._joint_state_timer = periodic_timer(self, 1.0 / self._config.joint_state_rate,
                                                     guard.wrap('joint_state_timer', self._on_joint_state_timer))
        # Under sim time the timers above run on the ROS clock (fourbar_ros.node.timers), which stands still at 0
        # until /clock runs; this one runs on the steady clock so that case is reported, once per episode.
        self._clock_warned = False
        self._clock_check = self.create_timer(NO_CLOCK_WARN_S, guard.wrap('check_sim_clock', self._check_sim_clock),
                                              clock=Clock(clock_type=ClockType.STEADY_TIME))

    # ------------------------------------------------------------------ logging

    def _log_problem(self, level: str, line: str) -> None:
        # rclpy's logger refuses two severities from one call site: one call per severity.
        if level == 'warn':
            self._warn(line)
        else:
            self._error(line)

    # ------------------------------------------------------------------ configuration

    def _startup_values(self) -> dict[str, object]:
        """Every startup value rcl parsed for this node (params files, ``-p``, constructor overrides).

        rclpy has no public accessor for them before they are declared, and declaring first would let rclpy
        refuse a bad value with its own message instead of our one line naming the parameter; so this reads
        rclpy's ``_parameter_overrides``.
        """
        return {name: p.value for name, p in self._parameter_overrides.items()}

    def _validated_overrides(self) -> AntennaConfig:
        """Validate the startup values of our parameters before declaring; other names are ignored (ROS)."""
        return config_from_values(declared_values(self._startup_values()))

    def _report_unknown_overrides(self, explicit: Collection[str]) -> None:
        """Warn about unknown names addressed to this node (probably typos); others only at debug level."""
        for name in self._startup_values():
            if name in PARAMETERS_BY_NAME or is_foreign(name):
                continue
            if name in explicit:
                self._warn(f'{name}: not a fourbar_node parameter; ignored (known: {", ".join(PARAMETERS_BY_NAME)})')
            else:
                self._debug(f'{name}: not a fourbar_node parameter (from a wildcard section); ignored')

    @property
    def config(self) -> AntennaConfig:
        """The running configuration."""
        return self._config

    def _apply(self, cfg: AntennaConfig) -> None:
        self._config = cfg
        self._theta_min, self._theta_max = cfg.theta_min, cfg.theta_max
        self._policy = Policy(cfg.out_of_limits)
        self._reach = cfg.linkage.reach()
        self._joint_rule = JointStateRule(cfg)  # a velocity across a configuration change means nothing
        self._pose = pose_solver(cfg)
        # One JointState and one Float64, refilled per command: publish() serializes synchronously, so reuse is
        # safe, and it spares building a message (~5 us, a sixth of the node's cost over a bare relay).
        self._joint_msg = JointState()
        self._joint_msg.name = list(cfg.joint_names)
        self._torque_msg = Float64()
        self._markers = LinkageMarkers(cfg.frame_id)
        self.cache.reset(self._pose)
        self._generation += 1

    def _on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        """Validate the running configuration with the proposed changes, as a whole.

        rclpy calls this only after its own checks (declared, type, range, read-only) passed; every
        rejection, theirs or ours, is counted and logged in ``set_parameters_atomically``/``set_parameters``.
        """
        self._pending = None
        proposed: dict[str, object] = dict(self._config.as_values())
        changed = [p.name for p in params if not is_foreign(p.name)]
        for p in params:
            if not is_foreign(p.name):
                proposed[p.name] = p.value
        try:
            pending = config_from_values(proposed, changed)
            if self.actuation is not None:
                check_replan_tolerance(pending, self.actuation.contract)
                check_robot_model_kept(self._config, pending, changed)
        except ConfigError as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        self._pending = pending
        return SetParametersResult(successful=True)

    def _count_result(self, result: SetParametersResult) -> SetParametersResult:
        if not result.successful:
            self.counters.parameter_changes_rejected += 1
            self._warn(f'parameter change rejected: {result.reason}')
        return result

    def _count_undeclared(self, exc: ParameterNotDeclaredException) -> None:
        self.counters.parameter_changes_rejected += 1
        self._warn(f'parameter change rejected: {one_line(exc)}')

    # Every run-time change (the set_parameters and set_parameters_atomically services, ros2 param, in-process
    # calls) passes through these two; rclpy refuses unknown names, wrong types, out-of-range values and
    # read-only parameters before our callback runs, so the counting is done here, around all of it.
    def set_parameters_atomically(self, parameter_list: list[Parameter]) -> SetParametersResult:
        """rclpy's, with every rejection counted (``parameter_changes_rejected``) and logged."""
        try:
            return self._count_result(super().set_parameters_atomically(parameter_list))
        except ParameterNotDeclaredException as exc:
            self._count_undeclared(exc)
            raise

    def set_parameters(self, parameter_list: list[Parameter]) -> list[SetParametersResult]:
        """rclpy's (one parameter at a time), with every rejection counted and logged."""
        try:
            results: list[SetParametersResult] = super().set_parameters(parameter_list)
        except ParameterNotDeclaredException as exc:
            self._count_undeclared(exc)
            raise
        for result in results:
            self._count_result(result)
        return results

    def _after_set_parameters(self, params: list[Parameter]) -> None:
        if self._pending is not None and any(not is_foreign(p.name) for p in params):
            self._apply(self._pending)
            self.counters.parameter_changes_accepted += 1
        self._pending = None

    # ------------------------------------------------------------------ commands

    def _on_command(self, raw: bytes, info: dict[str, Any]) -> None:
        # Latency-critical path first (check, solve, publish joint_states); bookkeeping after.
        counters = self.counters
        seq = info['publication_sequence_number']
        if seq is not None:  # the rmw's per-publisher number: a gap is a command we never took
            counters.commands_lost += self.gaps.observe(seq)
        try:
            command = read_float64(raw)
        except MalformedCdrError as exc:
            counters.commands_malformed += 1
            self.problems.warn('command payload', f'{COMMAND.name}: payload skipped: {exc}')
            return
        self._last_command = command
        decision = decide(command, self._theta_min, self._theta_max, self._policy, self._reach)
        if decision.outcome is Outcome.ACCEPTED:
            theta = command
            self._last_decision = None
            clamped = None
        else:
            self._last_decision = decision
            counters.record(decision.outcome)
            self.problems.warn(f'command {decision.outcome.value}', decision.reason)
            if decision.theta is None:
                return
            theta, clamped = decision.theta, decision
        self._served = theta
        state: Pose | None = None
        if self.actuation is not None:
            self.actuation.command(theta)
            if self.completion is not None:
                self.completion.set_commanded(theta)
        elif self._joints_heard() > 0:
            state = self._solve(theta)
            if state is not None:
                self._publish_joints(theta, state)
        if clamped is None:
            counters.commands_received += 1
            counters.commands_accepted += 1
        if self._torque_heard() > 0:
            if state is None:
                state = self._solve(theta)
            if state is not None:
                self._torque_msg.data = state.input_torque
                self._send_torque(self._torque_msg)
                counters.input_torque_published += 1
        else:
            counters.input_torque_skipped += 1
            if state is None:
                counters.commands_not_solved += 1

    def _on_completed(self, stamp_ns: int, position: float) -> None:
        """A measurement completed (its stamp ns, the driven joint rad): the command's fate and the model check."""
        assert self.actuation is not None and self.completion is not None and self.completion.theta is not None
        self.actuation.note_theta(self.completion.theta)
        if self.model_check is not None:
            self.model_check.on_completed(stamp_ns, position)

    def _solve(self, theta: float) -> Pose | None:
        try:
            return self.cache.get(theta)
        except FourBarError as exc:  # limits lie inside the reach, so only a core bug gets here
            self.problems.error('solve', f'cannot solve theta={theta!r}: {exc}')
            return None

    def _publish_joints(self, theta: float, state: Pose) -> None:
        now = self._ros_clock.now()
        msg = self._joint_msg
        msg.header.stamp = now.to_msg()
        msg.position, msg.velocity, msg.effort = self._joint_rule.sample(theta, state, now.nanoseconds)
        self._send_joints(msg)
        self.counters.joint_states_published += 1
        self._held = (theta, self._generation, state)
        self._answered = True

    def _on_joint_state_timer(self) -> None:
        """Republish the last served pose with a fresh stamp and zero velocities (not a sample of the velocity
        rule, not counted), so a subscriber that arrives after the command gets the pose too. Only after a
        whole period without a per-command JointState: a command stream is never interleaved with repeats."""
        served = self._served
        answered, self._answered = self._answered, False
        if served is None or answered or not self._publishes_pose or self._joint_pub.get_subscription_count() == 0:
            return
        held = self._held
        if held is None or held[:2] != (served, self._generation):  # not published yet (nobody listened then)
            try:
                held = (served, self._generation, self._pose(served))  # outside the cache: its counters stay
            except FourBarError:  # the served angle is invalid under a newer configuration
                return
            self._held = held
        msg = self._joint_msg
        msg.header.stamp = self._ros_clock.now().to_msg()
        msg.position, msg.velocity, msg.effort = self._joint_rule.held(served, held[2])
        self._joint_pub.publish(msg)

    # ------------------------------------------------------------------ markers

    def _on_marker_timer(self) -> None:
        """Publish the drawing if someone listens and the pose, configuration or audience changed."""
        subscribers = self._marker_pub.get_subscription_count()
        served = self._served
        if subscribers == 0 or served is None:
            self.counters.markers_skipped += 1
            return
        key = (served, self._generation, subscribers)
        if key == self._marker_key:
            self.counters.markers_skipped += 1
            return
        try:
            state = self.cache.get(served)
        except FourBarError:  # the served angle is invalid under a newer configuration
            self.counters.markers_skipped += 1
            return
        cfg = self._config
        pts = linkage_points(cfg.frame_length, cfg.rocker_ab_length, cfg.coupler_length, cfg.rocker_cd_length,
                             served, state.gamma, state.delta)
        self._marker_pub.publish(self._markers.update(pts, self.get_clock().now().to_msg()))
        self._marker_key = key
        self.counters.markers_published += 1

    # ------------------------------------------------------------------ diagnostics

    def diagnostic_status(self) -> DiagnosticStatus:
        """The current status message (also what the timer publishes)."""
        state: LinkageState | None = None
        if self._served is not None:
            try:  # the full state (rates, transmission angle) only here, once per period
                state = solve(self._config, self._served)
            except FourBarError:
                state = None
        last = self._last_decision
        if last is None and self._last_command is not None:  # the fast path stores no Decision
            last = Decision(self._last_command, Outcome.ACCEPTED, '')
        summary = summarize(self._config, last, self._last_command, state, self.counters,
                            self.cache.computed, self.cache.reused,
                            lost_since_last=self.counters.commands_lost - self._lost_reported)
        since, received = self._rate_window
        values = summary.values + command_rate(self.counters.commands_received - received, time.monotonic() - since)
        level, message = summary.level, summary.message
        if self.completion is not None:
            measured_level, measured_message, measured_values = self.completion.diagnostics()
            values += measured_values
            if measured_level > level:
                level, message = measured_level, measured_message
        if self.model_check is not None:
            check_level, check_message, check_values = self.model_check.diagnostics()
            values += check_values
            if check_level > level:
                level, message = check_level, check_message
        if self.actuation is not None:
            actuation_level, actuation_message, actuation_values = self.actuation.diagnostics()
            values += actuation_values
            if actuation_level > level:
                level, message = actuation_level, actuation_message
        values += self.guard.diagnostic_values()
        if self.guard.total and level < Level.WARN:
            level, message = Level.WARN, f'{self.guard.total} callback errors (see callback_errors_<callback>)'
        return DiagnosticStatus(
            level=bytes([int(level)]), name=status_name(self.get_fully_qualified_name()),
            message=message, hardware_id=self._config.hardware_id,
            values=[KeyValue(key=k, value=v) for k, v in values])

    def _on_diagnostics_timer(self) -> None:
        if self._diag_pub.get_subscription_count() == 0:
            self.counters.diagnostics_skipped += 1
            if self.actuation is not None:
                self.actuation.check_senders()  # logged with nobody on /diagnostics too
            return
        self.counters.diagnostics_published += 1
        msg = DiagnosticArray(status=[self.diagnostic_status()])
        msg.header.stamp = self.get_clock().now().to_msg()
        self._diag_pub.publish(msg)
        self._lost_reported = self.counters.commands_lost
        self._rate_window = (time.monotonic(), self.counters.commands_received)

    # ------------------------------------------------------------------ sim time

    def _check_sim_clock(self) -> None:
        """Warn once if use_sim_time is on and no /clock has arrived (the ROS clock still reads 0)."""
        clock = self._ros_clock
        waiting = isinstance(clock, ROSClock) and clock.ros_time_is_active and clock.now().nanoseconds == 0
        if waiting and not self._clock_warned:
            self._warn(f'use_sim_time is true but no /clock message arrived in {NO_CLOCK_WARN_S:g} s: stamps are 0, '
                       'joint velocities are empty and diagnostics and markers (timers on the ROS clock) are not '
                       'published until /clock runs (e.g. ros2 bag play --clock)')
        self._clock_warned = waiting


def refused(exc: Exception) -> SetParametersResult:
    """What a parameter-set callback that raised answers (its exception counted and logged by the guard)."""
    return SetParametersResult(successful=False, reason=f'{type(exc).__name__}: {one_line(exc)}')


def destroy_node(node: Node) -> None:
    """``node.destroy_node()`` (rclpy's is unannotated)."""
    destroy: Callable[[], object] = node.destroy_node
    destroy()
