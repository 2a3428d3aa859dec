"""fourbar_node: antenna angle commands in, rocker joint states, input torque, diagnostics and markers out.

Interface (relative names, so namespaces and remapping apply):
  sub  antenna_angle_cmd  std_msgs/Float64           commanded antenna angle theta, rad (+ tilts down)
  pub  joint_states       sensor_msgs/JointState     name [gamma_joint, delta_joint, coupler_joint], position
                                                     [gamma, delta, gamma + theta] rad (every movable joint of
                                                     `fourbar urdf`'s model); velocity rad/s by finite
                                                     difference of successive published positions (empty
                                                     when not meaningful); effort N m: driven rocker's torque,
                                                     0.0 for the other joints
  pub  input_torque       std_msgs/Float64           torque the driven rocker needs, N m (+ in the sense of q)
  pub  /diagnostics       diagnostic_msgs/DiagnosticArray   every diagnostics_period s
  pub  linkage_markers    visualization_msgs/MarkerArray    frame, rockers, coupler, joints, antenna arrow;
                                                     every marker_period s, only when subscribed and changed
QoS: keep-last 1000 for the command (best effort, see COMMAND_QOS) and the per-command outputs (reliable),
reliable keep-last 10 for markers and diagnostics; commands the queues drop are counted (commands_lost).
Each can be overridden with ``qos_overrides./<topic>.<publisher|subscription>.<policy>`` parameters.
Markers are not per command (drawing them costs more than the rest of a command): a timer publishes them
at most every marker_period s.
The node only adapts messages and parameters; the math is in fourbar_ros.antenna/loads and the
decisions in the pure modules command_policy, state_cache, joint_velocity, diagnostic_values.
"""

from __future__ import annotations

import argparse
import itertools
import signal
import sys
import time
from collections.abc import Callable, Collection, Sequence
from typing import Any, NoReturn

import rclpy
import rclpy.utilities
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock, ROSClock
from rclpy.clock_type import ClockType
from rclpy.exceptions import ParameterNotDeclaredException
from rclpy.executors import Executor
from rclpy.impl.rcutils_logger import RcutilsLogger
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.qos_overriding_options import QoSOverridingOptions
from rclpy.signals import SignalHandlerOptions
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
from fourbar_ros.config.robot_model import coupler_joint_position
from fourbar_ros.core.antenna import Driven, LinkageState
from fourbar_ros.core.errors import FourBarError
from fourbar_ros.core.loads import Pose, pose_solver, solve
from fourbar_ros.node.command_policy import Decision, Outcome, Policy, decide
from fourbar_ros.node.diagnostic_values import DIAGNOSTIC_TASK, Counters, SequenceGaps, command_rate, summarize
from fourbar_ros.node.executor import (
    DEFAULT_EXECUTOR,
    EXECUTOR_ENV,
    EXECUTORS,
    MessageInfoCallback,
    Spinner,
    create_executor,
    executor_kind,
)
from fourbar_ros.node.joint_velocity import Sample, velocity_step
from fourbar_ros.node.marker_geometry import linkage_points
from fourbar_ros.node.markers import LinkageMarkers
from fourbar_ros.node.param_descriptors import declarations
from fourbar_ros.node.state_cache import StateCache

