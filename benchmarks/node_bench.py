"""fourbar_node against a bare rclpy relay, measured in the same run: ``python -m benchmarks.node_bench [--quick]``.

Figures (printed as JSON; ``run(quick)`` returns them for benchmarks/run.py):
- latency: command (std_msgs/Float64) to JointState round trip seen by a client, median and p99, for the shipped
  node and for a relay process on the same (default) executor (Float64 in, JointState out with the same fields
  filled, no math, same QoS), alternating ping by ping so machine load hits both alike. Commands cycle
  through distinct angles, so the node's repeat cache never helps. Measured with only joint_states subscribed
  (the other outputs are then skipped) and again with every output subscribed.
- rate: the highest command rate each sustains without loss: every command of a trial (``duration`` s at that
  rate) answered, and the last answer within 0.25 s of the last command (a backlog that grows over the trial
  shows up as lag). Doubling from 250 Hz to the first failure, then bisection; the full run alternates three
  rounds and reports each side's median round (all rounds are listed too).
- executors: the same paced load for four processes, interleaved: a bare relay and fourbar_node, each on
  rclpy's SingleThreadedExecutor and on its EventsExecutor (``--executor``; the node with the default
  executor is started without the option, as a user starts it). Commands at 200 Hz, one outstanding at a
  time, in blocks that rotate between the four every round (3 rounds); per process the round-trip median
  and p99 and its CPU time per command (every thread of the process, idle timers included, from /proc).
  Ratios are against the relay on the SingleThreadedExecutor. Targets: the shipped node's median latency
  <= 0.85x and CPU per command <= 0.6x that relay's.
- skipped work: the node's command callback timed in-process (per call, microseconds) with subscribers (in a
  separate process) on joint_states only, on both per-command outputs (joint_states, input_torque), and on
  none, interleaved call by call with the relay's callback (so the node's extra CPU per command is measured
  even when machine load blurs the round trips); and the marker and diagnostics timer callbacks with and
  without a subscriber.
Targets (node vs relay on one executor): latency ratio <= 1.10, rate ratio >= 0.9. No figure here is
asserted by any test.

Completion section (``--completion``, ``run_completion(quick)``): the same paced, interleaved executor rounds for
measured joint_states in, completed state out. The client publishes the driven joint's JointState (position,
velocity, effort) at 200 Hz, one outstanding, and waits for the completed JointState: fourbar_node in
``mode:=trajectory`` (its joint_states, the client's own measurement filtered out) against a bare relay
(``relay --measured``: JointState in, a JointState of the same shape out on ``relayed_joint_states``, so it never
receives its own output while the node does). Same targets for the shipped node against the relay on the
SingleThreadedExecutor; the 1-minute load average at start and end is recorded.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import ExitStack, contextmanager
from pathlib import Path
from typing import Any, NamedTuple

from fourbar_ros.live.node_process import free_domain_id

REPO = Path(__file__).resolve().parent.parent
YAML = REPO / 'config' / 'antenna.yaml'
DEPTH = 1000
PACED_HZ = 200.0  # command rate of the executor comparison (one outstanding at a time)
LAG_S = 0.25  # a rate is sustained if the last answer comes at most this long after the last command
RELAYED = 'relayed_joint_states'  # the measured relay's output topic


# --------------------------------------------------------------------------- helper processes

def relay_callback(node: Any, pub: Any) -> Callable[[Any], None]:
    """The baseline's work per command: a JointState with the node's message shape (stamp, two names, two
    positions, two velocities, two efforts), all copies of the command: no math."""
    from sensor_msgs.msg import JointState

    names = ['rocker_ab_joint', 'rocker_cd_joint']
    clock = node.get_clock()

    def relay(msg: Any) -> None:
        out = JointState()
        out.header.stamp = clock.now().to_msg()
        out.name = names
        out.position = [msg.data, msg.data]
        out.velocity = [msg.data, msg.data]
        out.effort = [msg.data, 0.0]
        pub.publish(out)

    return relay


def measured_relay_callback(pub: Any) -> Callable[[Any], None]:
    """The completion's baseline per measurement: a JointState with the completed message's shape (the
    measurement's stamp, two names, two positions, two velocities when measured, no efforts), all copies of the
    measured joint: no math, no check."""
    from sensor_msgs.msg import JointState

    names = ['rocker_cd_joint', 'coupler_joint']

    def relay(msg: Any) -> None:
        out = JointState()
        out.header.stamp = msg.header.stamp
        out.name = names
        q = msg.position[0]
        out.position = [q, q]
        if msg.velocity:
            out.velocity = [msg.velocity[0], msg.velocity[0]]
        pub.publish(out)

    return relay


def relay_main(argv: Sequence[str]) -> int:
    """The baseline process: subscribe Float64 ``antenna_angle_cmd``, publish ``joint_states`` (relay_callback);
    with ``--measured``, subscribe JointState ``joint_states`` and publish ``relayed_joint_states``
    (measured_relay_callback: another topic, so a bare relay never receives its own output).

    ``--executor single|events`` (before ``--ros-args``) picks the executor; it is spun the way fourbar_node
    spins its own (fourbar_ros.ros_executor), and SIGINT/SIGTERM end it.
    """
    import signal

    import rclpy
    import rclpy.utilities
    from rclpy.node import Node
    from rclpy.signals import SignalHandlerOptions
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64

    from fourbar_ros.node.executor import Spinner, create_executor

    args = list(argv)
    kind = None
    if '--executor' in args:
        at = args.index('--executor')
        kind = args[at + 1]
        del args[at:at + 2]
    measured = '--measured' in args
    if measured:
        args.remove('--measured')
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    node = Node('relay')
    if measured:
        pub = node.create_publisher(JointState, RELAYED, DEPTH)
        node.create_subscription(JointState, 'joint_states', measured_relay_callback(pub), DEPTH)
    else:
        pub = node.create_publisher(JointState, 'joint_states', DEPTH)
        node.create_subscription(Float64, 'antenna_angle_cmd', relay_callback(node, pub), DEPTH)
    executor = create_executor(kind)
    executor.add_node(node)
    spinner = Spinner(executor)
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda _s, _f: spinner.request_stop())
    try:
        spinner.spin()
    finally:
        executor.shutdown(timeout_sec=0.0)
        destroy(node)
        rclpy.utilities.try_shutdown()
    return 0


def sink_main(argv: Sequence[str]) -> int:
    """Subscribe to the given topics (``name:Type``) and spin: a consumer in another process."""
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.executors import ExternalShutdownException
    from rclpy.node import Node
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64
    from visualization_msgs.msg import MarkerArray

    types = {'JointState': JointState, 'Float64': Float64, 'MarkerArray': MarkerArray,
             'DiagnosticArray': DiagnosticArray}
    split = list(argv).index('--ros-args') if '--ros-args' in argv else len(argv)
    rclpy.init(args=list(argv[split:]))
    node = Node('sink')
    for spec in argv[:split]:
        topic, type_name = spec.split(':')
        node.create_subscription(types[type_name], topic, lambda _m: None, DEPTH)
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        destroy(node)
        rclpy.utilities.try_shutdown()
    return 0


class Child:
    """A helper process, terminated then killed on exit."""

    def __init__(self, cmd: list[str], env: dict[str, str]) -> None:
        self.proc = subprocess.Popen(cmd, env=env, cwd=REPO, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                     start_new_session=True)

    def close(self) -> None:
        for send, wait in ((self.proc.terminate, 5.0), (self.proc.kill, 10.0)):
            if self.proc.poll() is not None:
                return
            send()
            try:
                self.proc.wait(timeout=wait)
                return
            except subprocess.TimeoutExpired:
                continue


def node_script() -> list[str]:
    script = Path(sys.executable).parent / 'fourbar_node'
    return [str(script)] if script.exists() else [sys.executable, '-m', 'fourbar_ros.node']


def destroy(node: Any) -> None:
    """node.destroy_node() (unannotated in rclpy) through a typed name."""
    call: Callable[[], object] = node.destroy_node
    call()


def wait_until(predicate: Callable[[], bool], timeout: float, what: str) -> None:
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            raise RuntimeError(f'timed out waiting for {what}')
        time.sleep(0.01)


# --------------------------------------------------------------------------- measurements

def commands(n: int, lo: float, hi: float) -> list[float]:
    """n distinct angles spread over [lo, hi] (golden-ratio sequence), so no command repeats."""
    return [lo + (hi - lo) * ((0.5 + i * 0.6180339887498949) % 1.0) for i in range(n)]


class Target:
    """One system under test as the client sees it: a command publisher and a JointState counter."""

    def __init__(self, client: Any, ns: str) -> None:
        from sensor_msgs.msg import JointState
        from std_msgs.msg import Float64

        self.Float64 = Float64
        self.pub = client.create_publisher(Float64, f'{ns}/antenna_angle_cmd', DEPTH)
        self.count = 0
        self.last_arrival = 0.0
        self.sub = client.create_subscription(JointState, f'{ns}/joint_states', self._on_reply, DEPTH)

    def _on_reply(self, _msg: Any) -> None:
        self.last_arrival = time.perf_counter()
        self.count += 1

    def send(self, theta: float) -> None:
        self.pub.publish(self.Float64(data=theta))


class MeasuredTarget(Target):
    """A completion under test: the driven joint's JointState (position, velocity, effort, as
    joint_state_broadcaster publishes it) to ``<ns>/joint_states``, counting the JointStates without the driven
    joint (the completed ones; the client's own measurement comes back too) on ``<ns>/<reply>``."""

    def __init__(self, client: Any, ns: str, driven: str, reply: str) -> None:
        from sensor_msgs.msg import JointState

        self.JointState = JointState
        self.driven = [driven]
        self.pub = client.create_publisher(JointState, f'{ns}/joint_states', DEPTH)
        self.count = 0
        self.last_arrival = 0.0
        self.sub = client.create_subscription(JointState, f'{ns}/{reply}', self._on_completed, DEPTH)

    def _on_completed(self, msg: Any) -> None:
        if self.driven[0] not in msg.name:
            self._on_reply(msg)

    def send(self, theta: float) -> None:
        """Publish a measurement of the driven rocker at ``theta`` (here its angle q, rad)."""
        self.pub.publish(self.JointState(name=self.driven, position=[theta], velocity=[0.1], effort=[0.01]))


def ping(executor: Any, target: Target, theta: float, timeout: float = 2.0) -> float | None:
    """One round trip in seconds (None if no answer within timeout)."""
    before = target.count
    t0 = time.perf_counter()
    target.send(theta)
    deadline = t0 + timeout
    while target.count == before:
        if time.perf_counter() > deadline:
            return None
        executor.spin_once(timeout_sec=0.05)
    return target.last_arrival - t0


def connect(executor: Any, target: Target, theta: float, timeout: float = 30.0) -> None:
    """Ping until answered (discovery is asymmetric), then let stragglers arrive."""
    deadline = time.monotonic() + timeout
    while ping(executor, target, theta, timeout=0.2) is None:
        if time.monotonic() > deadline:
            raise RuntimeError(f'no answer on {target.sub.topic_name}')
    end = time.monotonic() + 0.3
    while time.monotonic() < end:
        executor.spin_once(timeout_sec=0.05)


def percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, round(q * (len(ordered) - 1)))]


