"""fourbar_node: antenna angle commands in, rocker joint states, input torque, diagnostics and markers out.

Interface (relative names, so namespaces and remapping apply):
  sub  antenna_angle_cmd  std_msgs/Float64           commanded antenna angle theta, rad (+ tilts down)
  pub  joint_states       sensor_msgs/JointState     position [gamma, delta] rad; velocity rad/s by finite
                                                     difference of successive published positions (empty
                                                     when not meaningful); effort N m: driven rocker's torque,
                                                     0.0 for the other rocker
  pub  input_torque       std_msgs/Float64           torque the driven rocker needs, N m (+ in the sense of q)
  pub  /diagnostics       diagnostic_msgs/DiagnosticArray   every diagnostics_period s
  pub  linkage_markers    visualization_msgs/MarkerArray    frame, rockers, coupler, joints, antenna arrow;
                                                     every marker_period s, only when subscribed and changed
QoS: the ROS default profile (reliable, volatile, keep-last) with depth 1000 for the command and the
per-command outputs (a burst of a thousand commands is queued, not dropped) and depth 10 for markers and
diagnostics. Markers are not per command (drawing them costs more than the rest of a command): a timer
publishes them at most every marker_period s. Each can be overridden with
``qos_overrides./<topic>.<publisher|subscription>.<policy>`` parameters.
The node only adapts messages and parameters; the math is in fourbar_ros.antenna/loads and the
decisions in the pure modules command_policy, state_cache, joint_velocity, diagnostic_values.
"""

from __future__ import annotations

import itertools
import sys
from collections.abc import Callable
from typing import Any

import rclpy
import rclpy.utilities
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import SetParametersResult
from rclpy.executors import ExternalShutdownException
from rclpy.impl.rcutils_logger import RcutilsLogger
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos_overriding_options import QoSOverridingOptions
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64
from visualization_msgs.msg import MarkerArray

from fourbar_ros.antenna import Driven, LinkageState
from fourbar_ros.command_policy import Decision, Outcome, Policy, decide
from fourbar_ros.config import AntennaConfig, ConfigError, config_from_values
from fourbar_ros.diagnostic_values import Counters, summarize
from fourbar_ros.errors import FourBarError
from fourbar_ros.joint_velocity import Sample, finite_difference
from fourbar_ros.loads import Pose, pose_solver, solve
from fourbar_ros.marker_geometry import linkage_points
from fourbar_ros.params import is_foreign
from fourbar_ros.ros_markers import LinkageMarkers
from fourbar_ros.ros_params import declarations
from fourbar_ros.state_cache import StateCache

NODE_NAME = 'fourbar_node'
#: Keep-last depth of the command subscription and the per-command outputs.
STREAM_DEPTH = 1000
#: Keep-last depth of markers and diagnostics (latest state only matters).
STATUS_DEPTH = 10
WARN_THROTTLE_S = 1.0


