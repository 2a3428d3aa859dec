"""fourbar_node against a bare rclpy relay, measured in the same run: ``python -m benchmarks.node_bench [--quick]``.

The relay: Float64 in, a JointState of the node's shape out with every field a copy of the command (no math, same
QoS). Figures (JSON), commands cycling through distinct angles so the node's repeat cache never helps:
- executors: a relay and fourbar_node on each rclpy executor, 200 Hz, one command outstanding, in blocks that
  rotate between the four processes every round; round-trip median and p99 and CPU time per command (every
  thread, from /proc). Targets, shipped node against the relay on the SingleThreadedExecutor: latency <= 0.85x,
  CPU <= 0.6x.
- latency (target <= 1.10x) and the highest loss-free rate (doubling, then bisecting; target >= 0.9x) of the node
  against the relay on the same executor, pinged alternately; latency also with every output subscribed.
- skipped work: the node's command callback in-process, interleaved call by call with the relay's, by which
  outputs have subscribers; the marker and diagnostics timers with and without one.
``--completion``: the same executor rounds for the driven joint's JointState in on ``measured_joint_states``, the
complete JointState out on ``joint_states`` (fourbar_node in ``mode:=trajectory`` against the JointState relay
``measured-relay``, which reads and writes the same topics and copies the measurement into the node's message
shape). Targets: median latency at most 1.15x the relay on the node's own executor, CPU per message at most 0.6x the
relay on the SingleThreadedExecutor; the latency ratio to that relay is reported too.
No figure here is asserted by a test.
"""

from __future__ import annotations

import math
import os
import statistics
import sys
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import ExitStack, contextmanager
from typing import Any, NamedTuple

from benchmarks import CONFIG, REPO, options, print_json
from benchmarks.timing import cpu_seconds, percentile, round_trips_us
from fourbar_ros.interface.topics import COMMAND, JOINT_STATES, MEASURED_JOINT_STATES, STREAM_DEPTH
from fourbar_ros.live.node_process import NodeProcess, free_domain_id, node_args, node_command

PACED_HZ = 200.0  # command rate of the executor comparison (one outstanding at a time)
LAG_S = 0.25  # a rate is sustained if the last answer comes at most this long after the last command
#: The targets: the node against the relay on its own executor, the shipped node against the single-threaded relay.
TARGETS = {'latency_ratio_max': 1.10, 'rate_ratio_min': 0.9,
           'shipped_latency_over_single_relay_max': 0.85, 'shipped_cpu_over_single_relay_max': 0.6}
#: The completion's targets: latency against the relay on the node's own executor, CPU against the single one.
COMPLETION_TARGETS = {'latency_over_same_executor_relay_max': 1.15, 'cpu_over_single_relay_max': 0.6}


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
    """The completion's baseline per measurement: a JointState with the complete message's shape (the
    measurement's stamp, three names, three positions, three velocities when measured, efforts [measured, 0, 0]),
    all copies of the measured joint: no math, no check."""
    from sensor_msgs.msg import JointState

    names = ['rocker_ab_joint', 'rocker_cd_joint', 'coupler_joint']

    def relay(msg: Any) -> None:
        out = JointState()
        out.header.stamp = msg.header.stamp
        out.name = names
        q = msg.position[0]
        out.position = [q, q, q]
        if msg.velocity:
            out.velocity = [msg.velocity[0]] * 3
        if msg.effort:
            out.effort = [msg.effort[0], 0.0, 0.0]
        pub.publish(out)

    return relay


def helper_node(role: str, topics: Sequence[str]) -> Any:
    """The node of a helper process: ``relay`` (Float64 ``antenna_angle_cmd`` -> ``joint_states``),
    ``measured-relay`` (JointState ``measured_joint_states`` -> ``joint_states``) or ``sink`` (subscribes to
    ``topics``, each ``name:Type``, and drops what comes)."""
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.node import Node
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64
    from visualization_msgs.msg import MarkerArray

    node = Node(role.replace('-', '_'))
    if role == 'relay':
        pub = node.create_publisher(JointState, JOINT_STATES.name, STREAM_DEPTH)
        node.create_subscription(Float64, COMMAND.name, relay_callback(node, pub), STREAM_DEPTH)
    elif role == 'measured-relay':
        pub = node.create_publisher(JointState, JOINT_STATES.name, STREAM_DEPTH)
        node.create_subscription(JointState, MEASURED_JOINT_STATES.name, measured_relay_callback(pub), STREAM_DEPTH)
    else:
        types = {t.__name__: t for t in (JointState, Float64, MarkerArray, DiagnosticArray)}
        for spec in topics:
            topic, type_name = spec.split(':')
            node.create_subscription(types[type_name], topic, lambda _m: None, STREAM_DEPTH)
    return node


