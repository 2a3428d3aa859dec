"""Feed fourbar_node's measured input by hand while it drives the real joint_trajectory_controller, and record what
the controller does, update by update.

    python takeover_probe.py NAMESPACE SCENARIO.json OUT.json

A process of its own, started with the real ros2_control stack on its paths (control_msgs' and
controller_manager_msgs' Python messages need the library path set before the process starts). The node under test
(``takeover_node``) reads its measured driven joint on ``held_joint_states``, its commands on ``takeover_cmd`` and
publishes its antenna angle on ``takeover_angle`` (remapped); the probe relays joint_state_broadcaster's states to
it, message for message with their own stamps, until the scenario holds them. Every wait is on an event with a
deadline; a command counts as taken in once the node's status shows it (sent or held), and a plan is the node's
first trajectory after the command that ends at the command's driven angle (``*_end``, rad). SCENARIO.json:
- ``{"kind": "late", "first": theta, "first_end": q, "then": theta, "then_end": q, "held_before_end": s,
  "after_end": s}``: hold the states and command ``first``; once its plan is seen, relay the states stamped up to
  ``held_before_end`` before its end (the held ones at once); command ``then`` once the clock is ``after_end`` past
  that end; once it is taken in, relay again (a node that waits for a fresh measurement gets one) and wait for its
  plan;
- ``{"kind": "switch", "first": theta, "first_end": q, "then": theta, "then_end": q, "cruise": rad/s,
  "before_switch": s}``: command ``first``; once the drive moves at ``cruise`` or faster, hold the states;
  deactivate, then activate joint_trajectory_controller (the controller manager's service), each once the node's
  status shows the controller's state; feed the held state stamped nearest ``before_switch`` before the switch (the
  first update without the controller) and wait for the node's antenna angle of it; command ``then``; once it is
  taken in, relay again and wait for its plan;
- ``{"kind": "halt", "ros2": path, "from": theta, "from_end": q, "first": theta, "first_end": q, "cruise": rad/s,
  "halted": theta, "then": theta, "then_end": q}``: command ``from`` and wait for the drive at rest there; command
  ``first``; once the drive moves at ``cruise`` or faster, ``ros2 service call NAMESPACE/takeover_node/halt
  std_srvs/srv/Trigger`` (the ``ros2`` command line at ``path``); where the node's brake (or its answer) comes after
  the cruise, resume and again from ``from``, up to HALT_TRIES times; wait for the node's brake and the drive at rest
  after it; deactivate, then activate joint_trajectory_controller as in "switch"; wait for three antenna angles
  from the node after that; command ``halted`` and wait for the node's status to count it dropped; ``ros2 service
  call .../resume``; command ``then``, wait for its plan and the drive at rest at its end.
OUT.json, times in ns on the node clock: ``states`` (every ``~/controller_state``, as jtc_judge.py records them),
``trajectories`` (the node's, as jtc_judge.py records them), ``measured`` (every broadcaster state: stamp, received,
position rad, velocity rad/s, whether relayed), ``fed`` (each state the node got: stamp, sent, position, velocity),
``events`` (name -> time), ``switch_ns`` (the switch's update; "switch" only), ``status`` (the node's last),
``statuses`` (name -> the node's status then) and ``calls`` (name -> a command line's argv, exit code, stdout, stderr;
"halt" only).
"""

from __future__ import annotations

import json
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from builtin_interfaces.msg import Duration
from control_msgs.msg import JointTrajectoryControllerState
from controller_manager_msgs.srv import SwitchController
from diagnostic_msgs.msg import DiagnosticArray
from probe_node import probe_node
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64
from trajectory_msgs.msg import JointTrajectory

from fourbar_ros.interface.topics import ANTENNA_ANGLE, COMMAND, MEASURED_JOINT_STATES
from fourbar_ros.node.qos import qos
from fourbar_ros.rules.diagnostics import status_name