NODE_NAME = 'fourbar_node'
#: Keep-last depth of the command subscription and the per-command outputs.
STREAM_DEPTH = 1000
#: The command subscription: best effort, keep-last STREAM_DEPTH. It matches reliable and best-effort
#: publishers alike, and one payload the middleware cannot take (an empty one) cannot stall the commands that
#: follow it from that publisher, as it does on a reliable subscription (Fast DDS keeps waiting for it). Lost
#: commands are counted either way (``commands_lost``); on one host best effort loses no more than reliable
#: keep-last, whose queues drop the oldest when full.
_qos_profile: Callable[..., QoSProfile] = QoSProfile  # rclpy's constructor is unannotated
COMMAND_QOS = _qos_profile(depth=STREAM_DEPTH, reliability=ReliabilityPolicy.BEST_EFFORT)
#: Keep-last depth of markers and diagnostics (latest state only matters).
STATUS_DEPTH = 10
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
        self._error: Callable[..., object] = logger.error
        self._debug: Callable[..., object] = logger.debug
        try:
            self._config = self._validated_overrides()
            constructor_overrides: list[Parameter] = kwargs.get('parameter_overrides') or []
            explicit = set(command_line_names) | {p.name for p in constructor_overrides}
            for path in params_files:
                explicit.update(unknown_in_node_sections(path, self.get_name(), self.get_namespace()))
        except ConfigError:
            destroy(self)
            raise
        self._report_unknown_overrides(explicit)
        self.declare_parameters('', list(declarations(self._config.as_values())))
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.add_post_set_parameters_callback(self._after_set_parameters)
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
        self._last_sample: Sample | None = None
        self._generation = 0  # bumped by every configuration change
        self._marker_key: tuple[float, int, int] | None = None
        self._apply(self._config)

        qos_options = QoSOverridingOptions.with_default_policies()
        self._joint_pub = self.create_publisher(JointState, 'joint_states', STREAM_DEPTH,
                                                qos_overriding_options=qos_options)
        self._torque_pub = self.create_publisher(Float64, 'input_torque', STREAM_DEPTH,
                                                 qos_overriding_options=qos_options)
        self._marker_pub = self.create_publisher(MarkerArray, 'linkage_markers', STATUS_DEPTH,
                                                 qos_overriding_options=qos_options)
        self._diag_pub = self.create_publisher(DiagnosticArray, '/diagnostics', STATUS_DEPTH)
        # Two parameters: rclpy then passes the message info, in the form each executor uses.
        self._command_sub = self.create_subscription(Float64, 'antenna_angle_cmd',
                                                     MessageInfoCallback(self._on_command),
                                                     COMMAND_QOS, qos_overriding_options=qos_options)
        self._diag_timer = self.create_timer(self._config.diagnostics_period, self._on_diagnostics_timer)
        self._marker_timer = self.create_timer(self._config.marker_period, self._on_marker_timer)
        # The timers above run on the ROS clock, which stands still at 0 under sim time until /clock runs;
        # this one runs on the steady clock so that case is reported, once per episode.
        self._clock_warned = False
        self._clock_check = self.create_timer(NO_CLOCK_WARN_S, self._check_sim_clock,
                                              clock=Clock(clock_type=ClockType.STEADY_TIME))

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
        self._velocity_timeout = cfg.velocity_timeout
        self._policy = Policy(cfg.out_of_limits)
        self._reach = cfg.linkage.reach()
        self._driven_first = cfg.driven is Driven.GAMMA
        # One JointState and one Float64, refilled per command: publish() serializes synchronously, so reuse is
        # safe, and it spares building a message (~5 us, a sixth of the node's cost over a bare relay).
        self._joint_msg = JointState()
        self._joint_msg.name = list(cfg.joint_names)
        self._torque_msg = Float64()
        self._markers = LinkageMarkers(cfg.frame_id)
        self.cache.reset(pose_solver(cfg))
        self._last_sample = None  # a velocity across a configuration change means nothing
        self._generation += 1

    def _on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        """Validate the running configuration with the proposed changes, as a whole.

        rclpy calls this only after its own checks (declared, type, range, read-only) passed; every
        rejection, theirs or ours, is counted and logged in ``set_parameters_atomically``/``set_parameters``.
        """
        proposed: dict[str, object] = dict(self._config.as_values())
        changed = [p.name for p in params if not is_foreign(p.name)]
        for p in params:
            if not is_foreign(p.name):
                proposed[p.name] = p.value
        try:
            self._pending = config_from_values(proposed, changed)
        except ConfigError as exc:
            self._pending = None
            return SetParametersResult(successful=False, reason=str(exc))
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

    def _on_command(self, msg: Float64, info: dict[str, Any]) -> None:
        # Latency-critical path first (check, solve, publish joint_states); bookkeeping after.
        command = msg.data
        counters = self.counters
        seq = info['publication_sequence_number']
        if seq is not None:  # the rmw's per-publisher number: a gap is a command we never took
            counters.commands_lost += self.gaps.observe(seq)
        self._last_command = command
        if self._theta_min <= command <= self._theta_max:  # accepted as is (NaN and inf fail here)
            theta = command
            self._last_decision = None
            clamped = None
        else:
            decision = decide(command, self._theta_min, self._theta_max, self._policy, self._reach)
            self._last_decision = decision
            counters.record(decision.outcome)
            self._warn(decision.reason, throttle_duration_sec=WARN_THROTTLE_S)
            if decision.theta is None:
                return
            theta, clamped = decision.theta, decision
        self._served = theta
        state: Pose | None = None
        if self._joint_pub.get_subscription_count() > 0:
            state = self._solve(theta)
            if state is not None:
                self._publish_joints(theta, state)
        if clamped is None:
            counters.commands_received += 1
            counters.commands_accepted += 1
        if self._torque_pub.get_subscription_count() > 0:
            if state is None:
                state = self._solve(theta)
            if state is not None:
                self._torque_msg.data = state.input_torque
                self._torque_pub.publish(self._torque_msg)
                counters.input_torque_published += 1
        else:
            counters.input_torque_skipped += 1
            if state is None:
                counters.commands_not_solved += 1

    def _solve(self, theta: float) -> Pose | None:
        try:
            return self.cache.get(theta)
        except FourBarError as exc:  # limits lie inside the reach, so only a core bug gets here
            self._error(f'cannot solve theta={theta!r}: {exc}', throttle_duration_sec=WARN_THROTTLE_S)
            return None

    def _publish_joints(self, theta: float, state: Pose) -> None:
        now = self._ros_clock.now()
        gamma, delta, torque = state
        positions = (gamma, delta, coupler_joint_position(gamma, theta))
        msg = self._joint_msg
        msg.header.stamp = now.to_msg()
        msg.position = list(positions)
        msg.velocity, self._last_sample = velocity_step(self._last_sample, Sample(now.nanoseconds, positions),
                                                        self._velocity_timeout)
        msg.effort = [torque, 0.0, 0.0] if self._driven_first else [0.0, torque, 0.0]
        self._joint_pub.publish(msg)
        self.counters.joint_states_published += 1

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
        # Named as diagnostic_updater names a task's status: '<node name>: <task>' (no namespace, no leading slash).
        return DiagnosticStatus(
            level=bytes([int(summary.level)]), name=f'{self.get_name()}: {DIAGNOSTIC_TASK}',
            message=summary.message, hardware_id=self._config.hardware_id,
            values=[KeyValue(key=k, value=v) for k, v in values])

    def _on_diagnostics_timer(self) -> None:
        if self._diag_pub.get_subscription_count() == 0:
            self.counters.diagnostics_skipped += 1
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


