"""Shared helpers for tests that use the real ROS 2 middleware (rclpy). Used by the node and bag tests.

- ``DomainLease``/``lease_domain_id()``: a ROS_DOMAIN_ID no concurrent run holds (an flock per id).
- ``RosSession``: an rclpy Context on that domain id, a client node and an executor spinning in a thread.
- ``Collector``: a subscription that stores messages and lets a test wait for them with a deadline.
- ``wait_for(predicate, timeout)``: poll a condition until a deadline (discovery, counts); never a bare sleep.
- ``NodeProcess``: ``fourbar_node`` as a separate process (console script, ``--ros-args``), on the leased
  domain id, always terminated and then killed on every path.
- ``sync_probe``: prove every output path is connected end to end before a test starts counting messages.

The pytest fixtures built on these (one session per run, cleaned after each module) are in conftest.py.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import ExitStack, contextmanager, suppress
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Generic, TypeVar

import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node

from fourbar_ros.bags.domain import FREE_DOMAIN_IDS, free_domain_id

REPO = Path(__file__).resolve().parent.parent
#: Default deadline (s) for discovery and message waits; generous because the machine is shared.
TIMEOUT = 30.0
#: Domain ids tests may lease: the ranges that are safe on Linux (ports below the ephemeral range),
#: minus 10-89, which developers use for manual experiments.
TEST_DOMAIN_IDS: tuple[int, ...] = FREE_DOMAIN_IDS

M = TypeVar('M')


# --------------------------------------------------------------------------- domain ids

@dataclass
class DomainLease:
    """A held ROS_DOMAIN_ID (fourbar_ros.bags.domain.free_domain_id's lock), given back by ``release()``."""

    domain_id: int
    _hold: ExitStack

    def release(self) -> None:
        """Give the id back (idempotent)."""
        self._hold.close()


def lease_domain_id(candidates: Sequence[int] = TEST_DOMAIN_IDS) -> DomainLease:
    """A free id among ``candidates``: the same lock files and port check the bag tools and the demo use, so
    concurrent pytest runs, benchmarks and demos on this machine never share a domain; a crashed run's lock
    disappears with its process."""
    hold = ExitStack()
    return DomainLease(hold.enter_context(free_domain_id(candidates)), hold)


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
    """rclpy on a leased domain id: context, client node, executor thread. Use as a context manager."""

    node_name: str = 'fourbar_test_client'
    lease: DomainLease | None = None
    context: Context = field(default_factory=Context)
    node: Any = None
    executor: Any = None
    _thread: threading.Thread | None = None
    _owned_lease: bool = False

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
            self._thread = threading.Thread(target=self._spin, name='ros-executor', daemon=True)
            self._thread.start()
        except BaseException:
            self.close()
            raise
        return self

    def _spin(self) -> None:
        from rclpy.executors import ExternalShutdownException

        with suppress(ExternalShutdownException):
            self.executor.spin()

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Stop the executor, destroy nodes, shut the context down, release the domain id."""
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

    def destroy_entities_since(self, before: set[Any]) -> None:
        """Destroy what was added after ``entities()`` returned ``before``: endpoints, timers and extra nodes."""
        node = self.node
        for kinds, destroy in ((node.subscriptions, node.destroy_subscription),
                               (node.publishers, node.destroy_publisher), (node.clients, node.destroy_client),
                               (node.services, node.destroy_service), (node.timers, node.destroy_timer)):
            for entity in [e for e in kinds if e not in before]:
                destroy(entity)
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
        """Stop spinning ``node`` and destroy it."""
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
        self.node.destroy_subscription(collector.subscription)

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

def sync_probe(publish: Callable[[float], None], collectors: Sequence[Collector[Any]],
               probes: Sequence[float], matches: Callable[[Collector[Any], Any, float], bool],
               timeout: float = TIMEOUT, interval: float = 0.05) -> None:
    """Send probe commands until every collector has answered, then wait for the answers still in flight.

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


# --------------------------------------------------------------------------- node process

def node_command() -> list[str]:
    """How to start ``fourbar_node``: the console script next to this Python, else ``python -m``."""
    script = Path(sys.executable).parent / 'fourbar_node'
    if script.exists():
        return [str(script)]
    return [sys.executable, '-m', 'fourbar_ros.node.fourbar_node']


@dataclass
class NodeProcess:
    """``fourbar_node --ros-args ...`` as a child process; ``stop()`` or leaving the ``with`` ends it."""

    args: Sequence[str]
    env: dict[str, str]
    command: Sequence[str] = field(default_factory=node_command)
    cwd: Path = REPO
    proc: subprocess.Popen[bytes] | None = None
    stdout: str = ''
    stderr: str = ''
    _out: Any = None
    _err: Any = None

    def __enter__(self) -> NodeProcess:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.kill()

    def start(self) -> None:
        """Start the process (its own session, so signals reach only it). Output goes to temporary
        files, not pipes, so a chatty node can never block on a full pipe."""
        self._out = tempfile.TemporaryFile()  # noqa: SIM115 - closed in _collect_output
        self._err = tempfile.TemporaryFile()  # noqa: SIM115
        self.proc = subprocess.Popen([*self.command, *self.args], env=self.env, cwd=self.cwd,
                                     stdout=self._out, stderr=self._err, start_new_session=True)

    def _collect_output(self) -> None:
        for name in ('_out', '_err'):
            f = getattr(self, name)
            if f is None:
                continue
            f.seek(0)
            setattr(self, 'stdout' if name == '_out' else 'stderr', f.read().decode('utf-8', 'replace'))
            f.close()
            setattr(self, name, None)

    def stderr_now(self) -> str:
        """What the running process wrote to stderr so far (the file stays open)."""
        if self._err is None:
            return self.stderr
        self._err.seek(0)
        return str(self._err.read().decode('utf-8', 'replace'))

    def running(self) -> bool:
        """True while the process has not exited."""
        return self.proc is not None and self.proc.poll() is None

    def wait_exit(self, timeout: float = TIMEOUT) -> int:
        """Wait for the process to exit by itself; return its status and keep its output."""
        assert self.proc is not None
        try:
            self.proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.kill()
            raise AssertionError(f'{self.command} did not exit within {timeout} s') from None
        self._collect_output()
        return self.proc.returncode

    def stop(self, sig: int = signal.SIGINT, timeout: float = TIMEOUT) -> int:
        """Send ``sig`` and wait for the exit status (killed after ``timeout`` s)."""
        assert self.proc is not None
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
        return self.wait_exit(timeout)

    def kill(self) -> None:
        """Terminate, then kill; always reaps the process (safe to call repeatedly)."""
        proc = self.proc
        if proc is None:
            return
        for send, wait in ((proc.terminate, 5.0), (proc.kill, 10.0)):
            if proc.poll() is not None:
                break
            send()
            try:
                proc.wait(timeout=wait)
                break
            except subprocess.TimeoutExpired:
                continue
        if proc.returncode is None:
            proc.wait()
        self._collect_output()


@contextmanager
def node_process(args: Sequence[str], env: dict[str, str]) -> Iterator[NodeProcess]:
    """``with node_process([...], ros.env()) as p:`` — the node as a child process, always cleaned up."""
    proc = NodeProcess(args, env)
    proc.start()
    try:
        yield proc
    finally:
        proc.kill()


def wait_future(future: Any, timeout: float = TIMEOUT, what: str = 'a service response') -> Any:
    """Wait for an rclpy Future completed by the executor thread; return its result."""
    wait_for(future.done, timeout, what)
    return future.result()
