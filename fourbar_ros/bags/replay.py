"""Replay a command bag into a running fourbar_node (rclpy), plus helpers to run the node as a process.

Two modes:

- timed: each command is published at its recorded time offset divided by ``rate``
  (``rate=2`` plays twice as fast), like ``ros2 bag play --rate``;
- lock-step: after each command the node is expected to answer, wait (with a deadline) for its
  ``joint_states`` message before publishing the next one, so nothing queues up and nothing is
  lost whatever the node's speed. Which commands the node answers is predicted with the node's
  own rule (``command_policy.decide``) from its live ``theta_min``, ``theta_max`` and
  ``out_of_limits`` parameters (or a parameter file): rejected commands get no answer to wait for,
  and the next answered command proves the node has consumed them (one subscription, in order).

The recorded CDR bytes are published unchanged (rclpy >= Jazzy's ``Publisher.publish(bytes)``).

Timed mode can also publish ``/clock`` (``rosgraph_msgs/Clock``) from the bag's timeline, like
``ros2 bag play --clock``: the playback time (the first command's stamp plus the elapsed wall time
times ``rate``) at ``clock_hz`` (40 Hz by default, rosbag2's default), so a node with
``use_sim_time:=true`` runs on the bag's time.
"""

from __future__ import annotations

import contextlib
import fcntl
import math
import os
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any, cast

import rclpy
import rclpy.utilities
from rclpy.context import Context
from rclpy.duration import Duration
from rclpy.executors import Executor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosbags.interfaces import QosDurability, QosReliability
from std_msgs.msg import Float64

from fourbar_ros.bags.storage import CommandStream
from fourbar_ros.core.antenna import Reach
from fourbar_ros.core.errors import FourBarError
from fourbar_ros.node.command_policy import Policy, decide

#: rclpy's QoSProfile constructor is unannotated; a typed alias keeps mypy strict about the rest.
make_qos = cast('Callable[..., QoSProfile]', QoSProfile)

#: History depth of the replay publisher (timed mode may run ahead of a slow node by this much).
PUBLISH_DEPTH = 1000
#: Rate (Hz) of /clock in timed replay with a clock, as ``ros2 bag play --clock`` publishes by default.
DEFAULT_CLOCK_HZ = 40.0


class ReplayError(FourBarError):
    """The node is absent, did not answer a command in time, or its parameters are unusable."""


# --------------------------------------------------------------------------- progress bar

class Progress:
    """A one-line progress bar on stderr, drawn at most 10 times a second; silent unless a TTY."""

    def __init__(self, total: int, label: str, stream: IO[str] | None = None,
                 enabled: bool | None = None) -> None:
        self.total = max(total, 1)
        self.label = label
        self.stream = stream if stream is not None else sys.stderr
        self.enabled = self.stream.isatty() if enabled is None else enabled
        self._last = 0.0
        self._start = time.monotonic()
        self._drawn = False
        self._done = 0

    def update(self, done: int, force: bool = False) -> None:
        """Redraw with ``done`` of ``total`` items finished."""
        self._done = done
        if not self.enabled:
            return
        now = time.monotonic()
        if not force and now - self._last < 0.1:
            return
        self._last = now
        width = 30
        filled = int(width * min(done, self.total) / self.total)
        elapsed = now - self._start
        self.stream.write(f'\r{self.label} [{"#" * filled}{"." * (width - filled)}] '
                          f'{done}/{self.total} {elapsed:5.1f} s')
        self.stream.flush()
        self._drawn = True

    def end(self) -> None:
        """Redraw the last state and end the line (if anything was drawn)."""
        if self.enabled and self._drawn:
            self.update(self._done, force=True)
            self.stream.write('\n')
            self.stream.flush()


# --------------------------------------------------------------------------- topics and QoS

def sibling_topic(command_topic: str, name: str) -> str:
    """The topic ``name`` in the namespace of ``command_topic`` (``/ns/antenna_angle_cmd`` -> ``/ns/NAME``)."""
    head = command_topic.rsplit('/', 1)[0] if '/' in command_topic else ''
    return f'{head}/{name}' if head or command_topic.startswith('/') else name


