"""Replay a command bag into a running fourbar_node (rclpy), timed or lock-step.

Lock-step predicts which commands the node answers by its own rule (``rules.policy.decide``) and its live
parameters; the modes and ``/clock``: docs/how-to/bags.md."""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass
from typing import Any

from rclpy.duration import Duration
from rclpy.executors import Executor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosbags.interfaces import QosDurability, QosReliability
from std_msgs.msg import Float64

from fourbar_ros.bags.storage import CommandStream
from fourbar_ros.interface.stamps import from_ns, ns_to_seconds, seconds_to_ns
from fourbar_ros.interface.topics import STREAM_DEPTH
from fourbar_ros.live.graph import (
    ReplayError,
    make_qos,
    publisher_nodes,
    spin_until,
    subscriber_nodes,
    wait_for_node_names,
)
from fourbar_ros.live.node_params import LIMIT_PARAMETERS, Predictor, fetch_parameters, handshake, predictor_from_values
from fourbar_ros.live.progress import Progress
from fourbar_ros.runtime.spin import spin_once

#: History depth of the replay publisher (timed mode may run ahead of a slow node by this much): the node's own.
PUBLISH_DEPTH = STREAM_DEPTH
#: Rate (Hz) of /clock in timed replay with a clock, as ``ros2 bag play --clock`` publishes by default.
DEFAULT_CLOCK_HZ = 40.0


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

    With ``answer_topic`` (lock-step), counts the node's answers there (``std_msgs/Float64`` by default: the
    node's ``input_torque``, one per served command; received raw: the replayer never decodes them).
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
        #: Subscriber nodes with parameter services, asked by ``confirm_delivery`` (set by ``prepare_*``).
        self.reachable: list[str] = []
        self.subscription = None
        if answer_topic is not None:
            if answer_type is None:
                answer_type = Float64
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
            raise ReplayError(f'{what} within {timeout_s:g} s (is fourbar_node running with ROS_DOMAIN_ID={domain} '
                              f'in the namespace {self.publisher.topic_name.rsplit("/", 1)[0] or "/"}? a node in '
                              'another namespace NS: --topic /NS/antenna_angle_cmd)')

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
        self.reachable = subscribers
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
        replayer's publishers (the handshake of ``fetch_parameters``). fourbar_node's reliable subscription gets
        what it missed resent, but a best-effort one (another node's) drops whatever arrives before it has matched
        the publisher.

        Returns (subscribers without parameter services, which may miss the first and last commands; subscribers
        whose ``use_sim_time`` is false, which ignore ``/clock``).
        """
        cmd = self.publisher.topic_name
        self.reachable = []
        unreachable: list[str] = []
        ignoring: list[str] = []
        for target in wait_for_node_names(self.node, executor, lambda: subscriber_nodes(self.node, cmd),
                                          timeout_s, f'subscribed to {cmd}'):
            try:
                values = fetch_parameters(self.node, executor, target, ['use_sim_time'], timeout_s)
            except ReplayError:
                unreachable.append(target)
                continue
            self.reachable.append(target)
            if values.get('use_sim_time') is not True:
                ignoring.append(target)
        return unreachable, ignoring

    def confirm_delivery(self, executor: Executor, timeout_s: float) -> None:
        """Return once every subscriber has received every command published so far; call before this node's
        context goes away.

        A reliable publisher waits for the reliable subscriptions' acknowledgements (fourbar_node's); a
        best-effort subscription sends none, and a replay that closed its context right after the last publish
        would lose the commands still in flight to it. So also ask each subscriber node
        (``prepare_timed``/``prepare_lockstep`` found them) for a parameter: the request leaves this participant
        after the commands, for the same node, which receives them in order; its answer proves the commands
        before it arrived.

        The executor keeps running callbacks while the acknowledgements are awaited (a reliable writer's last
        sample may wait for its next heartbeat, up to a heartbeat period): ``wait_for_all_acked`` holds the GIL
        while it blocks, so it is asked without blocking between bounded spins, and a recorder on the same
        executor stamps what arrives meanwhile when it arrives.
        """
        if self.publisher.qos_profile.reliability == ReliabilityPolicy.RELIABLE:
            spin_until(executor, self.all_acked, timeout_s)
        handshake(self.node, executor, self.reachable, timeout_s)

    def all_acked(self) -> bool:
        """Every reliable subscription has acknowledged every command published so far (asked without waiting)."""
        return bool(self.publisher.wait_for_all_acked(Duration(nanoseconds=0)))

    def _publish_clock(self, stamp_ns: int) -> None:
        from builtin_interfaces.msg import Time

        sec, nanosec = from_ns(stamp_ns)
        self.clock_publisher.publish(_clock_type()(clock=Time(sec=sec, nanosec=nanosec)))

    def run_timed(self, executor: Executor, rate: float = 1.0,
                  progress: Progress | None = None, ack_timeout_s: float = 10.0,
                  clock_hz: float = DEFAULT_CLOCK_HZ) -> ReplayStats:
        """Publish with the recorded timing scaled by ``1/rate``; return once the subscribers have every command.

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
                self._publish_clock(stamps[0] + seconds_to_ns((now - start) * rate))
                stats.clocks += 1
                next_clock += period
                if next_clock <= now:  # fell behind (a busy machine): resume the rate, no burst
                    next_clock = now + period
        for i, raw in enumerate(raws):
            due = start + ns_to_seconds(stamps[i] - stamps[0]) / rate
            while True:
                now = time.monotonic()
                tick(now)
                if now >= due:
                    break
                spin_once(executor, (min(due, next_clock) if clock else due) - now)
            self.publisher.publish(raw)
            stats.published += 1
            if progress:
                progress.update(stats.published)
        stats.seconds = time.monotonic() - start
        # Exiting with commands in flight would drop them; not counted in ``seconds`` (an acknowledgement
        # can take one DDS heartbeat period).
        self.confirm_delivery(executor, ack_timeout_s)
        stats.answers = self.answers
        return stats

    def run_lockstep(self, executor: Executor, answers: Predictor, deadline_s: float = 5.0,
                     progress: Progress | None = None, window: int = 1) -> ReplayStats:
        """Publish the commands, keeping at most ``window`` expected answers outstanding.

        ``window=1`` is strict lock-step: each answered command waits (at most ``deadline_s``) for
        its answer before the next command goes out. A larger window pipelines; it stays lossless
        while ``window`` is below the node's command queue depth (``STREAM_DEPTH`` for fourbar_node).
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
            self.confirm_delivery(executor, deadline_s)
        stats.answers = self.answers - base
        return stats
