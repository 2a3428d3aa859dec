"""Shared helpers for tests that use the real ROS 2 middleware (rclpy). Used by the node and bag tests.

- ``DomainLease``/``lease_domain_id()``, ``node_command``: fourbar_ros.live.node_process, the domain leases the
  tools use (re-exported here for the tests); ``NodeProcess``: its node process, here also ending whatever is left
  of the process group and remembered for failure messages (the last lines each node wrote).
- ``RosSession``: an rclpy Context on a leased domain id (its own, or the one it is given: conftest's session
  fixture gives it the test process's; discovery limited to this host), a client node and an executor spinning in
  a thread; what a test created is destroyed through it
  (``destroy``, ``uncollect``, ``remove_node``), with the thread paused.
- ``Collector``: a subscription that stores messages and lets a test wait for them with a deadline (each message
  looked at once per wait, outside the lock).
- ``wait_for(predicate, timeout)``: poll a condition until a deadline (discovery, counts); never a bare sleep.
- ``RosSession.wait_subscribers``/``wait_publishers``: this side's match, failing with what this process's graph
  shows of the topic and the node's side (``RosSession.report``: the nodes' diagnostics counters, their last log
  lines).
- ``sync_probe``: prove every output path is connected on both sides (this side matched, and the node sending:
  it publishes an output only once it has matched a subscription) before a test starts counting messages.
- ``ONE_JOINT_STATE_PER_COMMAND``: node arguments that turn the joint_states republish off.

The pytest fixtures built on these (one session per run, cleaned after each module) are in conftest.py. The node
as a child process: ``with NodeProcess(args, ros.env()) as node:`` (always ended and reaped on leaving the block).
"""

from __future__ import annotations

import os
import threading
import time
import weakref
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager, suppress
from dataclasses import dataclass, field
from typing import Any, Generic, TypeVar

import rclpy
from rclpy.client import Client
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.service import Service
from rclpy.subscription import Subscription
from rclpy.timer import Timer

from fourbar_ros.live.node_process import DomainLease, lease_domain_id, node_command
from fourbar_ros.live.node_process import NodeProcess as _NodeProcess
from support.isolation import DISCOVERY_RANGE, isolated_env, kill_group

__all__ = ['TIMEOUT', 'Collector', 'DomainLease', 'NodeProcess', 'RosSession', 'Ticker', 'lease_domain_id',
           'node_command', 'node_logs', 'sync_probe', 'wait_for', 'wait_future']

#: Default deadline (s) for discovery and message waits; generous because the machine is shared.
TIMEOUT = 30.0
#: Longest single wait (s) of the session's executor thread (how late it sees a stop when idle).
SPIN_SLICE_S = 0.1
#: How long a failure message waits for the nodes' diagnostics (a little more than the shipped period, 1 s).
REPORT_WAIT_S = 2.5
#: Log lines of each node process quoted in a failure message.
REPORT_LOG_LINES = 8

M = TypeVar('M')


# --------------------------------------------------------------------------- waiting

def wait_for(predicate: Callable[[], bool], timeout: float = TIMEOUT, what: str = 'condition',
             poll: float = 0.01) -> None:
    """Poll ``predicate`` until it is true; raise AssertionError naming ``what`` at the deadline."""
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            raise AssertionError(f'timed out after {timeout} s waiting for {what}')
        time.sleep(poll)