def publisher_qos(stream: CommandStream, depth: int = PUBLISH_DEPTH) -> QoSProfile:
    """Offer what the recorded publisher offered (reliability, durability), as ``ros2 bag play`` does.

    Without recorded profiles: reliable, volatile. History: keep-last ``depth``.
    """
    reliable, transient = True, False
    if stream.qos:
        reliable = all(q.reliability != QosReliability.BEST_EFFORT for q in stream.qos)
        transient = all(q.durability == QosDurability.TRANSIENT_LOCAL for q in stream.qos)
    return make_qos(
        history=HistoryPolicy.KEEP_LAST, depth=depth,
        reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if transient else DurabilityPolicy.VOLATILE)


def spin_until(executor: Executor, done: Callable[[], bool], timeout_s: float) -> bool:
    """Run callbacks until ``done()`` or ``timeout_s`` seconds pass; return ``done()``."""
    end = time.monotonic() + timeout_s
    while not done():
        remaining = end - time.monotonic()
        if remaining <= 0.0:
            return done()
        executor.spin_once(timeout_sec=min(remaining, 0.1))
    return True


# --------------------------------------------------------------------------- which commands get answers

Predictor = Callable[[float], bool]


def predictor(theta_min: float, theta_max: float, out_of_limits: str) -> Predictor:
    """True for commands the node answers (accepted or clamped), by the node's own policy."""
    policy = Policy(out_of_limits)
    reach = Reach(0.0, math.pi)  # only labels out-of-limit commands; no effect on the outcome

    def answers(theta: float) -> bool:
        return not decide(theta, theta_min, theta_max, policy, reach).outcome.rejected
    return answers


def _node_names(node: Node, infos: Sequence[Any]) -> list[str]:
    me = node.get_fully_qualified_name()
    names: list[str] = []
    for info in infos:
        if info.node_name == '_NODE_NAME_UNKNOWN_':  # rmw placeholder until discovery completes
            continue
        fqn = f'{info.node_namespace.rstrip("/")}/{info.node_name}'
        if fqn != me and fqn not in names:
            names.append(fqn)
    return names


def subscriber_nodes(node: Node, topic: str) -> list[str]:
    """Fully qualified names of the other nodes subscribed to ``topic``."""
    return _node_names(node, node.get_subscriptions_info_by_topic(topic))


def publisher_nodes(node: Node, topic: str) -> list[str]:
    """Fully qualified names of the other nodes publishing ``topic``."""
    return _node_names(node, node.get_publishers_info_by_topic(topic))


def wait_for_node_names(node: Node, executor: Executor, lookup: Callable[[], list[str]],
                        timeout_s: float, what: str) -> list[str]:
    """Wait until the graph names the nodes behind ``what`` (names arrive after the endpoints)."""
    if not spin_until(executor, lambda: bool(lookup()), timeout_s):
        raise ReplayError(f'no named node {what} within {timeout_s:g} s')
    return lookup()


def fetch_parameters(node: Node, executor: Executor, target: str, names: Sequence[str],
                     timeout_s: float) -> dict[str, Any]:
    """Read parameters of node ``target`` (fully qualified name) through its parameter services.

    Also a discovery handshake: the reply travels on a reader this node created after its other
    subscriptions, and a DDS participant processes another's endpoint announcements in order, so
    once ``target`` has answered, its publishers have matched every subscription created before
    this call. Requests are repeated (idempotent reads) until ``timeout_s``.
    """
    from rcl_interfaces.srv import GetParameters
    from rclpy.parameter import parameter_value_to_python

    client = node.create_client(GetParameters, f'{target}/get_parameters')
    end = time.monotonic() + timeout_s
    try:
        if not spin_until(executor, client.service_is_ready, timeout_s):
            raise ReplayError(f'{target} offers no get_parameters service within {timeout_s:g} s')
        while True:
            left = end - time.monotonic()
            if left <= 0.0:
                raise ReplayError(f'{target} did not return its parameters within {timeout_s:g} s')
            future = client.call_async(GetParameters.Request(names=list(names)))
            get_result: Callable[[], Any] = future.result
            if spin_until(executor, future.done, min(left, 1.0)) and get_result() is not None:
                values = get_result().values
                return {n: parameter_value_to_python(v) for n, v in zip(names, values, strict=False)}
            client.remove_pending_request(future)
    finally:
        node.destroy_client(client)