def latency(executor: Any, targets: dict[str, Target], thetas: list[float]) -> dict[str, dict[str, float]]:
    """Pings alternating between the targets (order flipped every round, so load hits both alike);
    median and p99 in microseconds, and lost pings."""
    rtts: dict[str, list[float]] = {k: [] for k in targets}
    lost = dict.fromkeys(targets, 0)
    names = list(targets)
    for i, theta in enumerate(thetas):
        for name in names if i % 2 == 0 else names[::-1]:
            rtt = ping(executor, targets[name], theta)
            if rtt is None:
                lost[name] += 1
            else:
                rtts[name].append(rtt)
    return {k: {'median_us': 1e6 * statistics.median(v), 'p99_us': 1e6 * percentile(v, 0.99),
                'samples': len(v), 'lost': lost[k]} for k, v in rtts.items()}


def sustains(executor: Any, target: Target, rate: float, duration: float, thetas: list[float]) -> tuple[bool, float]:
    """Send at ``rate`` for ``duration`` s; (all answered without backlog, achieved send rate)."""
    n = max(10, int(rate * duration))
    before = target.count
    stop = threading.Event()

    def spin() -> None:
        while not stop.is_set():
            executor.spin_once(timeout_sec=0.01)

    spinner = threading.Thread(target=spin, daemon=True)
    spinner.start()
    try:
        t0 = time.perf_counter()
        sent = 0
        while sent < n:  # publish whatever is due, then sleep a little: paced on average, light on the CPU
            due = min(n, int((time.perf_counter() - t0) * rate) + 1)
            while sent < due:
                target.send(thetas[sent % len(thetas)])
                sent += 1
            time.sleep(0.0005)
        t_last = time.perf_counter()
        achieved = n / max(t_last - t0, 1e-9)
        allowed = LAG_S
        deadline = t_last + allowed
        while target.count - before < n and time.perf_counter() < deadline:
            time.sleep(0.001)
        ok = target.count - before == n and target.last_arrival - t_last <= allowed
        # Let any late answers drain so the next trial starts clean.
        settle = time.perf_counter() + 1.0
        while target.count - before < n and time.perf_counter() < settle:
            time.sleep(0.005)
    finally:
        stop.set()
        spinner.join()
    return ok and target.count - before == n, achieved