NS = 1_000_000_000
DISCOVERY_S = 60.0
#: The longest (s) any one event is waited for.
EVENT_S = 30.0
CONTROLLER = 'joint_trajectory_controller'
JOINT = 'rocker_ab_joint'
#: The node under test (its name, for its diagnostics) and its remapped inputs.
NODE = 'takeover_node'
HELD, COMMANDS, ANGLE = 'held_joint_states', 'takeover_cmd', 'takeover_angle'
#: Records kept after the last plan's end (s).
TAIL_S = 0.5
#: Updates the drive must show at rest before a scenario starts.
REST_UPDATES = 5
#: The controller manager's update rate (Hz, the shipped controllers file's).
UPDATE_RATE = 100
#: How close (rad) a plan's last position is to the command's driven angle (both from the same solve: equal but for
#: the rounding of a conversion).
END_RAD = 1e-9


def _ns(stamp: Any) -> int:
    return int(stamp.sec) * NS + int(stamp.nanosec)


class _Recorder:
    """What the callbacks store (under ``lock``), and the relay of the broadcaster's states to the node."""

    def __init__(self, node: Node) -> None:
        self.clock = node.get_clock()
        self.lock = threading.Lock()
        self.states: list[dict[str, Any]] = []
        self.trajectories: list[dict[str, Any]] = []
        self.measured: list[dict[str, Any]] = []
        self.messages: list[JointState] = []  # as received, beside ``measured``
        self.pending: list[JointState] = []  # to the node before the next state relayed
        self.fed: list[dict[str, Any]] = []
        self.status: dict[str, str] = {}
        self.status_name = status_name(f'{node.get_namespace().rstrip("/")}/{NODE}')
        self.angles = 0  # the node's antenna angles received
        #: relay the states stamped up to this (ns); None: all
        self.relay_until: int | None = None
        deep = QoSProfile(depth=10000, reliability=ReliabilityPolicy.RELIABLE)
        node.create_subscription(JointTrajectoryControllerState, f'{CONTROLLER}/controller_state', self._on_state,
                                 deep)
        node.create_subscription(JointTrajectory, f'{CONTROLLER}/joint_trajectory', self._on_trajectory, deep)
        node.create_subscription(JointState, 'joint_state_broadcaster/joint_states', self._on_joints, deep)
        node.create_subscription(DiagnosticArray, '/diagnostics', self._on_diagnostics, 10)
        node.create_subscription(Float64, ANGLE, self._on_angle, qos(ANTENNA_ANGLE))
        self.held = node.create_publisher(JointState, HELD, qos(MEASURED_JOINT_STATES))
        self.commands = node.create_publisher(Float64, COMMANDS, qos(COMMAND))

    def now(self) -> int:
        return int(self.clock.now().nanoseconds)

    def _on_state(self, msg: JointTrajectoryControllerState) -> None:
        row = {'stamp': _ns(msg.header.stamp), 'ref_tfs': _ns(msg.reference.time_from_start),
               'fb_tfs': _ns(msg.feedback.time_from_start), 'received': self.now(),
               'ref': [list(msg.reference.positions), list(msg.reference.velocities),
                       list(msg.reference.accelerations)],
               'fb': [list(msg.feedback.positions), list(msg.feedback.velocities)],
               'out': list(msg.output.positions)}
        with self.lock:
            self.states.append(row)

    def _on_trajectory(self, msg: JointTrajectory) -> None:
        row = {'received': self.now(), 'echoed': True, 'stamp': _ns(msg.header.stamp),
               'points': [[_ns(p.time_from_start) / NS, *(float(f[0]) if len(f) else None for f in
                                                          (p.positions, p.velocities, p.accelerations))]
                          for p in msg.points]}
        with self.lock:
            self.trajectories.append(row)

    def _on_joints(self, msg: JointState) -> None:
        if JOINT not in msg.name:
            return
        i = list(msg.name).index(JOINT)
        stamp = _ns(msg.header.stamp)
        row = {'stamp': stamp, 'received': self.now(), 'position': float(msg.position[i]),
               'velocity': float(msg.velocity[i]) if i < len(msg.velocity) else None, 'relayed': False}
        with self.lock:
            self.measured.append(row)
            self.messages.append(msg)
            out, self.pending = self.pending, []
            if self.relay_until is None or stamp <= self.relay_until:
                row['relayed'] = True
                out.append(msg)
        for m in out:  # published here only, in order: the node gets the states in the order of their stamps
            j = list(m.name).index(JOINT)
            fed = {'stamp': _ns(m.header.stamp), 'sent': self.now(), 'position': float(m.position[j]),
                   'velocity': float(m.velocity[j]) if j < len(m.velocity) else None}
            self.held.publish(m)
            with self.lock:
                self.fed.append(fed)

    def feed(self, msg: JointState) -> None:
        """``msg`` to the node, as the broadcaster sent it, before the next state relayed (with the next state
        received: the broadcaster's 100 Hz)."""
        with self.lock:
            self.pending.append(msg)

    def relay(self, until: int | None, backlog: bool = False) -> None:
        """From now on relay the states stamped up to ``until`` (ns; None: all); with ``backlog``, first those held
        since the last one relayed, up to ``until``."""
        with self.lock:
            self.relay_until = until
            if backlog:
                last = max((row['stamp'] for row in self.measured if row['relayed']), default=0)
                for row, msg in zip(self.measured, self.messages, strict=True):
                    if not row['relayed'] and last < row['stamp'] and (until is None or row['stamp'] <= until):
                        row['relayed'] = True
                        self.pending.append(msg)

    def hold(self) -> None:
        """Relay nothing newer than the latest state received."""
        with self.lock:
            self.relay_until = self.measured[-1]['stamp']

    def _on_angle(self, _: Float64) -> None:
        with self.lock:
            self.angles += 1

    def _on_diagnostics(self, msg: DiagnosticArray) -> None:
        for s in msg.status:
            if s.name == self.status_name:
                with self.lock:
                    self.status = {kv.key: kv.value for kv in s.values}

    def at_rest(self) -> bool:
        """The last REST_UPDATES broadcaster states show the drive still."""
        with self.lock:
            last = self.measured[-REST_UPDATES:]
        return len(last) == REST_UPDATES and all(m['velocity'] == 0.0 for m in last) and len(
            {m['position'] for m in last}) == 1


