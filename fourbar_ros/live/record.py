"""Record topics to a rosbag2 bag (rclpy + rosbags), atomically, as ``ros2 bag record`` does: docs/how-to/bags.md."""

from __future__ import annotations

import time
from collections.abc import Callable, Collection, Sequence
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any

from rclpy.executors import Executor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability

from fourbar_ros.bags.storage import AtomicBagWriter, BagError, jazzy_typestore, time_from_ns
from fourbar_ros.interface.topics import DEFAULT_STORAGE, STREAM_DEPTH, Storage
from fourbar_ros.live.graph import ReplayError, make_qos, publisher_nodes, spin_until, wait_for_node_names
from fourbar_ros.live.node_params import handshake
from fourbar_ros.runtime.executor import MessageInfoCallback, arrival_ns

#: History depth of the recording subscriptions: how far the recorder may fall behind a burst (the node's own).
RECORD_DEPTH = STREAM_DEPTH
#: Seconds between flushes of the bag being recorded (what a SIGKILL may lose, plus one spin).
DEFAULT_FLUSH_INTERVAL = 1.0


def rosbags_qos(profile: Any) -> Qos:
    """An rclpy ``QoSProfile`` (as the graph reports an endpoint) as a rosbags ``Qos``."""
    return Qos(
        QosHistory(int(profile.history)), int(profile.depth),
        QosReliability(int(profile.reliability)), QosDurability(int(profile.durability)),
        time_from_ns(profile.deadline.nanoseconds), time_from_ns(profile.lifespan.nanoseconds),
        QosLiveliness(int(profile.liveliness)),
        time_from_ns(profile.liveliness_lease_duration.nanoseconds),
        bool(profile.avoid_ros_namespace_conventions))


def request_qos(offered: Sequence[Qos]) -> QoSProfile:
    """Subscription QoS that connects to every offer (rosbag2's rule): reliable only if all
    publishers are, transient-local only if all are; keep-last ``RECORD_DEPTH``."""
    reliable = bool(offered) and all(q.reliability == QosReliability.RELIABLE for q in offered)
    transient = bool(offered) and all(q.durability == QosDurability.TRANSIENT_LOCAL for q in offered)
    return make_qos(
        history=HistoryPolicy.KEEP_LAST, depth=RECORD_DEPTH,
        reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if transient else DurabilityPolicy.VOLATILE)


def _import_type(msgtype: str) -> Any:
    """The rclpy message class of ``pkg/msg/Name``."""
    import importlib

    pkg, kind, name = msgtype.split('/')
    return getattr(importlib.import_module(f'{pkg}.{kind}'), name)


def _msgdef(msgtype: str) -> tuple[str, str]:
    """(message definition, RIHS01 hash) of a type from the Jazzy typestore, or the installed .msg."""
    store = jazzy_typestore()
    if msgtype not in store.fielddefs:
        from ament_index_python.packages import PackageNotFoundError, get_package_share_directory
        from rosbags.typesys import get_types_from_msg

        pkg, kind, name = msgtype.split('/')
        try:
            text = (Path(get_package_share_directory(pkg)) / kind / f'{name}.msg').read_text()
        except (PackageNotFoundError, OSError) as exc:
            raise BagError(f'cannot find the definition of {msgtype} ({exc})') from None
        store.register(get_types_from_msg(text, msgtype))
    msgdef, _ = store.generate_msgdef(msgtype, ros_version=2)
    return msgdef, store.hash_rihs01(msgtype)


@dataclass
class TopicPlan:
    """One topic to record: resolved name, type, offered QoS profiles, graph type hash."""

    name: str
    msgtype: str
    offered: list[Qos]
    type_hash: str


def discover(node: Node, executor: Executor, topics: Sequence[str], timeout_s: float,
             stop: Callable[[], bool] = lambda: False) -> list[TopicPlan]:
    """Wait until every topic has a publisher; return name, type and offered QoS of each.

    Raises BagError naming the topics still without a publisher after ``timeout_s``; returns
    an empty list if ``stop()`` turns true first.
    """
    names = [node.resolve_topic_name(t) for t in topics]
    if len(set(names)) != len(names):
        raise BagError(f'topics listed twice: {" ".join(names)}')

    def ready() -> bool:
        return all(node.get_publishers_info_by_topic(n) for n in names)
    if not spin_until(executor, lambda: stop() or ready(), timeout_s):
        missing = [n for n in names if not node.get_publishers_info_by_topic(n)]
        raise BagError(f'no publisher on {", ".join(missing)} within {timeout_s:g} s')
    if stop():
        return []
    plans = []
    for name in names:
        infos = node.get_publishers_info_by_topic(name)
        types = sorted({i.topic_type for i in infos})
        if len(types) != 1:
            raise BagError(f'{name} is published with several types: {", ".join(types)}')
        plans.append(TopicPlan(name, types[0], [rosbags_qos(i.qos_profile) for i in infos],
                               str(infos[0].topic_type_hash)))
    return plans