def handshake(node: Node, executor: Executor, targets: Sequence[str], timeout_s: float) -> None:
    """Make sure each target node has discovered every subscription ``node`` created so far."""
    for target in targets:
        fetch_parameters(node, executor, target, ['use_sim_time'], timeout_s)


LIMIT_PARAMETERS = ('theta_min', 'theta_max', 'out_of_limits')


def predictor_from_values(values: dict[str, Any], source: str) -> Predictor:
    """A Predictor from ``theta_min``, ``theta_max`` (rad) and ``out_of_limits`` values."""
    try:
        return predictor(float(values['theta_min']), float(values['theta_max']),
                         str(values['out_of_limits']))
    except (KeyError, TypeError, ValueError) as exc:
        raise ReplayError(f'{source} is not a fourbar_node (parameters {values!r}): {exc}') from None


# --------------------------------------------------------------------------- the replayer

@dataclass
class ReplayStats:
    """Outcome of a replay: commands published, answers expected and seen, wall time (s)."""

    published: int = 0
    expected_answers: int = 0
    answers: int = 0
    seconds: float = 0.0
    clocks: int = 0

    @property
    def rate_hz(self) -> float:
        """Commands published per second of wall time."""
        return self.published / self.seconds if self.seconds > 0 else math.inf


def _clock_type() -> Any:
    """``rosgraph_msgs.msg.Clock`` (imported by name: the message package ships no type stubs)."""
    import importlib

    return importlib.import_module('rosgraph_msgs.msg').Clock