def _wait(predicate: Callable[[], object], what: str, timeout: float = EVENT_S) -> None:
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            raise TimeoutError(f'takeover_probe: {what}: not seen in {timeout} s')
        time.sleep(0.001)  # polls what the callback thread stored, bounded by the deadline


def _end_ns(plan: dict[str, Any]) -> int:
    """A plan's end (ns): its stamp (its arrival for a zero one) plus its last point's time."""
    start = plan['stamp'] if plan['stamp'] != 0 else plan['received']
    return int(start + round(plan['points'][-1][0] * NS))


def _command(rec: _Recorder, theta: float, events: dict[str, int], name: str, taken: bool = True) -> None:
    """Command ``theta``; with ``taken``, wait until the node's status shows it taken in (planned and sent, or
    held)."""
    events[name] = rec.now()
    rec.commands.publish(Float64(data=float(theta)))
    if not taken:
        return
    _wait(lambda: rec.status.get('command_theta_rad') == repr(float(theta)),
          f'the node\'s status showing the command theta = {theta!r} rad')
    events[f'{name}_taken'] = rec.now()


def _plan(rec: _Recorder, end: float, since: int, what: str) -> dict[str, Any]:
    """The node's first trajectory received after ``since`` (ns) that ends at ``end`` (rad)."""
    def found() -> dict[str, Any] | None:
        with rec.lock:
            return next((t for t in rec.trajectories
                         if t['received'] > since and abs(t['points'][-1][1] - end) <= END_RAD), None)
    _wait(found, f'the node\'s plan {what}, to {end!r} rad')
    plan = found()
    assert plan is not None
    return plan


def _relay(rec: _Recorder, events: dict[str, int]) -> None:
    rec.relay(None)
    events['relayed'] = rec.now()