class Recorder:
    """Records the planned topics from ``node`` into an atomic bag at ``out``.

    Call ``close()`` to finish the bag (it appears at ``out``) or ``abort()`` to drop it.
    """

    def __init__(self, node: Node, out: Path, plans: Sequence[TopicPlan], storage: Storage = DEFAULT_STORAGE,
                 on_message: Callable[[str, int], None] | None = None,
                 flush_interval: float = DEFAULT_FLUSH_INTERVAL) -> None:
        self.node = node
        self.flush_interval = flush_interval
        self._next_flush = time.monotonic() + flush_interval
        self.out = Path(out)
        self.plans = list(plans)
        self.bag = AtomicBagWriter(self.out, storage)
        self.counts: dict[str, int] = {p.name: 0 for p in self.plans}
        #: per topic, the latest source timestamp (ns, the publisher's clock) of a message written so far
        self.last_source_ns: dict[str, int] = {p.name: 0 for p in self.plans}
        self.on_message = on_message
        self._subs: list[Any] = []
        self.bag.open()
        try:
            for plan in self.plans:
                msgdef, rihs01 = _msgdef(plan.msgtype)
                if plan.type_hash.startswith('RIHS01_') and plan.type_hash != rihs01:
                    raise BagError(f'{plan.name}: the publisher\'s {plan.msgtype} (hash {plan.type_hash}) '
                                   'is not the ROS 2 Jazzy definition; cannot store its definition')
                conn = self.bag.add_topic(plan.name, plan.msgtype, plan.offered,
                                          msgdef=msgdef, rihs01=rihs01)
                self._subs.append(node.create_subscription(
                    _import_type(plan.msgtype), plan.name, self._writer_for(conn, plan.name),
                    request_qos(plan.offered), raw=True))
            self.bag.flush()  # the file header is on disk from the start
        except BaseException:
            self.abort()
            raise

    def _writer_for(self, conn: Any, name: str) -> MessageInfoCallback:
        """The subscription callback writing ``name``'s messages. The log time is the middleware's receive time
        (``received_timestamp``, system clock), so a callback run late by a busy executor or a loaded machine still
        records when the message arrived; under sim time, the node's clock when the callback runs."""
        clock: Any = self.node.get_clock()

        def write(data: bytes, info: dict[str, Any]) -> None:
            self.bag.write(conn, arrival_ns(clock, info), data)
            self.counts[name] += 1
            self.last_source_ns[name] = max(self.last_source_ns[name], int(info.get('source_timestamp') or 0))
            if self.on_message is not None:
                self.on_message(name, self.counts[name])
        return MessageInfoCallback(write)

    def flush_if_due(self, now: float | None = None) -> bool:
        """Flush the bag if ``flush_interval`` seconds (monotonic) passed since the last flush."""
        now = time.monotonic() if now is None else now
        if now < self._next_flush:
            return False
        self.bag.flush()
        self._next_flush = now + self.flush_interval
        return True

    def seconds_to_flush(self) -> float:
        """Seconds until the next flush is due (0 if overdue)."""
        return max(0.0, self._next_flush - time.monotonic())

    def matched(self) -> bool:
        """True once every subscription has matched as many publishers as its topic had when discovered (at least
        one): several nodes may publish one topic (joint_states)."""
        return all(s.get_publisher_count() >= max(1, len(p.offered)) for s, p in zip(self._subs, self.plans,
                                                                                     strict=False))

    def handshake(self, executor: Executor, timeout_s: float, own: Collection[str] = ()) -> list[str]:
        """Wait until every publishing node has discovered this recorder's subscriptions.

        A parameter-service round trip with each publishing node (see ``node_params.fetch_parameters``):
        without it, the first messages could go out before a publisher has matched the new
        subscription, and be lost. Topics in ``own`` are published by the recorder's node itself: no other node
        to ask. Returns the nodes that could not be asked (no parameter services).
        """
        names: list[str] = []
        for plan in self.plans:
            if plan.name in own:
                continue
            for fqn in wait_for_node_names(self.node, executor, partial(publisher_nodes, self.node, plan.name),
                                           timeout_s, f'publishing {plan.name}'):
                if fqn not in names:
                    names.append(fqn)
        unreachable = []
        for fqn in names:
            try:
                handshake(self.node, executor, [fqn], timeout_s)
            except ReplayError:
                unreachable.append(fqn)
        return unreachable

    def _unsubscribe(self) -> None:
        for sub in self._subs:
            self.node.destroy_subscription(sub)
        self._subs = []

    def close(self) -> Path:
        """Stop recording and publish the complete bag at ``out``."""
        self._unsubscribe()
        return self.bag.commit()

    def abort(self) -> None:
        """Stop recording and leave nothing behind."""
        self._unsubscribe()
        self.bag.abort()


def record_until(executor: Executor, recorder: Recorder, stop: Callable[[], bool],
                 max_seconds: float | None = None) -> float:
    """Run callbacks until ``stop()`` or ``max_seconds``; return the seconds recorded.

    The bag is flushed every ``recorder.flush_interval`` seconds in between (a spin waits at most
    until the next flush is due, so a quiet topic does not delay it).
    """
    start = time.monotonic()
    while not stop():
        if max_seconds is not None and time.monotonic() - start >= max_seconds:
            break
        executor.spin_once(timeout_sec=min(0.1, recorder.seconds_to_flush()))
        recorder.flush_if_due()
    return time.monotonic() - start