class Replayer:
    """Publishes a CommandStream on ``topic`` (default: its recorded topic) from ``node``.

    With ``answer_topic`` (lock-step), counts the node's answers there (``sensor_msgs/JointState``
    by default, received raw: the replayer never decodes them).
    """

    def __init__(self, node: Node, stream: CommandStream, topic: str | None = None,
                 answer_topic: str | None = None, answer_type: Any = None, clock: bool = False) -> None:
        self.node = node
        self.stream = stream
        self.topic = topic or stream.topic
        self.publisher = node.create_publisher(Float64, self.topic, publisher_qos(stream))
        self.clock_publisher: Any = None
        if clock:
            # rosbag2's clock QoS: best effort, keep last 1 (what rclpy's and rclcpp's time sources request).
            self.clock_publisher = node.create_publisher(
                _clock_type(), '/clock', make_qos(history=HistoryPolicy.KEEP_LAST, depth=1,
                                          reliability=ReliabilityPolicy.BEST_EFFORT))
        self.answer_topic = answer_topic
        self.answers = 0
        self.subscription = None
        if answer_topic is not None:
            if answer_type is None:
                from sensor_msgs.msg import JointState
                answer_type = JointState
            self.subscription = node.create_subscription(
                answer_type, answer_topic, self._on_answer,
                make_qos(history=HistoryPolicy.KEEP_LAST, depth=PUBLISH_DEPTH,
                         reliability=ReliabilityPolicy.RELIABLE), raw=True)

    def _on_answer(self, _msg: bytes) -> None:
        self.answers += 1

    def wait_for_node(self, executor: Executor, timeout_s: float) -> None:
        """Wait until the node subscribes the command topic (and, lock-step, publishes answers)."""
        def matched() -> bool:
            if self.publisher.get_subscription_count() < 1:
                return False
            return self.subscription is None or self.subscription.get_publisher_count() >= 1
        if not spin_until(executor, matched, timeout_s):
            what = f'no subscriber on {self.publisher.topic_name}'
            if self.publisher.get_subscription_count() >= 1 and self.subscription is not None:
                what = f'no publisher on {self.subscription.topic_name}'
            domain = os.environ.get('ROS_DOMAIN_ID', '0')
            raise ReplayError(f'{what} within {timeout_s:g} s (is fourbar_node running with '
                              f'ROS_DOMAIN_ID={domain}?)')

    def prepare_lockstep(self, executor: Executor, timeout_s: float,
                         answers: Predictor | None = None) -> Predictor:
        """Handshake with the node (see ``fetch_parameters``) and return which commands it answers.

        Without ``answers``, the node's ``theta_min``, ``theta_max`` and ``out_of_limits`` decide.
        """
        if self.subscription is None:
            raise ReplayError('lock-step replay needs an answer topic')
        cmd, out = self.publisher.topic_name, self.subscription.topic_name
        subscribers = wait_for_node_names(self.node, executor, lambda: subscriber_nodes(self.node, cmd),
                                          timeout_s, f'subscribed to {cmd}')
        publishers = wait_for_node_names(self.node, executor, lambda: publisher_nodes(self.node, out),
                                         timeout_s, f'publishing {out}')
        others = [n for n in publishers if n not in subscribers]
        if answers is None:
            if len(subscribers) != 1:
                raise ReplayError(f'lock-step needs exactly one node subscribed to {cmd} to ask for its '
                                  f'limits (found: {", ".join(subscribers)}); pass --params FILE instead')
            values = fetch_parameters(self.node, executor, subscribers[0], LIMIT_PARAMETERS, timeout_s)
            answers = predictor_from_values(values, subscribers[0])
            handshake(self.node, executor, others, timeout_s)
        else:
            handshake(self.node, executor, subscribers + others, timeout_s)
        return answers

    def prepare_timed(self, executor: Executor, timeout_s: float) -> tuple[list[str], list[str]]:
        """Before a timed replay: make sure every node subscribed to the command topic has discovered this
        replayer's publishers (the handshake of ``fetch_parameters``). A best-effort subscription (the node's)
        drops whatever arrives before it has matched the publisher, and nothing is resent.

        Returns (subscribers without parameter services, which may miss the first commands; subscribers whose
        ``use_sim_time`` is false, which ignore ``/clock``).
        """
        cmd = self.publisher.topic_name
        unreachable: list[str] = []
        ignoring: list[str] = []
        for target in wait_for_node_names(self.node, executor, lambda: subscriber_nodes(self.node, cmd),
                                          timeout_s, f'subscribed to {cmd}'):
            try:
                values = fetch_parameters(self.node, executor, target, ['use_sim_time'], timeout_s)
            except ReplayError:
                unreachable.append(target)
                continue
            if values.get('use_sim_time') is not True:
                ignoring.append(target)
        return unreachable, ignoring

    def _publish_clock(self, stamp_ns: int) -> None:
        from builtin_interfaces.msg import Time

        sec, nanosec = divmod(stamp_ns, 1_000_000_000)
        self.clock_publisher.publish(_clock_type()(clock=Time(sec=sec, nanosec=nanosec)))

    def run_timed(self, executor: Executor, rate: float = 1.0,
                  progress: Progress | None = None, ack_timeout_s: float = 10.0,
                  clock_hz: float = DEFAULT_CLOCK_HZ) -> ReplayStats:
        """Publish with the recorded timing scaled by ``1/rate``; wait until the node acknowledged.

        With a clock publisher (``Replayer(clock=True)``), ``/clock`` carries the playback time every
        ``1/clock_hz`` s of wall time from the start (the first command's stamp) to the last command.
        """
        if not rate > 0.0 or not math.isfinite(rate):
            raise ReplayError(f'rate must be a positive number, got {rate}')
        if not clock_hz > 0.0 or not math.isfinite(clock_hz):
            raise ReplayError(f'clock rate must be a positive number of Hz, got {clock_hz}')
        stats = ReplayStats()
        stamps, raws = self.stream.stamps_ns, self.stream.raw
        clock = self.clock_publisher is not None
        period = 1.0 / clock_hz
        start = time.monotonic()
        next_clock = start

        def tick(now: float) -> None:
            nonlocal next_clock
            if clock and now >= next_clock:
                self._publish_clock(stamps[0] + round((now - start) * rate * 1e9))
                stats.clocks += 1
                next_clock += period
                if next_clock <= now:  # fell behind (a busy machine): resume the rate, no burst
                    next_clock = now + period
        for i, raw in enumerate(raws):
            due = start + (stamps[i] - stamps[0]) * 1e-9 / rate
            while True:
                now = time.monotonic()
                tick(now)
                if now >= due:
                    break
                executor.spin_once(timeout_sec=(min(due, next_clock) if clock else due) - now)
            self.publisher.publish(raw)
            stats.published += 1
            if progress:
                progress.update(stats.published)
        stats.seconds = time.monotonic() - start
        if self.publisher.qos_profile.reliability == ReliabilityPolicy.RELIABLE:
            # Exiting with unacknowledged samples would drop them; this can take one DDS
            # heartbeat period (seconds), which is why it is not counted in ``seconds``.
            self.publisher.wait_for_all_acked(Duration(seconds=ack_timeout_s))
        stats.answers = self.answers
        return stats

    def run_lockstep(self, executor: Executor, answers: Predictor, deadline_s: float = 5.0,
                     progress: Progress | None = None, window: int = 1) -> ReplayStats:
        """Publish the commands, keeping at most ``window`` expected answers outstanding.

        ``window=1`` is strict lock-step: each answered command waits (at most ``deadline_s``) for
        its answer before the next command goes out. A larger window pipelines; it stays lossless
        while ``window`` is below the node's command queue depth (1000 for fourbar_node).
        """
        if self.subscription is None:
            raise ReplayError('lock-step replay needs an answer topic')
        if window < 1:
            raise ReplayError(f'window must be at least 1, got {window}')
        topic = self.subscription.topic_name
        stats = ReplayStats()
        base = self.answers
        waiting: list[tuple[int, float]] = []  # (command index, theta) of each expected answer

        def wait_until_outstanding(limit: int) -> None:
            target = base + stats.expected_answers - limit

            def done() -> bool:
                return self.answers >= target
            if not spin_until(executor, done, deadline_s):
                i, theta = waiting[self.answers - base]
                raise ReplayError(f'no answer on {topic} to command {i} (theta = {theta!r} rad) within '
                                  f'{deadline_s:g} s: the node lost it or stopped')

        start = time.monotonic()
        for i, (raw, theta) in enumerate(zip(self.stream.raw, self.stream.values, strict=True)):
            self.publisher.publish(raw)
            stats.published += 1
            if answers(theta):
                stats.expected_answers += 1
                waiting.append((i, theta))
                wait_until_outstanding(window - 1)
            if progress:
                progress.update(stats.published)
        wait_until_outstanding(0)
        stats.seconds = time.monotonic() - start
        if not (self.stream.values and answers(self.stream.values[-1])):
            # Unanswered commands at the end: make sure they reached the node's reader (the last
            # answer already proves every earlier command was consumed).
            self.publisher.wait_for_all_acked(Duration(seconds=deadline_s))
        stats.answers = self.answers - base
        return stats