def destroy(node: Node) -> None:
    """``node.destroy_node()`` (rclpy's is unannotated)."""
    destroy_node: Callable[[], object] = node.destroy_node
    destroy_node()


def one_line(exc: BaseException) -> str:
    """The exception's text on one line (its class name if empty)."""
    text = ' '.join(str(exc).split())
    return text or exc.__class__.__name__


def params_files(argv: list[str]) -> list[str]:
    """The ``--params-file`` paths among ``argv``, in order."""
    return [path for flag, path in itertools.pairwise(argv) if flag == '--params-file']


def command_line_names(argv: list[str]) -> list[str]:
    """The parameter names set with ``-p name:=value`` (or ``--param``) among ``argv``."""
    return [arg.split(':=', 1)[0].rsplit(':', 1)[-1] for flag, arg in itertools.pairwise(argv)
            if flag in ('-p', '--param') and ':=' in arg]


def params_file_problem(argv: list[str]) -> str | None:
    """One line if a ``--params-file`` argument cannot be read, is larger than 1 MiB, is not YAML or holds an
    alias (rcl refuses those too), else None.

    Checked before rclpy.init, because rcl would log its own multi-line error first.
    """
    from fourbar_ros.config.rcl_yaml import params_file_problem as file_problem

    for flag, path in itertools.pairwise(argv):
        if flag == '--params-file' and (problem := file_problem(path)) is not None:
            return problem
    return None


#: Longest time (s) the spin loop waits for work before it looks at the stop flag again.
STOP_POLL_S = 0.1


class StopRequest:
    """Set by SIGINT/SIGTERM; the spin loop ends when it sees it.

    rclpy's own handlers shut the context down from the signal while a callback may still be running, so
    get_subscription_count, publish or the next wait set raise RCLError ("context is invalid") and SIGINT's
    KeyboardInterrupt can land inside take_message. This handler only sets a flag (Python runs it in the main
    thread between bytecodes); the loop then returns and main() destroys the node and shuts down, in order.
    """

    def __init__(self) -> None:
        self.signal: int | None = None
        self._wakers: list[Callable[[], None]] = []

    def __call__(self, signum: int, frame: object) -> None:
        self.signal = signum
        for wake in self._wakers:
            wake()

    def on_request(self, wake: Callable[[], None]) -> None:
        """Call ``wake()`` from the handler when a stop arrives (e.g. to end a running spin slice)."""
        self._wakers.append(wake)

    def install(self) -> None:
        """Handle SIGINT and SIGTERM in this process (main thread only)."""
        signal.signal(signal.SIGINT, self)
        signal.signal(signal.SIGTERM, self)

    @property
    def requested(self) -> bool:
        """True once a stop signal arrived."""
        return self.signal is not None