def helper_main(argv: Sequence[str]) -> int:
    """``ROLE [--executor KIND | TOPIC:TYPE...] --ros-args ...``: a helper process (see helper_node), started, spun
    and stopped by SIGINT/SIGTERM as fourbar_node is (the sink on the SingleThreadedExecutor)."""
    from fourbar_ros.node.run import node_options, non_ros_args, serve_node
    from fourbar_ros.runtime.executor import executor_kind
    from fourbar_ros.runtime.stop import STOP

    STOP.install()
    role, *rest = argv
    own = non_ros_args(rest)
    kind = executor_kind('single' if role == 'sink' else node_options([role, *own]).executor)
    return serve_node(role, lambda: helper_node(role, own), [role, *rest], kind)


def helper(*args: str) -> list[str]:
    """The command line of a helper process (see helper_main)."""
    return [sys.executable, '-m', 'benchmarks.node_bench', *args]


def start(cmd: list[str], env: dict[str, str]) -> NodeProcess:
    """``cmd`` as a child process in the repository (killed by ``kill()``)."""
    return NodeProcess([], env, command=cmd, cwd=REPO).start()


@contextmanager
def subscribed(env: dict[str, str], *topics: str) -> Iterator[None]:
    """A sink process subscribed to ``topics`` (each ``name:Type``) for the duration of the block."""
    sink = start(helper('sink', *topics), env)
    try:
        yield
    finally:
        sink.kill()


def wait_until(predicate: Callable[[], bool], timeout: float, what: str) -> None:
    """Poll ``predicate`` (graph state, no executor needed) until true; RuntimeError at the deadline."""
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
    """One system under test as the client sees it: a command publisher on ``<ns>/antenna_angle_cmd`` and a
    counter of the JointStates on ``<ns>/<reply>``."""

    def __init__(self, client: Any, ns: str, reply: str = JOINT_STATES.name) -> None:
        from sensor_msgs.msg import JointState

        self.pub = self.publisher(client, ns)
        self.count = 0
        self.last_arrival = 0.0
        self.sub = client.create_subscription(JointState, f'{ns}/{reply}', self.on_reply, STREAM_DEPTH)

    def publisher(self, client: Any, ns: str) -> Any:
        from std_msgs.msg import Float64

        self.message = Float64
        return client.create_publisher(Float64, f'{ns}/{COMMAND.name}', STREAM_DEPTH)

    def on_reply(self, _msg: Any) -> None:
        self.last_arrival = time.perf_counter()
        self.count += 1

    def send(self, theta: float) -> None:
        self.pub.publish(self.message(data=theta))


class MeasuredTarget(Target):
    """A completion under test: the driven joint's JointState (position, velocity, effort, as
    joint_state_broadcaster publishes it) to ``<ns>/measured_joint_states``, counting the complete JointStates on
    ``<ns>/joint_states``."""

    def __init__(self, client: Any, ns: str, driven: str) -> None:
        self.driven = [driven]
        super().__init__(client, ns, JOINT_STATES.name)

    def publisher(self, client: Any, ns: str) -> Any:
        from sensor_msgs.msg import JointState

        self.message = JointState
        return client.create_publisher(JointState, f'{ns}/{MEASURED_JOINT_STATES.name}', STREAM_DEPTH)

    def send(self, theta: float) -> None:
        """Publish a measurement of the driven rocker at ``theta`` (here its angle q, rad)."""
        self.pub.publish(self.message(name=self.driven, position=[theta], velocity=[0.1], effort=[0.01]))


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
    return {k: {**round_trips_us(v), 'samples': len(v), 'lost': lost[k]} for k, v in rtts.items()}


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
        deadline = t_last + LAG_S
        while target.count - before < n and time.perf_counter() < deadline:
            time.sleep(0.001)
        ok = target.count - before == n and target.last_arrival - t_last <= LAG_S
        settle = time.perf_counter() + 1.0  # let late answers drain so the next trial starts clean
        while target.count - before < n and time.perf_counter() < settle:
            time.sleep(0.005)
    finally:
        stop.set()
        spinner.join()
    return ok and target.count - before == n, achieved