def _switch(node: Node, rec: _Recorder, events: dict[str, int], verb: str, shows: str) -> None:
    """``verb`` ('activate' or 'deactivate') the controller, then wait until the node's status shows ``shows``."""
    client = node.create_client(SwitchController, 'controller_manager/switch_controller')
    try:
        if not client.wait_for_service(timeout_sec=EVENT_S):
            raise TimeoutError(f'takeover_probe: no {client.srv_name} service in {EVENT_S} s')
        request = SwitchController.Request(strictness=SwitchController.Request.STRICT, timeout=Duration(sec=10))
        setattr(request, f'{verb}_controllers', [CONTROLLER])
        done = threading.Event()
        events[f'{verb}_request'] = rec.now()
        future = client.call_async(request)
        future.add_done_callback(lambda _: done.set())
        if not done.wait(EVENT_S):
            raise TimeoutError(f'takeover_probe: {client.srv_name}: no answer in {EVENT_S} s')
        answer = future.result()
        assert answer is not None and answer.ok, f'{verb} {CONTROLLER}: {answer}'
        events[f'{verb}d'] = rec.now()
    finally:
        node.destroy_client(client)
    _wait(lambda: rec.status.get('controller_state') == shows, f'the node showing the controller {shows}')
    events[f'{verb}d_seen'] = rec.now()


def _late(rec: _Recorder, spec: dict[str, Any], events: dict[str, int]) -> None:
    # Held from the command until its plan is seen (the plan's end says which states the node gets), then the held
    # ones up to the limit at once: however late the plan reaches the probe, the node's last state is the limit's.
    rec.hold()
    _command(rec, spec['first'], events, 'first', taken=False)
    plan = _plan(rec, spec['first_end'], events['first'], 'for the first command')
    end = _end_ns(plan)
    rec.relay(end - round(spec['held_before_end'] * NS), backlog=True)
    events['first_plan'], events['first_end'] = plan['received'], end
    due = end + round(spec['after_end'] * NS)
    _wait(lambda: rec.now() >= due, 'the time to command again')
    _command(rec, spec['then'], events, 'then')
    _relay(rec, events)  # a node that waits for a fresh measurement gets one
    _plan(rec, spec['then_end'], events['then'], 'for the second command')


def _switched(rec: _Recorder, spec: dict[str, Any], events: dict[str, int], node: Node) -> int:
    """The scenario "switch"; the switch's update (ns)."""
    _command(rec, spec['first'], events, 'first')
    _plan(rec, spec['first_end'], events['first'], 'for the first command')

    def cruising() -> bool:
        with rec.lock:
            v = rec.measured[-1]['velocity']
        return v is not None and abs(v) >= spec['cruise']
    _wait(cruising, f'the drive at {spec["cruise"]} rad/s')
    rec.hold()
    with rec.lock:
        held_from = len(rec.measured)
    events['held'] = rec.now()
    # Enough states after the hold that the one before the switch was not relayed.
    _wait(lambda: len(rec.measured) >= held_from + 5, 'five broadcaster states after the hold')
    _switch(node, rec, events, 'deactivate', 'inactive')
    _switch(node, rec, events, 'activate', 'active')
    with rec.lock:
        before = [s['stamp'] for s in rec.states if s['received'] < events['activate_request']]
    switch_ns = max(before) + NS // UPDATE_RATE  # the first update without the controller
    target = switch_ns - round(spec['before_switch'] * NS)
    with rec.lock:
        k = min(range(len(rec.measured)), key=lambda j: abs(rec.measured[j]['stamp'] - target))
        chosen, msg = rec.measured[k], rec.messages[k]
        angles = rec.angles
    assert not chosen['relayed'], f'the state stamped {chosen["stamp"]} ns was relayed before the switch'
    events['fed'] = rec.now()
    rec.feed(msg)
    # The node publishes the antenna angle of each measurement once it has taken it in (the stream is held: this one)
    _wait(lambda: rec.angles > angles, 'the node\'s antenna angle of the state fed')
    events['fed_taken'] = rec.now()
    _command(rec, spec['then'], events, 'then')
    _relay(rec, events)
    _plan(rec, spec['then_end'], events['then'], 'for the second command')
    return switch_ns