class Collector(Generic[M]):
    """Messages received on one subscription, in arrival order, with a condition to wait on.

    A wait looks at each message once: it copies the new ones under the lock (those after the last it looked at)
    and evaluates its predicate outside it, so the executor thread that appends is never held up by a test's
    predicate, and a long stream costs a constant per message, not a rescan per arrival."""

    def __init__(self, topic: str) -> None:
        self.topic = topic
        self.messages: list[M] = []
        self._cond = threading.Condition()
        self._dropped = 0  # messages forgotten by clear(): the absolute index of messages[0]
        self._listeners: set[threading.Event] = set()
        self.subscription: Any = None

    def __call__(self, msg: M) -> None:
        with self._cond:
            self.messages.append(msg)
            self._cond.notify_all()
            for event in self._listeners:
                event.set()

    def __len__(self) -> int:
        with self._cond:
            return len(self.messages)

    def listen(self, event: threading.Event, on: bool = True) -> None:
        """Set ``event`` on every message from now on (``on=False``: no more)."""
        with self._cond:
            (self._listeners.add if on else self._listeners.discard)(event)

    def _side(self) -> str:
        sub = self.subscription
        try:
            matched = sub.get_publisher_count() if sub is not None else 'no subscription'
        except Exception as exc:
            matched = f'unknown ({exc})'
        return f'{len(self.messages)} received, this subscription matched with {matched} publisher(s)'

    def wait_count(self, count: int, timeout: float = TIMEOUT) -> list[M]:
        """Block until at least ``count`` messages arrived; return a copy of all of them."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while len(self.messages) < count:
                left = deadline - time.monotonic()
                if left <= 0:
                    side = self._side()
                    break
                self._cond.wait(left)
            else:
                return list(self.messages)
        # Outside the lock: the report waits for the executor thread, which may be waiting for the lock.
        raise AssertionError(f'timed out after {timeout} s waiting for {count} messages on {self.topic}: '
                             f'{side}{_report([self.topic])}')

    def wait_match(self, predicate: Callable[[M], bool], timeout: float = TIMEOUT, start: int = 0) -> M:
        """Block until a message at index >= ``start`` satisfies ``predicate``; return it."""
        deadline = time.monotonic() + timeout
        with self._cond:
            seen = self._dropped + start  # absolute index of the next message to look at
        checked = 0
        new: list[M] = []
        while True:
            with self._cond:
                while len(self.messages) + self._dropped <= seen:
                    left = deadline - time.monotonic()
                    if left <= 0:
                        side = self._side()
                        last = repr(self.messages[-1])[:300] if self.messages else 'none'
                        break
                    self._cond.wait(left)
                else:
                    first = max(seen - self._dropped, 0)
                    new = self.messages[first:]
                    seen = self._dropped + len(self.messages)
                    side = ''
            if side:
                break
            checked += len(new)
            for msg in new:
                if predicate(msg):
                    return msg
        raise AssertionError(f'timed out after {timeout} s waiting for a matching message on {self.topic}: '
                             f'{checked} looked at, none matched; {side}; last: {last}{_report([self.topic])}')

    def drop_while(self, predicate: Callable[[M], bool]) -> int:
        """Forget the leading messages that satisfy ``predicate``; how many."""
        with self._cond:
            n = 0
            while n < len(self.messages) and predicate(self.messages[n]):
                n += 1
            del self.messages[:n]
            self._dropped += n
            return n

    def clear(self) -> None:
        """Forget the messages received so far."""
        with self._cond:
            self._dropped += len(self.messages)
            self.messages.clear()


# --------------------------------------------------------------------------- node processes

_NODES: list[weakref.ref[NodeProcess]] = []  # the node processes this test process started (for failure messages)


class NodeProcess(_NodeProcess):
    """fourbar_ros.live.node_process.NodeProcess, which also ends what is left of its process group (anything the
    node started) when it is killed or has exited, and is remembered for ``node_logs``."""

    def start(self) -> NodeProcess:
        super().start()
        _NODES[:] = [ref for ref in _NODES if ref() is not None]
        _NODES.append(weakref.ref(self))
        return self

    def __enter__(self) -> NodeProcess:
        return self.start()

    def wait_exit(self, timeout_s: float = 30.0) -> int:
        try:
            return super().wait_exit(timeout_s)
        finally:
            if self.proc is not None:
                kill_group(self.proc.pid)

    def kill(self) -> None:
        super().kill()
        if self.proc is not None:
            kill_group(self.proc.pid)


def node_logs(lines: int = REPORT_LOG_LINES) -> list[str]:
    """The last ``lines`` lines of every node process started here and not yet collected, one entry each."""
    out = []
    for ref in _NODES:
        node = ref()
        if node is None or node.proc is None:
            continue
        state = 'running' if node.running() else f'exited {node.proc.returncode}'
        tail = [x for x in node.stderr_now().splitlines() if x.strip()][-lines:]
        out.append(f'node process {node.proc.pid} ({state}; {" ".join(node.args)[:160]}), last lines: '
                   + (' | '.join(tail) if tail else '(none)'))
    return out


_SESSIONS: list[RosSession] = []  # the open session of this test process


def _report(topics: Sequence[str] = ()) -> str:
    """``RosSession.report`` of the open session (else the node processes' last lines), for failure messages."""
    if _SESSIONS:
        return _SESSIONS[-1].report(topics)
    return ''.join(f'\n  {line}' for line in node_logs())


# --------------------------------------------------------------------------- session

@dataclass
class RosSession:
    """rclpy on a leased domain id: context, client node, executor thread. Use as a context manager.

    rclpy's executor is not safe against an entity destroyed while its thread builds a wait set (an event handler
    then raises InvalidHandle there, and the thread dies): every destruction goes through ``paused()``, which holds
    the thread between two bounded spins.
    """

    node_name: str = 'fourbar_test_client'
    lease: DomainLease | None = None
    context: Context = field(default_factory=Context)
    node: Any = None
    executor: Any = None
    _thread: threading.Thread | None = None
    _owned_lease: bool = False
    _spin_lock: threading.Lock = field(default_factory=threading.Lock)  # held by the thread while it spins
    _running: threading.Event = field(default_factory=threading.Event)  # clear: the thread waits before spinning
    _stopping: bool = False

    @property
    def domain_id(self) -> int:
        assert self.lease is not None
        return self.lease.domain_id

    def __enter__(self) -> RosSession:
        if self.lease is None:  # a domain of its own (conftest's session passes the test process's domain)
            self.lease = lease_domain_id()
            self._owned_lease = True
        # rcl reads the discovery range from the environment when the context is initialized (the test process
        # has it already: support.isolation); the domain id is given to rclpy, not written there.
        os.environ.update(DISCOVERY_RANGE)
        os.environ.pop('ROS_LOCALHOST_ONLY', None)
        try:
            rclpy.init(context=self.context, domain_id=self.lease.domain_id)
            self.executor = SingleThreadedExecutor(context=self.context)
            self.node = Node(self.node_name, context=self.context)
            self.executor.add_node(self.node)
            self._running.set()
            self._thread = threading.Thread(target=self._spin, name='ros-executor', daemon=True)
            self._thread.start()
        except BaseException:
            self.close()
            raise
        _SESSIONS.append(self)
        return self

    def _spin(self) -> None:
        from rclpy.executors import ExternalShutdownException

        with suppress(ExternalShutdownException):
            while not self._stopping and self.context.ok():
                self._running.wait()
                with self._spin_lock:
                    if self._running.is_set() and not self._stopping:
                        self.executor.spin_once(timeout_sec=SPIN_SLICE_S)

    @contextmanager
    def paused(self) -> Iterator[None]:
        """The executor thread holds still (outside any wait set) while the block runs."""
        self._running.clear()
        self.executor.wake()  # ends the running wait at once
        try:
            with self._spin_lock:
                yield
        finally:
            self._running.set()

    def wait_for(self, predicate: Callable[[], bool], timeout: float = TIMEOUT, what: str = 'condition') -> None:
        """``wait_for`` with ``predicate`` evaluated between two callbacks of the executor thread (``paused``): a
        callback that has counted something has also finished what it does after counting."""

        def between() -> bool:
            with self.paused():
                return predicate()

        wait_for(between, timeout, what)

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Stop the executor, destroy nodes, shut the context down, release the domain id."""
        if self in _SESSIONS:
            _SESSIONS.remove(self)
        self._stopping = True
        self._running.set()
        if self.executor is not None:
            self.executor.shutdown(timeout_sec=5.0)
        if self._thread is not None:
            self.context.try_shutdown()
            self._thread.join(timeout=10.0)
        if self.node is not None:
            self.node.destroy_node()
            self.node = None
        self.context.try_shutdown()
        if self._owned_lease and self.lease is not None:
            self.lease.release()

    def entities(self) -> set[Any]:
        """What the client node and the executor hold now (for ``destroy_entities_since``)."""
        node = self.node
        return {*node.subscriptions, *node.publishers, *node.clients, *node.services, *node.timers,
                *self.executor.get_nodes()}

    def destroy(self, *entities: Any) -> None:
        """Destroy the client node's publishers, subscriptions, clients, services or timers, and Collectors'
        subscriptions, with the executor thread paused."""
        node = self.node
        by_kind = ((Subscription, node.destroy_subscription), (Publisher, node.destroy_publisher),
                   (Client, node.destroy_client), (Service, node.destroy_service), (Timer, node.destroy_timer))
        with self.paused():
            for item in entities:
                entity = item.subscription if isinstance(item, Collector) else item
                next(destroy for kind, destroy in by_kind if isinstance(entity, kind))(entity)

    def destroy_entities_since(self, before: set[Any]) -> None:
        """Destroy what was added after ``entities()`` returned ``before``: endpoints, timers and extra nodes."""
        node = self.node
        added = [e for kind in (node.subscriptions, node.publishers, node.clients, node.services, node.timers)
                 for e in kind if e not in before]
        self.destroy(*added)
        for extra in [n for n in self.executor.get_nodes() if n not in before]:
            self.remove_node(extra)

    def env(self, **extra: str) -> dict[str, str]:
        """Environment for a child process on this session's domain id, discovery limited to this host (as this
        process's)."""
        env = isolated_env(os.environ, self.domain_id)
        env.setdefault('PYTHONUNBUFFERED', '1')
        env.update(extra)
        return env

    def add_node(self, node: Node) -> None:
        """Spin another node (e.g. the node under test, in-process) in the executor thread."""
        self.executor.add_node(node)
        self.executor.wake()

    def remove_node(self, node: Node) -> None:
        """Stop spinning ``node`` and destroy it (the executor thread paused)."""
        with self.paused():
            self.executor.remove_node(node)
            node.destroy_node()

    def collect(self, msg_type: type[M], topic: str, qos: Any = 1000) -> Collector[M]:
        """Subscribe the client node to ``topic``; messages land in the returned Collector."""
        collector: Collector[M] = Collector(topic)
        collector.subscription = self.node.create_subscription(msg_type, topic, collector, qos)
        self.executor.wake()
        return collector

    def uncollect(self, collector: Collector[Any]) -> None:
        """Destroy a Collector's subscription."""
        self.destroy(collector)

    def publisher(self, msg_type: type, topic: str, qos: Any = 1000) -> Any:
        """A client publisher."""
        return self.node.create_publisher(msg_type, topic, qos)

    def wait_subscribers(self, publisher: Any, count: int = 1, timeout: float = TIMEOUT) -> None:
        """Wait until ``publisher`` is matched with ``count`` subscriptions (this side's match: whether the other
        side has matched this publisher shows only in what it does, see ``sync_probe``). Enough for a reliable
        topic (the node's commands): a reliable writer keeps what it sent for a reader it has matched until that
        reader, once it has matched the writer too, acknowledges it. Not for a best-effort one (/clock): samples
        sent before the reader's match are lost (``sync_probe``'s ``ready``)."""
        try:
            wait_for(lambda: publisher.get_subscription_count() >= count, timeout,
                     f'{count} subscriber(s) on {publisher.topic_name}')
        except AssertionError as exc:
            raise AssertionError(f'{exc}: this publisher matched {publisher.get_subscription_count()}'
                                 f'{self.report([publisher.topic_name])}') from None

    def wait_publishers(self, collector: Collector[Any], count: int = 1, timeout: float = TIMEOUT) -> None:
        """Wait until a Collector's subscription is matched with ``count`` publishers (this side's match, as
        ``wait_subscribers``)."""
        sub = collector.subscription
        try:
            wait_for(lambda: sub.get_publisher_count() >= count, timeout,
                     f'{count} publisher(s) on {sub.topic_name}')
        except AssertionError as exc:
            raise AssertionError(f'{exc}: {collector._side()}{self.report([sub.topic_name])}') from None

    def graph(self, topic: str) -> str:
        """What this process's graph shows of ``topic``: the nodes of its publishers and subscriptions."""
        def names(infos: Any) -> list[str]:
            return sorted(f'{i.node_namespace.rstrip("/")}/{i.node_name}' for i in infos)
        node = self.node
        return (f'{topic}: publishers {names(node.get_publishers_info_by_topic(topic))}, subscriptions '
                f'{names(node.get_subscriptions_info_by_topic(topic))}')

    def diagnostics(self, wait_s: float = REPORT_WAIT_S) -> dict[str, dict[str, str]]:
        """The latest status of every node publishing diagnostics on this domain, by status name, waited for up
        to ``wait_s`` (a node publishes its status only while someone subscribes: it does from now on)."""
        from diagnostic_msgs.msg import DiagnosticArray

        topics = [name for name, types in self.node.get_topic_names_and_types()
                  if 'diagnostic_msgs/msg/DiagnosticArray' in types]
        if not topics:
            return {}
        arrived = threading.Event()
        collectors = [self.collect(DiagnosticArray, topic, 10) for topic in topics]
        try:
            for col in collectors:
                col.listen(arrived)
            deadline = time.monotonic() + wait_s
            while not all(len(c) for c in collectors):
                left = deadline - time.monotonic()
                if left <= 0:
                    break
                arrived.wait(left)
                arrived.clear()
            # The latest status per name and publisher: nodes of one name in two namespaces publish the same name.
            statuses: dict[str, dict[str, str]] = {}
            for col in collectors:
                latest: dict[tuple[str, str], dict[str, str]] = {}
                for msg in list(col.messages):
                    for status in msg.status:
                        values = {kv.key: kv.value for kv in status.values}
                        latest[(status.name, values.get('mode', ''))] = values
                for (name, mode), values in latest.items():
                    statuses[f'{name} (mode {mode})' if mode else name] = values
            return statuses
        finally:
            self.destroy(*collectors)

    def report(self, topics: Sequence[str] = ()) -> str:
        """For a failure message: this process's graph of ``topics``, the nodes' diagnostics (their counters),
        and the last lines each node process of this test process wrote."""
        lines = []
        try:
            lines.extend(f'this side\'s graph of {self.graph(topic)}' for topic in topics)
            statuses = self.diagnostics()
            lines.extend(f'diagnostics of {name}: {values}' for name, values in statuses.items())
            if not statuses:
                lines.append(f'no diagnostics received within {REPORT_WAIT_S} s')
        except Exception as exc:
            lines.append(f'(graph or diagnostics unavailable: {exc!r})')
        lines.extend(node_logs())
        return ''.join(f'\n  {line}' for line in lines)


# --------------------------------------------------------------------------- end-to-end sync

#: fourbar_node arguments (after ``--ros-args``) for exactly one JointState per served command: no republish.
ONE_JOINT_STATE_PER_COMMAND: tuple[str, ...] = ('-p', 'joint_state_rate:=0.0')


def sync_probe(publish: Callable[[float], None], collectors: Sequence[Collector[Any]],
               probes: Sequence[float], matches: Callable[[Collector[Any], Any, float], bool],
               timeout: float = TIMEOUT, interval: float = 0.05,
               ready: Callable[[Any], bool] | None = None) -> None:
    """Send probe commands until every collector has answered, then wait for the answers still in flight.

    Every collector must carry exactly one message per served command: ``input_torque``, or ``joint_states``
    of a node started with ``ONE_JOINT_STATE_PER_COMMAND`` (the node otherwise republishes its last pose on
    joint_states after a pause, and a repeat would count as one answer too many).

    Discovery is not symmetric: this side may see the node's publishers before the node sees this side's
    subscriptions, and the node skips outputs nobody subscribes to. So probe ``probes[i]`` one at a time
    (``interval`` s apart) until each collector received an answer; ``matches(collector, msg, probe)``
    says which probe a message answers. Answers come in order, so once a collector's first answer is to
    probe j, it will also answer every later probe: wait for exactly those, then clear all collectors.

    ``ready(msg)``, if given, says an answer shows the node fully connected on another input too, and earlier
    answers are dropped: e.g. a sim-time node's answer stamped on the test's /clock (best effort: the node's clock
    subscription takes samples only once it has matched the test's publisher, which this side cannot see).
    """
    deadline = time.monotonic() + timeout
    sent = 0
    first: dict[int, int] = {}
    topics = [c.topic for c in collectors]

    def sides() -> str:
        return '; '.join(f'{c.topic}: {c._side()}' for c in collectors)

    arrived = threading.Event()
    for col in collectors:
        col.listen(arrived)
    try:
        while len(first) < len(collectors):
            if sent >= len(probes) or time.monotonic() >= deadline:
                why = f'timed out after {timeout} s' if sent < len(probes) else f'all {len(probes)} probes sent'
                raise AssertionError(f'{why} without an answer on every output ({sent} probes sent): {sides()}'
                                     f'{_report(topics)}')
            publish(probes[sent])
            sent += 1
            step_deadline = min(deadline, time.monotonic() + interval)
            while len(first) < len(collectors):
                arrived.clear()  # before looking: an answer arriving after the look sets it again
                for idx, col in enumerate(collectors):
                    if idx in first:
                        continue
                    if ready is not None:
                        col.drop_while(lambda m: not ready(m))
                    if not len(col):
                        continue
                    msg = col.messages[0]
                    answered = [j for j in range(sent) if matches(col, msg, probes[j])]
                    if not answered:
                        raise AssertionError(f'first message on {col.topic} answers no probe: {msg}')
                    first[idx] = answered[0]
                left = step_deadline - time.monotonic()
                if len(first) == len(collectors) or left <= 0:
                    break
                arrived.wait(left)
    finally:
        for col in collectors:
            col.listen(arrived, on=False)
    for idx, col in enumerate(collectors):
        col.wait_count(sent - first[idx], max(1.0, deadline - time.monotonic()))
        if len(col) != sent - first[idx]:
            raise AssertionError(f'{col.topic}: {len(col)} answers to {sent - first[idx]} probes ({sent} sent, '
                                 f'the first answered was probe {first[idx]}): {sides()}')
    for col in collectors:
        col.clear()


# --------------------------------------------------------------------------- paced publishing

class Ticker:
    """Calls ``tick(now)`` (``now``: time.monotonic()) at ``hz`` from a thread, paced by a deadline; a tick that
    falls more than 0.1 s behind (a busy machine) restarts the schedule instead of bursting to catch up."""

    def __init__(self, hz: float, tick: Callable[[float], None]) -> None:
        self._period = 1.0 / hz
        self._tick = tick
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name='ticker', daemon=True)

    def __enter__(self) -> Ticker:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join(timeout=10.0)

    def _run(self) -> None:
        next_t = time.monotonic()
        while not self._stop.is_set():
            self._tick(time.monotonic())
            next_t += self._period
            delay = next_t - time.monotonic()
            if delay > 0:
                self._stop.wait(delay)
            elif delay < -0.1:
                next_t = time.monotonic()


def wait_future(future: Any, timeout: float = TIMEOUT, what: str = 'a service response') -> Any:
    """Wait for an rclpy Future completed by the executor thread; return its result."""
    wait_for(future.done, timeout, what)
    return future.result()