def max_rate(executor: Any, target: Target, thetas: list[float], duration: float, bisections: int,
             start_hz: float = 250.0, cap_hz: float = 32000.0) -> dict[str, Any]:
    """Highest sustained rate (Hz): doubling from ``start_hz`` to the first failure, then bisection; and whether
    the client itself could not send that fast."""
    good, bad, client_limited = 0.0, 0.0, False

    def trial(rate: float) -> bool:
        nonlocal client_limited
        ok, achieved = sustains(executor, target, rate, duration, thetas)
        client_limited = client_limited or achieved < 0.95 * rate
        return ok

    rate = start_hz
    while rate <= cap_hz:
        if not trial(rate):
            bad = rate
            break
        good = rate
        rate *= 2.0
    if bad:
        lo, hi = good, bad
        for _ in range(bisections):
            mid = 0.5 * (lo + hi) if lo else 0.5 * hi
            lo, hi = (mid, hi) if trial(mid) else (lo, mid)
        good = lo
    return {'rate_hz': good, 'client_limited': client_limited}


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
            before = cpu_seconds(pids[name])
            got, missed = paced(executor, targets[name], block, rate)
            after = cpu_seconds(pids[name])
            used = cpu[name]
            cpu[name] = None if used is None or before is None or after is None else used + after - before
            rtts[name] += got
            lost[name] += missed
            medians[name].append(1e6 * statistics.median(got) if got else math.nan)
    out: dict[str, Any] = {}
    for name in names:
        used = cpu[name]
        out[name] = {**round_trips_us(rtts[name]), 'round_medians_us': [round(m, 1) for m in medians[name]],
                     'lost': lost[name],
                     'cpu_per_command_us': None if used is None else 1e6 * used / (rounds * per_round),
                     # the distribution, for the report's plot: round trip (us) at each percent 0, 1, ..., 100
                     'percentiles_us': [round(1e6 * percentile(rtts[name], q / 100), 1) for q in range(101)]}
    base = out[baseline]
    for row in out.values():
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

    from fourbar_ros.node.fourbar_node import FourBarNode, destroy_node

    make_parameter: Callable[..., Any] = Parameter
    node = FourBarNode(context=context, namespace='/cost', cli_args=node_args(CONFIG),
                       parameter_overrides=[make_parameter('diagnostics_period', value=3600.0)])
    cfg = node.config
    msgs = [Float64(data=t) for t in commands(256, cfg.theta_min, cfg.theta_max)]
    info: dict[str, Any] = {'publication_sequence_number': None}  # no sequence numbers: no loss accounting
    scenarios = {
        'none': [],
        'joint_states_only': ['/cost/joint_states:JointState'],
        'all_outputs': ['/cost/joint_states:JointState', '/cost/input_torque:Float64'],
    }
    relay_pub = node.create_publisher(JointState, '/cost/relay_joint_states', STREAM_DEPTH)
    relay = relay_callback(node, relay_pub)
    pubs = {'joint_states': node._joint_pub, 'input_torque': node._torque_pub}
    out: dict[str, Any] = {}
    relay_us: list[float] = []
    clock = time.perf_counter
    try:
        for name, topics in scenarios.items():
            with subscribed(domain_env, '/cost/relay_joint_states:JointState', *topics):
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
        timers: dict[str, dict[str, float]] = {'markers': {}, 'diagnostics': {}}
        served = [m.data for m in msgs]
        for kind, pub, topic, tick in (
                ('markers', node._marker_pub, '/cost/linkage_markers:MarkerArray', node._on_marker_timer),
                ('diagnostics', node._diag_pub, '/diagnostics:DiagnosticArray', node._on_diagnostics_timer)):
            for name, topics in (('skipped', []), ('subscribed', [topic])):
                with subscribed(domain_env, *topics):
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
        destroy_node(node)
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
    children: dict[str, NodeProcess]