def max_rate(executor: Any, target: Target, thetas: list[float], duration: float, bisections: int,
             start: float = 250.0, cap: float = 32000.0) -> dict[str, Any]:
    """Highest sustained rate (Hz): doubling from ``start`` to the first failure, then bisection."""
    good, bad = 0.0, 0.0
    rate = start
    client_limited = False
    while rate <= cap:
        ok, achieved = sustains(executor, target, rate, duration, thetas)
        if achieved < 0.95 * rate:
            client_limited = True
        if not ok:
            bad = rate
            break
        good = rate
        rate *= 2.0
    if bad:
        lo, hi = good, bad
        for _ in range(bisections):
            mid = 0.5 * (lo + hi) if lo else 0.5 * hi
            ok, achieved = sustains(executor, target, mid, duration, thetas)
            if achieved < 0.95 * mid:
                client_limited = True
            lo, hi = (mid, hi) if ok else (lo, mid)
        good = lo
    return {'rate_hz': good, 'client_limited': client_limited}


def process_cpu_s(pid: int) -> float | None:
    """User + system CPU seconds of process ``pid`` (all its threads) so far; None without /proc."""
    try:
        with open(f'/proc/{pid}/stat', encoding='ascii') as f:
            fields = f.read().rsplit(')', 1)[1].split()
    except OSError:
        return None
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def paced(executor: Any, target: Target, thetas: list[float], rate: float,
          timeout: float = 1.0) -> tuple[list[float], int]:
    """Send ``thetas`` at ``rate`` Hz, each waiting for its answer; (round trips in s, unanswered count)."""
    period = 1.0 / rate
    rtts: list[float] = []
    lost = 0
    due = time.perf_counter()
    for theta in thetas:
        wait = due - time.perf_counter()
        if wait > 0.0:
            time.sleep(wait)
        due += period
        rtt = ping(executor, target, theta, timeout)
        if rtt is None:
            lost += 1
        else:
            rtts.append(rtt)
    return rtts, lost