#: Far moves tried until the halt's command line reaches the node while the drive cruises (its start-up takes 1.4 s
#: here, 4.2 s on a loaded machine; a far move cruises 4.1 s).
HALT_TRIES = 3
#: How close (rad) the drive rests at a command's driven angle: the mock hardware's state is the controller's command,
#: which is the last point's position once the trajectory has ended (the same float, through the messages).
AT_RAD = 1e-9


def _rest_at(rec: _Recorder, q: float, since: int, what: str) -> None:
    """Wait for the drive at rest (``at_rest``) at ``q`` (rad), measured after ``since`` (ns)."""
    def there() -> bool:
        with rec.lock:
            last = rec.measured[-1]
        return last['received'] > since and abs(last['position'] - q) <= AT_RAD and rec.at_rest()
    _wait(there, f'the drive at rest at {q!r} rad {what}')


def _cli(spec: dict[str, Any], namespace: str, service: str, calls: dict[str, Any], events: dict[str, int],
         rec: _Recorder) -> None:
    """``ros2 service call NAMESPACE/takeover_node/SERVICE std_srvs/srv/Trigger``, recorded under ``service``, with
    events ``SERVICE_call`` (before the command line starts) and ``SERVICE_answered`` (after it exits)."""
    argv = [spec['ros2'], 'service', 'call', f'{namespace}/{NODE}/{service}', 'std_srvs/srv/Trigger']
    events[f'{service}_call'] = rec.now()
    try:
        done = subprocess.run(argv, capture_output=True, text=True, timeout=EVENT_S, check=False,
                              stdin=subprocess.DEVNULL)
    except subprocess.TimeoutExpired as exc:
        raise TimeoutError(f'takeover_probe: {" ".join(argv)}: no exit in {EVENT_S} s: {exc.stdout!r} '
                           f'{exc.stderr!r}') from None
    events[f'{service}_answered'] = rec.now()
    calls[service] = {'argv': argv, 'rc': done.returncode, 'stdout': done.stdout, 'stderr': done.stderr}


def _halted(rec: _Recorder, spec: dict[str, Any], events: dict[str, int], node: Node, namespace: str,
            calls: dict[str, Any], statuses: dict[str, dict[str, str]]) -> None:
    """The scenario "halt"."""
    def cruising() -> bool:
        with rec.lock:
            v = rec.measured[-1]['velocity']
        return v is not None and abs(v) >= spec['cruise']

    def brake() -> dict[str, Any] | None:
        with rec.lock:
            return next((t for t in rec.trajectories if t['received'] > events['halt_call']), None)

    missed: list[str] = []
    events['missed'] = 0
    while True:
        _command(rec, spec['from'], events, 'from')
        _rest_at(rec, spec['from_end'], events['from'], 'where the far move starts')
        _command(rec, spec['first'], events, 'first')
        _plan(rec, spec['first_end'], events['first'], 'for the far move')
        _wait(cruising, f'the drive at {spec["cruise"]} rad/s')
        _cli(spec, namespace, 'halt', calls, events, rec)
        plan = brake()
        with rec.lock:
            at = [m for m in rec.measured if plan is not None and m['received'] <= plan['received']]
        if plan is not None and at and abs(at[-1]['velocity']) >= spec['cruise']:
            break
        # The command line reached the node after the cruise (a loaded machine starts it slowly): once more.
        took = (events['halt_answered'] - events['halt_call']) / NS
        missed.append(f'{calls["halt"]["stdout"].strip()[-200:]!r}, exited {took:.3f} s after it started')
        events['missed'] += 1
        if len(missed) == HALT_TRIES:
            raise TimeoutError(f'takeover_probe: the halt reached the node after the cruise {HALT_TRIES} times: '
                               f'{missed}')
        _wait(rec.at_rest, 'the drive at rest after a halt that missed the cruise')
        _cli(spec, namespace, 'resume', calls, events, rec)
    calls['missed'] = missed
    events['brake'], end = plan['received'], _end_ns(plan)
    _wait(lambda: rec.now() >= end, 'the brake\'s planned end')
    _rest_at(rec, plan['points'][-1][1], end, 'after the brake')
    events['rest_seen'] = rec.now()
    statuses['halted'] = dict(rec.status)
    _switch(node, rec, events, 'deactivate', 'inactive')
    _switch(node, rec, events, 'activate', 'active')
    with rec.lock:
        angles = rec.angles
    _wait(lambda: rec.angles >= angles + 3, 'three antenna angles from the node after the activation')
    events['measured_again'] = rec.now()
    dropped = int(rec.status['halt_dropped'])
    _command(rec, spec['halted'], events, 'halted', taken=False)
    _wait(lambda: int(rec.status.get('halt_dropped', '0')) > dropped, 'the node\'s status counting the command '
          'while halted dropped')
    events['halted_dropped'] = rec.now()
    statuses['dropped'] = dict(rec.status)
    _cli(spec, namespace, 'resume', calls, events, rec)
    _command(rec, spec['then'], events, 'then')
    plan = _plan(rec, spec['then_end'], events['then'], 'after the resume')
    _rest_at(rec, spec['then_end'], _end_ns(plan), 'at the end of the motion after the resume')