# --------------------------------------------------------------------------- node process and domain

def _port_free(port: int) -> bool:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        try:
            s.bind(('', port))
        except OSError:
            return False
    return True


def domain_in_use(domain_id: int, participants: int = 8) -> bool:
    """True if a DDS participant of ``domain_id`` runs on this host.

    Checks the first ``participants`` unicast discovery ports of the RTPS port mapping
    (7400 + 250 d + 10 + 2 i), which a running participant holds exclusively.
    """
    base = 7400 + 250 * domain_id + 10
    return not all(_port_free(base + 2 * i) for i in range(participants))


#: Domain ids a fourbar run may take: safe on Linux (discovery ports outside the ephemeral range) and
#: clear of the ranges developers use by hand; the test suite leases from the same ids and lock files.
FREE_DOMAIN_IDS: tuple[int, ...] = (*range(90, 102), *range(215, 233))
DOMAIN_LOCK_DIR = Path(tempfile.gettempdir()) / 'fourbar_ros_domain_locks'


@contextlib.contextmanager
def free_domain_id(candidates: Sequence[int] = FREE_DOMAIN_IDS,
                   lock_dir: Path = DOMAIN_LOCK_DIR) -> Iterator[int]:
    """Reserve a ROS_DOMAIN_ID nobody on this host uses, for the duration of the ``with`` block.

    A domain is free when no other fourbar run holds its lock file (``<lock_dir>/<id>.lock``,
    flock, shared with the test suite) and no DDS participant holds its discovery ports.
    """
    lock_dir.mkdir(parents=True, exist_ok=True)
    start = os.getpid() % len(candidates)
    for domain in list(candidates[start:]) + list(candidates[:start]):
        try:
            fd = os.open(lock_dir / f'{domain}.lock', os.O_CREAT | os.O_RDWR, 0o666)
        except OSError:
            continue
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(fd)
            continue
        try:
            if domain_in_use(domain):
                continue
            yield domain
            return
        finally:
            os.close(fd)  # drops the flock
    raise ReplayError(f'no free ROS_DOMAIN_ID among {candidates[0]}..{candidates[-1]}')