class FourBarNode(Node):
    """The antenna tilt node. Raises ConfigError from the constructor if its parameters are invalid."""

    def __init__(self, node_name: str = NODE_NAME, **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        # rclpy's logger and destroy_node are unannotated: bind them to typed names once.
        get_logger: Callable[[], RcutilsLogger] = self.get_logger
        logger = get_logger()
        self._ros_clock = self.get_clock()
        self._warn: Callable[..., object] = logger.warning
        self._error: Callable[..., object] = logger.error
        try:
            self._config = self._validated_overrides()
        except ConfigError:
            _destroy(self)
            raise
        self.declare_parameters('', list(declarations(self._config.as_values())))
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.add_post_set_parameters_callback(self._after_set_parameters)
        self._pending: AntennaConfig | None = None

        self.counters = Counters()
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
        self._command_sub = self.create_subscription(Float64, 'antenna_angle_cmd', self._on_command,
                                                     STREAM_DEPTH, qos_overriding_options=qos_options)
        self._diag_timer = self.create_timer(self._config.diagnostics_period, self._on_diagnostics_timer)
        self._marker_timer = self.create_timer(self._config.marker_period, self._on_marker_timer)

    # ------------------------------------------------------------------ configuration

    def _validated_overrides(self) -> AntennaConfig:
        """Validate the startup values (params file, --param, constructor overrides) before declaring."""
        overrides = {name: p.value for name, p in self._parameter_overrides.items()}
        return config_from_values(overrides)

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
        """Validate the running configuration with the proposed changes, as a whole."""
        proposed: dict[str, object] = dict(self._config.as_values())
        for p in params:
            if not is_foreign(p.name):
                proposed[p.name] = p.value
        try:
            self._pending = config_from_values(proposed)
        except ConfigError as exc:
            self._pending = None
            self.counters.parameter_changes_rejected += 1
            self._warn(f'parameter change rejected: {exc}')
            return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def _after_set_parameters(self, params: list[Parameter]) -> None:
        if self._pending is not None and any(not is_foreign(p.name) for p in params):
            self._apply(self._pending)
            self.counters.parameter_changes_accepted += 1
        self._pending = None

    # ------------------------------------------------------------------ commands

    def _on_command(self, msg: Float64) -> None:
        # Latency-critical path first (check, solve, publish joint_states); bookkeeping after.
        command = msg.data
        counters = self.counters
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
                self._publish_joints(state)
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

    def _publish_joints(self, state: Pose) -> None:
        now = self._ros_clock.now()
        gamma, delta, torque = state
        sample = Sample(now.nanoseconds, (gamma, delta))
        msg = self._joint_msg
        msg.header.stamp = now.to_msg()
        msg.position = [gamma, delta]
        msg.velocity = finite_difference(self._last_sample, sample, self._velocity_timeout)
        msg.effort = [torque, 0.0] if self._driven_first else [0.0, torque]
        self._joint_pub.publish(msg)
        self._last_sample = sample
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
                            self.cache.computed, self.cache.reused)
        return DiagnosticStatus(
            level=bytes([int(summary.level)]), name=f'{self.get_fully_qualified_name()}: antenna tilt linkage',
            message=summary.message, hardware_id=self._config.frame_id,
            values=[KeyValue(key=k, value=v) for k, v in summary.values])

    def _on_diagnostics_timer(self) -> None:
        if self._diag_pub.get_subscription_count() == 0:
            self.counters.diagnostics_skipped += 1
            return
        self.counters.diagnostics_published += 1
        msg = DiagnosticArray(status=[self.diagnostic_status()])
        msg.header.stamp = self.get_clock().now().to_msg()
        self._diag_pub.publish(msg)


def _destroy(node: Node) -> None:
    destroy: Callable[[], object] = node.destroy_node
    destroy()


def _one_line(exc: BaseException) -> str:
    text = ' '.join(str(exc).split())
    return text or exc.__class__.__name__


def params_file_problem(argv: list[str]) -> str | None:
    """One line if a ``--params-file`` argument cannot be read or is not YAML, else None.

    Checked before rclpy.init, because rcl would log its own multi-line error first.
    """
    import yaml

    for flag, path in itertools.pairwise(argv):
        if flag != '--params-file':
            continue
        try:
            with open(path, encoding='utf-8') as f:
                yaml.compose(f, Loader=yaml.SafeLoader)
        except OSError as exc:
            return f'{path}: cannot read: {exc.strerror or exc}'
        except (yaml.YAMLError, UnicodeDecodeError) as exc:
            return f'{path}: not valid YAML: {_one_line(exc)}'
    return None


def main(args: list[str] | None = None) -> int:
    """Console script ``fourbar_node``: exit 0 on Ctrl-C/SIGTERM, 2 with one line on bad parameters."""
    from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException

    problem = params_file_problem(sys.argv if args is None else args)
    if problem is not None:
        print(f'fourbar_node: error: {problem}', file=sys.stderr)
        return 2
    try:
        rclpy.init(args=args)
    except Exception as exc:  # e.g. an unreadable --params-file: rcl raises RCLError
        print(f'fourbar_node: error: {_one_line(exc)}', file=sys.stderr)
        return 2
    node: FourBarNode | None = None
    try:
        node = FourBarNode()
        rclpy.spin(node)
    except (ConfigError, InvalidParameterTypeException, InvalidParameterValueException) as exc:
        print(f'fourbar_node: error: {_one_line(exc)}', file=sys.stderr)
        return 2
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            _destroy(node)
        rclpy.utilities.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