def _probe(node: Node, spec_path: str, out_path: str, namespace: str = '') -> int:
    spec = json.loads(Path(spec_path).read_text(encoding='utf-8'))
    rec = _Recorder(node)

    def ready() -> bool:
        # Both sides of discovery: the node's antenna angle says a state relayed reached it (a state published
        # before the node matched the probe's publisher is lost, and a held stream would then leave it with none).
        return (rec.held.get_subscription_count() >= 1 and rec.commands.get_subscription_count() >= 1
                and bool(rec.states) and rec.angles >= 1 and rec.status.get('controller_state') == 'active')
    try:
        _wait(ready, 'the node, the controller and the broadcaster', DISCOVERY_S)
        _wait(rec.at_rest, 'the drive at rest')
    except TimeoutError as exc:
        print(f'{exc}: subscribers {HELD} {rec.held.get_subscription_count()}, {COMMANDS} '
              f'{rec.commands.get_subscription_count()}; controller states {len(rec.states)}, states fed '
              f'{len(rec.fed)}, antenna angles from the node {rec.angles}, the node\'s status {rec.status}',
              file=sys.stderr)
        return 1
    events: dict[str, int] = {'start': rec.now()}
    switch_ns = None
    calls: dict[str, Any] = {}
    statuses: dict[str, dict[str, str]] = {}
    try:
        if spec['kind'] == 'late':
            _late(rec, spec, events)
        elif spec['kind'] == 'halt':
            _halted(rec, spec, events, node, namespace, calls, statuses)
        else:
            switch_ns = _switched(rec, spec, events, node)
    except TimeoutError as exc:
        print(f'{exc}; the node\'s status: {rec.status}; events {events}; command lines {calls}', file=sys.stderr)
        return 1
    with rec.lock:
        end = max(_end_ns(t) for t in rec.trajectories) + round(TAIL_S * NS)
    _wait(lambda: rec.now() >= end and rec.states[-1]['stamp'] >= end, 'the controller\'s states after the end')
    with rec.lock:
        out = {'states': rec.states, 'trajectories': rec.trajectories, 'measured': rec.measured, 'fed': rec.fed,
               'events': events, 'switch_ns': switch_ns, 'status': rec.status, 'statuses': statuses,
               'calls': calls}
    Path(out_path).write_text(json.dumps(out), encoding='utf-8')
    return 0


def main(namespace: str, spec_path: str, out_path: str) -> int:
    with probe_node('takeover_probe', namespace) as node:
        return _probe(node, spec_path, out_path, namespace)


if __name__ == '__main__':
    sys.exit(main(*sys.argv[1:4]))