NODE_MAIN = 'import sys; from fourbar_ros.node.fourbar_node import main; sys.exit(main())'


class NodeProcess:
    """``fourbar_node`` as a child process (own session) with a parameter file and domain id.

    ``stop()`` sends SIGINT and escalates to SIGTERM and SIGKILL; it is safe to call twice.
    """

    def __init__(self, params: Path | None, domain_id: int, log_path: Path | None = None,
                 ros_args: Sequence[str] = (), env: dict[str, str] | None = None) -> None:
        self.params = params
        self.domain_id = domain_id
        self.log_path = log_path
        self.ros_args = list(ros_args)
        self.env = dict(os.environ if env is None else env)
        self.env['ROS_DOMAIN_ID'] = str(domain_id)
        self.proc: subprocess.Popen[bytes] | None = None
        self._log: IO[bytes] | None = None

    def command(self) -> list[str]:
        """The argv that starts the node (the same interpreter as this process)."""
        args = [sys.executable, '-c', NODE_MAIN, '--ros-args']
        if self.params is not None:
            args += ['--params-file', str(self.params)]
        return args + self.ros_args

    def start(self) -> NodeProcess:
        """Start the node; its output goes to ``log_path`` (or is discarded)."""
        self._log = self.log_path.open('wb') if self.log_path else None
        self.proc = subprocess.Popen(
            self.command(), env=self.env, stdin=subprocess.DEVNULL,
            stdout=self._log or subprocess.DEVNULL, stderr=subprocess.STDOUT,
            start_new_session=True)
        return self

    def alive(self) -> bool:
        """True while the process runs."""
        return self.proc is not None and self.proc.poll() is None

    def last_log_line(self) -> str:
        """The last non-empty line the node wrote (for error messages)."""
        if self.log_path is None or not self.log_path.exists():
            return ''
        lines = [x for x in self.log_path.read_text(errors='replace').splitlines() if x.strip()]
        return lines[-1].strip() if lines else ''

    def stop(self, timeout_s: float = 10.0) -> int | None:
        """Stop the node (SIGINT, then SIGTERM, then SIGKILL); return its exit status."""
        proc = self.proc
        if proc is None:
            return None
        try:
            for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGKILL):
                if proc.poll() is not None:
                    break
                with contextlib.suppress(ProcessLookupError):
                    proc.send_signal(sig)
                with contextlib.suppress(subprocess.TimeoutExpired):
                    proc.wait(timeout=timeout_s)
            return proc.wait()
        finally:
            if self._log is not None:
                self._log.close()
                self._log = None

    def __enter__(self) -> NodeProcess:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()


def init_context(domain_id: int | None = None, handle_signals: bool = True) -> Context:
    """A fresh rclpy context (``domain_id`` None: from ROS_DOMAIN_ID, as rclpy does)."""
    from rclpy.signals import SignalHandlerOptions

    context = Context()
    rclpy.init(context=context, domain_id=domain_id,
               signal_handler_options=SignalHandlerOptions.ALL if handle_signals else SignalHandlerOptions.NO)
    return context


@contextlib.contextmanager
def interrupt_on_sigterm() -> Iterator[None]:
    """Turn SIGTERM into KeyboardInterrupt (like Ctrl-C) inside the block, so cleanup code runs.

    Use with ``init_context(handle_signals=False)``: rclpy's own handlers would invalidate the
    context under a running publisher instead of interrupting the program.
    """
    def raise_interrupt(_signum: int, _frame: object) -> None:
        raise KeyboardInterrupt
    previous = signal.signal(signal.SIGTERM, raise_interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def close_context(context: Context, *nodes: Node) -> None:
    """Destroy ``nodes`` and shut ``context`` down (idempotent)."""
    for node in nodes:
        destroy: Callable[[], object] = node.destroy_node
        destroy()
    rclpy.utilities.try_shutdown(context=context)