def spin_until_stopped(executor: Executor, stop: StopRequest, poll_s: float = STOP_POLL_S) -> None:
    """Run callbacks until ``stop`` is requested or the context ends.

    Spins in slices of at most ``poll_s`` s (an EventsExecutor must never wait without a deadline, see
    fourbar_ros.node.executor); a stop also ends the running slice, after the callback in progress.
    """
    spinner = Spinner(executor, poll_s)
    stop.on_request(spinner.request_stop)
    context_ok: Callable[[], bool] = executor.context.ok
    while not stop.requested and context_ok():
        spinner.spin_slice()


class UsageError(ValueError):
    """A bad command-line option of fourbar_node (not a ROS argument)."""


class _OptionParser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:
        raise UsageError(message)


def node_options(argv: Sequence[str]) -> argparse.Namespace:
    """The options of ``fourbar_node`` outside its ``--ros-args`` sections (``argv[0]`` is the program)."""
    parser = _OptionParser(prog='fourbar_node', description='The antenna tilt four-bar node.',
                           epilog='ROS arguments follow --ros-args, e.g. --ros-args --params-file config/antenna.yaml')
    parser.add_argument('--executor', choices=EXECUTORS, default=None,
                        help=f'rclpy executor that runs the callbacks (default: ${EXECUTOR_ENV}, else '
                             f'{DEFAULT_EXECUTOR}); see docs/node.md')
    return parser.parse_args(non_ros_args(argv)[1:])


def non_ros_args(argv: Sequence[str]) -> list[str]:
    """``argv`` without its ROS arguments: each ``--ros-args`` up to the next ``--`` (or the end), as rcl reads
    them. Pure, so a bad ROS argument (say an unreadable --params-file) is left to its own one-line check."""
    out: list[str] = []
    in_ros = False
    for arg in argv:
        if in_ros:
            in_ros = arg != '--'
        elif arg == '--ros-args':
            in_ros = True
        else:
            out.append(arg)
    return out


def main(args: list[str] | None = None) -> int:
    """Console script ``fourbar_node``: exit 0 on Ctrl-C/SIGTERM, 2 with one line on bad parameters."""
    from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException

    stop = StopRequest()
    stop.install()  # before rclpy.init: a stop during startup also ends cleanly, after the node is built
    argv = sys.argv if args is None else args
    try:
        kind = executor_kind(node_options(argv).executor)
    except ValueError as exc:  # UsageError, ExecutorChoiceError
        print(f'fourbar_node: error: {exc}', file=sys.stderr)
        return 2
    problem = params_file_problem(argv)
    if problem is not None:
        print(f'fourbar_node: error: {problem}', file=sys.stderr)
        return 2
    try:
        rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    except Exception as exc:  # e.g. an unreadable --params-file: rcl raises RCLError
        print(f'fourbar_node: error: {one_line(exc)}', file=sys.stderr)
        return 2
    node: FourBarNode | None = None
    executor: Executor | None = None
    try:
        node = FourBarNode(params_files=params_files(argv), command_line_names=command_line_names(argv))
        executor = create_executor(kind)
        executor.add_node(node)
        get_logger: Callable[[], RcutilsLogger] = node.get_logger
        info: Callable[[str], object] = get_logger().info
        info(f'callbacks run on the {kind} executor')
        spin_until_stopped(executor, stop)
    except (ConfigError, InvalidParameterTypeException, InvalidParameterValueException) as exc:
        print(f'fourbar_node: error: {one_line(exc)}', file=sys.stderr)
        return 2
    finally:
        # Nothing runs callbacks any more (one thread): destroy the node, then shut the context down.
        if executor is not None:
            executor.shutdown(timeout_sec=0.0)
        if node is not None:
            destroy(node)
        rclpy.utilities.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