def executor_rounds(executor: Any, targets: dict[str, Target], pids: dict[str, int], thetas: list[float],
                    per_round: int, rounds: int, rate: float, baseline: str) -> dict[str, Any]:
    """Paced round trips and process CPU per command for each system, in interleaved rounds.

    Each round gives every system a block of ``per_round`` commands at ``rate`` Hz (one outstanding at a
    time), in an order rotated every round, so load that drifts over the run hits all alike. CPU per command
    is the process's CPU time over its blocks (its executor, the middleware's threads, idle timers: all of
    it) divided by the commands. Ratios are against ``baseline``.
    """
    names = list(targets)
    rtts: dict[str, list[float]] = {k: [] for k in names}
    medians: dict[str, list[float]] = {k: [] for k in names}
    lost = dict.fromkeys(names, 0)
    cpu: dict[str, float | None] = dict.fromkeys(names, 0.0)
    for r in range(rounds):
        block = [thetas[(r * per_round + i) % len(thetas)] for i in range(per_round)]
        for name in names[r % len(names):] + names[:r % len(names)]:
            before = process_cpu_s(pids[name])
            got, missed = paced(executor, targets[name], block, rate)
            after = process_cpu_s(pids[name])
            used = cpu[name]
            cpu[name] = None if used is None or before is None or after is None else used + after - before
            rtts[name] += got
            lost[name] += missed
            medians[name].append(1e6 * statistics.median(got) if got else math.nan)
    out: dict[str, Any] = {}
    for name in names:
        used = cpu[name]
        out[name] = {'median_us': 1e6 * statistics.median(rtts[name]), 'p99_us': 1e6 * percentile(rtts[name], 0.99),
                     'round_medians_us': [round(m, 1) for m in medians[name]], 'lost': lost[name],
                     'cpu_per_command_us': None if used is None else 1e6 * used / (rounds * per_round),
                     # the distribution, for the report's plot: round trip (us) at each percent 0, 1, ..., 100
                     'percentiles_us': [round(1e6 * percentile(rtts[name], q / 100), 1) for q in range(101)]}
    base = out[baseline]
    for name in names:
        row = out[name]
        row['latency_ratio_median'] = row['median_us'] / base['median_us']
        row['latency_ratio_p99'] = row['p99_us'] / base['p99_us']
        cpu_us, base_cpu = row['cpu_per_command_us'], base['cpu_per_command_us']
        row['cpu_ratio'] = cpu_us / base_cpu if cpu_us is not None and base_cpu else None
    return out