@contextmanager
def running(systems: dict[str, list[str]]) -> Iterator[Bench]:
    """Start ``systems`` (name -> argv) on a free domain (the lock files the tests and tools use) with a client
    node on a SingleThreadedExecutor; stop everything on exit."""
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node

    from fourbar_ros.live.ros_context import close_context, init_context

    with ExitStack() as hold:
        domain_id = hold.enter_context(free_domain_id())
        env = dict(os.environ, ROS_DOMAIN_ID=str(domain_id))
        children: dict[str, NodeProcess] = {}
        context = None
        try:
            for name, cmd in systems.items():
                children[name] = start(cmd, env)
            context = init_context(domain_id)
            client = Node('bench_client', context=context)
            executor = SingleThreadedExecutor(context=context)
            executor.add_node(client)
            yield Bench(context, env, domain_id, client, executor, children)
        finally:
            for child in children.values():
                child.kill()
            if context is not None:
                close_context(context)


def executor_systems(relay: str, node_parameters: list[str]) -> dict[str, list[str]]:
    """The four processes of an executor comparison, named ``relay_<kind>`` and ``node_<kind>`` (and namespaced
    so): a bare relay (helper ``relay``) and fourbar_node (with ``-p`` ``node_parameters``, the joint_states
    republish off) on each executor. The shipped node is started as a user starts it (no option)."""
    from fourbar_ros.runtime.executor import DEFAULT_EXECUTOR, EXECUTORS

    out: dict[str, list[str]] = {}
    for kind in EXECUTORS:
        option = [] if kind == DEFAULT_EXECUTOR else ['--executor', kind]
        out[f'relay_{kind}'] = helper(relay, '--executor', kind, '--ros-args', '-r', f'__ns:=/relay_{kind}')
        params = [a for p in ('joint_state_rate:=0.0', *node_parameters) for a in ('-p', p)]
        out[f'node_{kind}'] = [*node_command(), *option, *node_args(CONFIG, '-r', f'__ns:=/node_{kind}', *params)]
    return out


def executor_comparison(bench: Bench, systems: dict[str, Target], values: list[float], quick: bool) -> dict[str, Any]:
    """``executor_rounds`` at PACED_HZ against the relay on the SingleThreadedExecutor, with its settings."""
    from fourbar_ros.runtime.executor import DEFAULT_EXECUTOR

    per_round, rounds = (100, 1) if quick else (400, 3)
    pids = {k: c.proc.pid for k, c in bench.children.items() if c.proc is not None}
    return {'rate_hz': PACED_HZ, 'rounds': rounds, 'commands_per_round': per_round, 'baseline': 'relay_single',
            'shipped': f'node_{DEFAULT_EXECUTOR}',
            'systems': executor_rounds(bench.executor, systems, pids, values, per_round, rounds, PACED_HZ,
                                       'relay_single')}


def shipped_targets(executors: dict[str, Any]) -> dict[str, bool]:
    """Whether the shipped node meets its targets against the relay on the SingleThreadedExecutor."""
    row = executors['systems'][executors['shipped']]
    return {'shipped_latency': row['latency_ratio_median'] <= TARGETS['shipped_latency_over_single_relay_max'],
            'shipped_cpu': row['cpu_ratio'] is not None
            and row['cpu_ratio'] <= TARGETS['shipped_cpu_over_single_relay_max']}


