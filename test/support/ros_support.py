"""Shared helpers for tests that use the real ROS 2 middleware (rclpy). Used by the node and bag tests.

- ``DomainLease``/``lease_domain_id()``, ``NodeProcess``, ``node_command``: fourbar_ros.live.node_process, the
  domain leases and node process the tools use (re-exported here for the tests).
- ``RosSession``: an rclpy Context on that domain id, a client node and an executor spinning in a thread; what a
  test created is destroyed through it (``destroy``, ``uncollect``, ``remove_node``), with the thread paused.
- ``Collector``: a subscription that stores messages and lets a test wait for them with a deadline.
- ``wait_for(predicate, timeout)``: poll a condition until a deadline (discovery, counts); never a bare sleep.
- ``sync_probe``: prove every output path is connected end to end before a test starts counting messages.
- ``ONE_JOINT_STATE_PER_COMMAND``: node arguments that turn the joint_states republish off.

The pytest fixtures built on these (one session per run, cleaned after each module) are in conftest.py. The node
as a child process: ``with NodeProcess(args, ros.env()) as node:`` (always ended and reaped on leaving the block).
"""

from __future__ import annotations

import os
import threading
import time
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

from fourbar_ros.live.node_process import DomainLease, NodeProcess, lease_domain_id, node_command

__all__ = ['TIMEOUT', 'Collector', 'DomainLease', 'NodeProcess', 'RosSession', 'Ticker', 'lease_domain_id',
           'node_command', 'sync_probe', 'wait_for', 'wait_future']

#: Default deadline (s) for discovery and message waits; generous because the machine is shared.
TIMEOUT = 30.0
#: Longest single wait (s) of the session's executor thread (how late it sees a stop when idle).
SPIN_SLICE_S = 0.1

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
    """Messages received on one subscription, in arrival order, with a condition to wait on."""

    def __init__(self, topic: str) -> None:
        self.topic = topic
        self.messages: list[M] = []
        self._cond = threading.Condition()
        self.subscription: Any = None

    def __call__(self, msg: M) -> None:
        with self._cond:
            self.messages.append(msg)
            self._cond.notify_all()

    def __len__(self) -> int:
        with self._cond:
            return len(self.messages)

    def wait_count(self, count: int, timeout: float = TIMEOUT) -> list[M]:
        """Block until at least ``count`` messages arrived; return a copy of all of them."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while len(self.messages) < count:
                left = deadline - time.monotonic()
                if left <= 0:
                    raise AssertionError(
                        f'timed out after {timeout} s: {len(self.messages)} of {count} messages on {self.topic}')
                self._cond.wait(left)
            return list(self.messages)

    def wait_match(self, predicate: Callable[[M], bool], timeout: float = TIMEOUT, start: int = 0) -> M:
        """Block until a message at index >= ``start`` satisfies ``predicate``; return it."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while True:
                for msg in self.messages[start:]:
                    if predicate(msg):
                        return msg
                left = deadline - time.monotonic()
                if left <= 0:
                    raise AssertionError(f'timed out after {timeout} s waiting for a matching message on {self.topic}')
                self._cond.wait(left)

    def clear(self) -> None:
        """Forget the messages received so far."""
        with self._cond:
            self.messages.clear()


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
        if self.lease is None:
            self.lease = lease_domain_id()
            self._owned_lease = True
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

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Stop the executor, destroy nodes, shut the context down, release the domain id."""
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
        """Environment for a child process on this session's domain id."""
        env = dict(os.environ)
        env['ROS_DOMAIN_ID'] = str(self.domain_id)
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
        """Wait until ``publisher`` is matched with ``count`` subscriptions."""
        wait_for(lambda: publisher.get_subscription_count() >= count, timeout,
                 f'{count} subscriber(s) on {publisher.topic_name}')

    def wait_publishers(self, collector: Collector[Any], count: int = 1, timeout: float = TIMEOUT) -> None:
        """Wait until a Collector's subscription is matched with ``count`` publishers."""
        sub = collector.subscription
        wait_for(lambda: sub.get_publisher_count() >= count, timeout,
                 f'{count} publisher(s) on {sub.topic_name}')


# --------------------------------------------------------------------------- end-to-end sync

#: fourbar_node arguments (after ``--ros-args``) for exactly one JointState per served command: no republish.
ONE_JOINT_STATE_PER_COMMAND: tuple[str, ...] = ('-p', 'joint_state_rate:=0.0')


def sync_probe(publish: Callable[[float], None], collectors: Sequence[Collector[Any]],
               probes: Sequence[float], matches: Callable[[Collector[Any], Any, float], bool],
               timeout: float = TIMEOUT, interval: float = 0.05) -> None:
    """Send probe commands until every collector has answered, then wait for the answers still in flight.

    Every collector must carry exactly one message per served command: ``input_torque``, or ``joint_states``
    of a node started with ``ONE_JOINT_STATE_PER_COMMAND`` (the node otherwise republishes its last pose on
    joint_states after a pause, and a repeat would count as one answer too many).

    Discovery is not symmetric: this side may see the node's publishers before the node sees this side's
    subscriptions, and the node skips outputs nobody subscribes to. So probe ``probes[i]`` one at a time
    (``interval`` s apart) until each collector received an answer; ``matches(collector, msg, probe)``
    says which probe a message answers. Answers come in order, so once a collector's first answer is to
    probe j, it will also answer every later probe: wait for exactly those, then clear all collectors.
    """
    deadline = time.monotonic() + timeout
    sent = 0
    first: dict[int, int] = {}
    while len(first) < len(collectors):
        if sent >= len(probes):
            raise AssertionError(f'{len(probes)} probes sent without an answer on every output')
        publish(probes[sent])
        sent += 1
        step_deadline = min(deadline, time.monotonic() + interval)
        while time.monotonic() < step_deadline and len(first) < len(collectors):
            for idx, col in enumerate(collectors):
                if idx in first or not len(col):
                    continue
                msg = col.messages[0]
                answered = [j for j in range(sent) if matches(col, msg, probes[j])]
                if not answered:
                    raise AssertionError(f'first message on {col.topic} answers no probe: {msg}')
                first[idx] = answered[0]
            time.sleep(0.005)
        if time.monotonic() >= deadline:
            raise AssertionError(f'timed out after {timeout} s probing {[c.topic for c in collectors]}')
    for idx, col in enumerate(collectors):
        col.wait_count(sent - first[idx], max(1.0, deadline - time.monotonic()))
        if len(col) != sent - first[idx]:
            raise AssertionError(f'{col.topic}: {len(col)} answers to {sent - first[idx]} probes')
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