def callback_costs(context: Any, domain_env: dict[str, str], repeats: int) -> dict[str, Any]:
    """Per-call cost (us) of the node's command callback, by which outputs have subscribers, interleaved call by
    call with the relay's callback (its JointState also subscribed); and of the marker and diagnostics timers."""
    from rclpy.parameter import Parameter
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64

    from fourbar_ros.node.fourbar_node import FourBarNode

    make_parameter: Callable[..., Any] = Parameter
    node = FourBarNode(context=context, namespace='/cost', cli_args=['--ros-args', '--params-file', str(YAML)],
                       parameter_overrides=[make_parameter('diagnostics_period', value=3600.0)])
    cfg = node.config
    msgs = [Float64(data=t) for t in commands(256, cfg.theta_min, cfg.theta_max)]
    info: dict[str, Any] = {'publication_sequence_number': None}  # no sequence numbers: no loss accounting
    scenarios = {
        'none': [],
        'joint_states_only': ['/cost/joint_states:JointState'],
        'all_outputs': ['/cost/joint_states:JointState', '/cost/input_torque:Float64'],
    }
    relay_pub = node.create_publisher(JointState, '/cost/relay_joint_states', DEPTH)
    relay = relay_callback(node, relay_pub)
    pubs = {'joint_states': node._joint_pub, 'input_torque': node._torque_pub}
    out: dict[str, Any] = {}
    relay_us: list[float] = []
    clock = time.perf_counter
    try:
        for name, topics in scenarios.items():
            sink = Child([sys.executable, '-m', 'benchmarks.node_bench', 'sink', '/cost/relay_joint_states:JointState',
                          *topics], domain_env)
            try:
                wanted = {t.split(':')[0].rsplit('/', 1)[1] for t in topics}
                wait_until(lambda w=wanted: relay_pub.get_subscription_count() > 0 and all(  # type: ignore[misc]
                    (pub.get_subscription_count() > 0) == (k in w) for k, pub in pubs.items()),
                    30.0, f'subscribers for {name}')
                node_calls, relay_calls = [], []
                for _ in range(repeats):
                    for m in msgs:
                        t0 = clock()
                        node._on_command(m, info)
                        t1 = clock()
                        relay(m)
                        relay_calls.append(clock() - t1)
                        node_calls.append(t1 - t0)
                out[name] = 1e6 * statistics.median(node_calls)
                relay_us.append(1e6 * statistics.median(relay_calls))
            finally:
                sink.close()
        timers: dict[str, dict[str, float]] = {'markers': {}, 'diagnostics': {}}
        served = [m.data for m in msgs]
        for kind, pub, topic, tick in (
                ('markers', node._marker_pub, '/cost/linkage_markers:MarkerArray', node._on_marker_timer),
                ('diagnostics', node._diag_pub, '/diagnostics:DiagnosticArray', node._on_diagnostics_timer)):
            for name, topics in (('skipped', []), ('subscribed', [topic])):
                sink = Child([sys.executable, '-m', 'benchmarks.node_bench', 'sink', *topics], domain_env)
                try:
                    wait_until(lambda p=pub, t=topics: (p.get_subscription_count() > 0) == bool(t),  # type: ignore[misc]
                               30.0, f'{kind} subscriber')
                    samples = []
                    for _ in range(repeats):
                        t0 = time.perf_counter()
                        for i in range(50):
                            node._served = served[i]  # a new pose each tick, so markers are redrawn
                            tick()
                        samples.append((time.perf_counter() - t0) / 50)
                    timers[kind][name] = 1e6 * statistics.median(samples)
                finally:
                    sink.close()
    finally:
        destroy(node)
    relay_median = statistics.median(relay_us)
    return {'command_callback_us': out, 'relay_callback_us': relay_median,
            'node_extra_us_per_command': out['joint_states_only'] - relay_median,
            'saved_us_per_command': out['all_outputs'] - out['joint_states_only'],
            'saved_fraction': 1.0 - out['joint_states_only'] / out['all_outputs'],
            'timer_callback_us': timers}