def run(quick: bool) -> dict[str, Any]:
    """Measure everything once; JSON-serialisable figures (times in microseconds, rates in Hz)."""
    from std_msgs.msg import Float64
    from visualization_msgs.msg import MarkerArray

    from fourbar_ros.config.antenna_config import load_config
    from fourbar_ros.node.fourbar_node import destroy_node
    from fourbar_ros.runtime.executor import DEFAULT_EXECUTOR

    cfg = load_config(CONFIG)
    n_lat, duration, bisections, repeats, rounds = (300, 1.0, 2, 5, 1) if quick else (2000, 2.0, 4, 15, 3)
    result: dict[str, Any] = {'quick': quick, 'default_executor': DEFAULT_EXECUTOR}
    with running(executor_systems('relay', [])) as bench:
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
        extra = [client.create_subscription(Float64, f'/{shipped}/input_torque', lambda _m: None, STREAM_DEPTH),
                 client.create_subscription(MarkerArray, f'/{shipped}/linkage_markers', lambda _m: None, STREAM_DEPTH)]
        wait_until(lambda: all(s.get_publisher_count() > 0 for s in extra), 30.0, 'node outputs')
        connect(executor, targets['node'], thetas[1])
        lat_all = latency(executor, targets, thetas[:n_lat // 2])
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
        result.update({
            'latency': {'relay': lat['relay'], 'node': lat['node'], 'node_all_outputs': lat_all['node'],
                        'relay_during_all_outputs': lat_all['relay']},
            'latency_ratio_median': lat['node']['median_us'] / lat['relay']['median_us'],
            'latency_ratio_p99': lat['node']['p99_us'] / lat['relay']['p99_us'],
            'latency_ratio_median_all_outputs': lat_all['node']['median_us'] / lat_all['relay']['median_us'],
            'rate': {k: {'rate_hz': rate_hz[k], 'rounds_hz': v, 'client_limited': limited[k]}
                     for k, v in rounds_hz.items()},
            'rate_ratio': rate_hz['node'] / rate_hz['relay'] if rate_hz['relay'] else None,
        })
        executor.remove_node(client)
        destroy_node(client)
        result['skipped_work'] = callback_costs(bench.context, bench.env, repeats)
    result['targets'] = TARGETS
    result['meets_targets'] = {
        'latency': result['latency_ratio_median'] <= TARGETS['latency_ratio_max'],
        'rate': result['rate_ratio'] is not None and result['rate_ratio'] >= TARGETS['rate_ratio_min'],
        **shipped_targets(result['executors']),
    }
    result['command'] = 'python -m benchmarks.node_bench' + (' --quick' if quick else '')
    return result


def run_completion(quick: bool) -> dict[str, Any]:
    """The completion section: measured joint_states in, completed JointState out, for fourbar_node in
    ``mode:=trajectory`` and a bare JointState relay, each on both executors (``executor_comparison``)."""
    from fourbar_ros.config.antenna_config import load_config
    from fourbar_ros.core.antenna import Driven
    from fourbar_ros.core.loads import pose

    cfg = load_config(CONFIG)
    # Driven rocker angles (rad) of distinct antenna angles over the tilt range: no repeats.
    qs = [pose(cfg, t).gamma if cfg.driven is Driven.GAMMA else pose(cfg, t).delta
          for t in commands(4096, cfg.theta_min, cfg.theta_max)]
    result: dict[str, Any] = {'quick': quick, 'load_average_1min_start': os.getloadavg()[0]}
    with running(executor_systems('measured-relay', ['mode:=trajectory'])) as bench:
        result['domain_id'] = bench.domain_id
        systems: dict[str, Target] = {name: MeasuredTarget(bench.client, f'/{name}', cfg.driven_joint)
                                      for name in bench.children}
        for target in systems.values():
            connect(bench.executor, target, qs[0])
        result['executors'] = executor_comparison(bench, systems, qs, quick)
    result['load_average_1min_end'] = os.getloadavg()[0]
    rows = result['executors']['systems']
    shipped = result['executors']['shipped']
    same = rows[shipped.replace('node_', 'relay_')]
    result['latency_over_same_executor_relay'] = rows[shipped]['median_us'] / same['median_us']
    result['latency_over_single_relay'] = rows[shipped]['latency_ratio_median']
    result['cpu_over_single_relay'] = rows[shipped]['cpu_ratio']
    result['targets'] = COMPLETION_TARGETS
    limits = COMPLETION_TARGETS
    result['meets_targets'] = {
        'latency': result['latency_over_same_executor_relay'] <= limits['latency_over_same_executor_relay_max'],
        'cpu': result['cpu_over_single_relay'] is not None
        and result['cpu_over_single_relay'] <= limits['cpu_over_single_relay_max']}
    result['command'] = 'python -m benchmarks.node_bench --completion' + (' --quick' if quick else '')
    return result


def main(argv: list[str] | None = None) -> int:
    """A helper process (``relay``, ``measured-relay``, ``sink``), else measure and print JSON."""
    argv = sys.argv[1:] if argv is None else argv
    if argv and argv[0] in ('relay', 'measured-relay', 'sink'):
        return helper_main(argv)
    args = options(argv, __doc__, completion='the completion section only (run_completion)')
    return print_json((run_completion if args.completion else run)(args.quick))


if __name__ == '__main__':
    sys.exit(main())