# --------------------------------------------------------------------------- entry points

class Bench(NamedTuple):
    """Helper processes on a leased domain, and the client that measures them."""

    context: Any
    env: dict[str, str]
    domain_id: int
    client: Any
    executor: Any
    children: dict[str, Child]


@contextmanager
def running(commands: dict[str, list[str]]) -> Iterator[Bench]:
    """Start ``commands`` (name -> argv) on a free domain (the lock files the tests and tools use) with a client
    node on a SingleThreadedExecutor; stop everything on exit."""
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node

    with ExitStack() as hold:
        domain_id = hold.enter_context(free_domain_id())
        env = dict(os.environ, ROS_DOMAIN_ID=str(domain_id))
        children: dict[str, Child] = {}
        context = Context()
        try:
            for name, cmd in commands.items():
                children[name] = Child(cmd, env)
            rclpy.init(context=context, domain_id=domain_id)
            client = Node('bench_client', context=context)
            executor = SingleThreadedExecutor(context=context)
            executor.add_node(client)
            yield Bench(context, env, domain_id, client, executor, children)
        finally:
            for child in children.values():
                child.close()
            context.try_shutdown()


def executor_systems(relay_options: list[str], node_parameters: list[str]) -> dict[str, list[str]]:
    """The four processes of an executor comparison, named ``relay_<kind>`` and ``node_<kind>`` (and namespaced
    so): a bare relay (``relay`` with ``relay_options``) and fourbar_node (with ``-p`` ``node_parameters``, the
    joint_states republish off) on each executor. The shipped node is started as a user starts it (no option)."""
    from fourbar_ros.node.executor import DEFAULT_EXECUTOR, EXECUTORS

    out: dict[str, list[str]] = {}
    for kind in EXECUTORS:
        option = [] if kind == DEFAULT_EXECUTOR else ['--executor', kind]
        out[f'relay_{kind}'] = [sys.executable, '-m', 'benchmarks.node_bench', 'relay', *relay_options, '--executor',
                                kind, '--ros-args', '-r', f'__ns:=/relay_{kind}']
        params = [a for p in ('joint_state_rate:=0.0', *node_parameters) for a in ('-p', p)]
        out[f'node_{kind}'] = [*node_script(), *option, '--ros-args', '--params-file', str(YAML), '-r',
                               f'__ns:=/node_{kind}', *params]
    return out


def executor_comparison(bench: Bench, systems: dict[str, Target], values: list[float], quick: bool) -> dict[str, Any]:
    """``executor_rounds`` at PACED_HZ against the relay on the SingleThreadedExecutor, with its settings."""
    from fourbar_ros.node.executor import DEFAULT_EXECUTOR

    per_round, rounds = (100, 1) if quick else (400, 3)
    return {'rate_hz': PACED_HZ, 'rounds': rounds, 'commands_per_round': per_round,
            'baseline': 'relay_single', 'shipped': f'node_{DEFAULT_EXECUTOR}',
            'systems': executor_rounds(bench.executor, systems, {k: c.proc.pid for k, c in bench.children.items()},
                                       values, per_round, rounds, PACED_HZ, 'relay_single')}


def shipped_targets(executors: dict[str, Any]) -> dict[str, bool]:
    """The shipped node against the relay on the SingleThreadedExecutor: median latency <= 0.85x, CPU <= 0.6x."""
    row = executors['systems'][executors['shipped']]
    return {'shipped_latency': row['latency_ratio_median'] <= 0.85,
            'shipped_cpu': row['cpu_ratio'] is not None and row['cpu_ratio'] <= 0.6}


def run(quick: bool) -> dict[str, Any]:
    """Measure everything once; JSON-serialisable figures (times in microseconds, rates in Hz)."""
    from fourbar_ros.config.antenna_config import load_config
    from fourbar_ros.node.executor import DEFAULT_EXECUTOR

    cfg = load_config(YAML)
    n_lat, duration, bisections, repeats, rounds = (300, 1.0, 2, 5, 1) if quick else (2000, 2.0, 4, 15, 3)
    result: dict[str, Any] = {'quick': quick, 'default_executor': DEFAULT_EXECUTOR}
    with running(executor_systems([], [])) as bench:
        client, executor = bench.client, bench.executor
        result['domain_id'] = bench.domain_id
        systems = {name: Target(client, f'/{name}') for name in bench.children}
        thetas = commands(max(n_lat, 4096), cfg.theta_min, cfg.theta_max)
        for target in systems.values():
            connect(executor, target, thetas[0])
        result['executors'] = executor_comparison(bench, dict(systems), thetas, quick)
        shipped = result['executors']['shipped']
        # The node against a relay on the same (default) executor: what the node adds.
        targets = {'relay': systems[f'relay_{DEFAULT_EXECUTOR}'], 'node': systems[shipped]}
        lat = latency(executor, targets, thetas[:n_lat])
        # The same with every output of the node subscribed.
        from std_msgs.msg import Float64
        from visualization_msgs.msg import MarkerArray
        extra = [client.create_subscription(Float64, f'/{shipped}/input_torque', lambda _m: None, DEPTH),
                 client.create_subscription(MarkerArray, f'/{shipped}/linkage_markers', lambda _m: None, DEPTH)]
        wait_until(lambda: all(s.get_publisher_count() > 0 for s in extra), 30.0, 'node outputs')
        connect(executor, targets['node'], thetas[1])
        lat_all = latency(executor, targets, thetas[:n_lat // 2])
        lat_all_ratio = lat_all['node']['median_us'] / lat_all['relay']['median_us']
        for s in extra:
            client.destroy_subscription(s)
        rounds_hz: dict[str, list[float]] = {'relay': [], 'node': []}
        limited = dict.fromkeys(rounds_hz, False)
        for _ in range(rounds):  # alternate the two searches; each side's median round
            for name in ('relay', 'node'):
                got = max_rate(executor, targets[name], thetas, duration, bisections)
                rounds_hz[name].append(got['rate_hz'])
                limited[name] = limited[name] or bool(got['client_limited'])
        rate_hz = {k: statistics.median(v) for k, v in rounds_hz.items()}
        rates = {k: {'rate_hz': rate_hz[k], 'rounds_hz': v, 'client_limited': limited[k]} for k, v in rounds_hz.items()}
        result.update({
            'latency': {'relay': lat['relay'], 'node': lat['node'], 'node_all_outputs': lat_all['node'],
                        'relay_during_all_outputs': lat_all['relay']},
            'latency_ratio_median': lat['node']['median_us'] / lat['relay']['median_us'],
            'latency_ratio_p99': lat['node']['p99_us'] / lat['relay']['p99_us'],
            'latency_ratio_median_all_outputs': lat_all_ratio,
            'rate': rates,
            'rate_ratio': rate_hz['node'] / rate_hz['relay'] if rate_hz['relay'] else None,
        })
        executor.remove_node(client)
        destroy(client)
        result['skipped_work'] = callback_costs(bench.context, bench.env, repeats)
    result['targets'] = {'latency_ratio_max': 1.10, 'rate_ratio_min': 0.9,
                         'shipped_latency_over_single_relay_max': 0.85, 'shipped_cpu_over_single_relay_max': 0.6}
    result['meets_targets'] = {
        'latency': result['latency_ratio_median'] <= 1.10,
        'rate': result['rate_ratio'] is not None and result['rate_ratio'] >= 0.9,
        **shipped_targets(result['executors']),
    }
    result['command'] = 'python -m benchmarks.node_bench' + (' --quick' if quick else '')
    return result


def run_completion(quick: bool) -> dict[str, Any]:
    """The completion section: measured joint_states in, completed JointState out, for fourbar_node in
    ``mode:=trajectory`` and a bare JointState relay (``relay --measured``), each on both executors, in
    interleaved paced rounds (``executor_comparison``); JSON-serialisable figures (us)."""
    from fourbar_ros.config.antenna_config import load_config
    from fourbar_ros.core.antenna import Driven
    from fourbar_ros.core.loads import pose

    cfg = load_config(YAML)
    # Driven rocker angles (rad) of distinct antenna angles over the tilt range: no repeats.
    qs = [pose(cfg, t).gamma if cfg.driven is Driven.GAMMA else pose(cfg, t).delta
          for t in commands(4096, cfg.theta_min, cfg.theta_max)]
    result: dict[str, Any] = {'quick': quick, 'load_average_1min_start': os.getloadavg()[0]}
    with running(executor_systems(['--measured'], ['mode:=trajectory'])) as bench:
        result['domain_id'] = bench.domain_id
        systems: dict[str, Target] = {
            name: MeasuredTarget(bench.client, f'/{name}', cfg.driven_joint,
                                 RELAYED if name.startswith('relay') else 'joint_states')
            for name in bench.children}
        for target in systems.values():
            connect(bench.executor, target, qs[0])
        result['executors'] = executor_comparison(bench, systems, qs, quick)
    result['load_average_1min_end'] = os.getloadavg()[0]
    result['targets'] = {'shipped_latency_over_single_relay_max': 0.85, 'shipped_cpu_over_single_relay_max': 0.6}
    result['meets_targets'] = shipped_targets(result['executors'])
    result['command'] = 'python -m benchmarks.node_bench --completion' + (' --quick' if quick else '')
    return result


def main(argv: list[str] | None = None) -> int:
    """``relay``/``sink`` run a helper process; otherwise measure and print JSON."""
    argv = sys.argv[1:] if argv is None else argv
    if argv and argv[0] == 'relay':
        return relay_main(argv[1:])
    if argv and argv[0] == 'sink':
        return sink_main(argv[1:])
    parser = argparse.ArgumentParser(prog='python -m benchmarks.node_bench', description=__doc__)
    parser.add_argument('--quick', action='store_true', help='fewer samples, shorter rate trials')
    parser.add_argument('--completion', action='store_true', help='the completion section only (run_completion)')
    args = parser.parse_args(argv)
    print(json.dumps((run_completion if args.completion else run)(args.quick), indent=2))
    return 0


if __name__ == '__main__':
    sys.exit(main())
