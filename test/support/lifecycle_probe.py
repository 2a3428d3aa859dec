"""Drive a running ros2_control bringup through lifecycle events and record what fourbar_node says of its commands.

    python lifecycle_probe.py NAMESPACE STEPS.json OUT.json

A process of its own, started with the ros2_control stack on its paths (controller_manager_msgs needs the library
path set before the process starts). STEPS.json is a list of steps, run in order, each waiting on an event with a
deadline (never on time alone):
- ``{"command": theta}``: an antenna angle (rad) to ``antenna_angle_cmd``;
- ``{"switch": {"activate": [...], "deactivate": [...]}}``: the controller manager's ``switch_controller`` (strict);
- ``{"unload": name}``: ``unload_controller``;
- ``{"hardware": [name, "active" | "inactive"]}``: ``set_hardware_component_state``;
- ``{"run": [...]}``: a command line (e.g. the spawner), to its exit;
- ``{"kill_manager": pid}``: SIGKILL to the ros2_control_node that process ``pid`` (the launch) started;
- ``{"until": {key: value, ...}, "timeout": s}``: wait until the node's diagnostics show every value;
- ``{"moving": true, "timeout": s}``: wait until the measured driven joint moves;
- ``{"pause": s}``: let time pass (a random sequence's spacing; not a wait for anything);
- ``{"mark": anything}``: nothing (a boundary in the log).
OUT.json: ``log`` (per step: the step, its time, what it returned and the node's status after it), ``statuses``
(time, the node's controller state, command fate and its reason, every status change), ``measured`` (time,
driven joint rad, at most every 10 ms), ``references`` (time, joint_trajectory_controller's reference
acceleration rad/s^2, the update's stamp s and the time the reference was sampled at s, every update), ``status``
(the last status: key -> value).
Times in s on the steady clock from the start.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import psutil
from builtin_interfaces.msg import Duration
from control_msgs.msg import JointTrajectoryControllerState
from controller_manager_msgs.srv import SetHardwareComponentState, SwitchController, UnloadController
from diagnostic_msgs.msg import DiagnosticArray
from lifecycle_msgs.msg import State
from probe_node import probe_node
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64

from fourbar_ros.rules.diagnostics import status_name

DISCOVERY_S = 60.0
SERVICE_S = 30.0
JOINT = 'rocker_ab_joint'
STATE_IDS = {'active': State.PRIMARY_STATE_ACTIVE, 'inactive': State.PRIMARY_STATE_INACTIVE}


def _probe(node: Node, namespace: str, steps_path: str, out_path: str) -> int:
    steps = json.loads(Path(steps_path).read_text(encoding='utf-8'))
    t0 = time.monotonic()
    status: dict[str, str] = {}
    statuses: list[list[Any]] = []
    measured: list[list[float]] = []
    references: list[list[float]] = []
    lock = threading.Lock()

    ours = status_name(f'/{namespace.strip("/")}/fourbar_node')  # this namespace's node (others may run beside it)

    def on_diagnostics(msg: DiagnosticArray) -> None:
        for s in msg.status:
            values = {kv.key: kv.value for kv in s.values}
            if s.name == ours:
                with lock:
                    status.clear()
                    status.update(values, message=s.message)
                    row = [values['controller_state'], values.get('command_fate', ''),
                           values.get('command_fate_reason', '')]
                    if not statuses or statuses[-1][1:] != row:
                        statuses.append([time.monotonic() - t0, *row])

    def on_joints(msg: JointState) -> None:
        if JOINT in msg.name and msg.position:
            now = time.monotonic() - t0
            if not measured or now - measured[-1][0] >= 0.01:
                measured.append([now, float(msg.position[list(msg.name).index(JOINT)])])

    def on_reference(msg: JointTrajectoryControllerState) -> None:
        if msg.reference.accelerations:
            stamp = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
            # the time the reference was sampled at: the update's time minus the time since the trajectory's start,
            # plus the sampled time since that start (the controller's own accumulated time)
            since = msg.feedback.time_from_start.sec + 1e-9 * msg.feedback.time_from_start.nanosec
            sampled = msg.reference.time_from_start.sec + 1e-9 * msg.reference.time_from_start.nanosec
            references.append([time.monotonic() - t0, float(msg.reference.accelerations[0]), stamp,
                               stamp - since + sampled])

    reliable = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
    node.create_subscription(JointTrajectoryControllerState, 'joint_trajectory_controller/controller_state',
                             on_reference, QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE))
    node.create_subscription(DiagnosticArray, '/diagnostics', on_diagnostics, reliable)
    node.create_subscription(JointState, 'joint_state_broadcaster/joint_states', on_joints, 10)
    to_node = node.create_publisher(Float64, 'antenna_angle_cmd', reliable)
    clients = {'switch': node.create_client(SwitchController, 'controller_manager/switch_controller'),
               'unload': node.create_client(UnloadController, 'controller_manager/unload_controller'),
               'hardware': node.create_client(SetHardwareComponentState,
                                              'controller_manager/set_hardware_component_state')}
    log: list[dict[str, Any]] = []

    def wait(predicate: Any, timeout: float) -> bool:
        deadline = time.monotonic() + timeout
        while not predicate() and time.monotonic() < deadline:
            time.sleep(0.01)  # polls what the callback thread stored, bounded by the deadline
        return bool(predicate())

    def call(kind: str, request: Any) -> Any:
        client = clients[kind]
        if not client.wait_for_service(timeout_sec=SERVICE_S):
            return f'no {client.srv_name} service in {SERVICE_S} s'
        done = threading.Event()
        future = client.call_async(request)
        future.add_done_callback(lambda _: done.set())
        if not done.wait(SERVICE_S):
            return f'{client.srv_name}: no answer in {SERVICE_S} s'
        return future.result()

    if not wait(lambda: to_node.get_subscription_count() >= 1 and bool(status) and bool(measured), DISCOVERY_S):
        print(f'lifecycle_probe: not ready in {DISCOVERY_S} s: command subscribers '
              f'{to_node.get_subscription_count()}, status {bool(status)}, measured {len(measured)}',
              file=sys.stderr)
        return 1
    for step in steps:
        at = time.monotonic() - t0
        result: Any = None
        if 'command' in step:
            to_node.publish(Float64(data=float(step['command'])))
        elif 'switch' in step:
            request = SwitchController.Request(
                activate_controllers=step['switch'].get('activate', []),
                deactivate_controllers=step['switch'].get('deactivate', []),
                strictness=SwitchController.Request.STRICT, timeout=Duration(sec=10))
            answer = call('switch', request)
            result = answer if isinstance(answer, str) else {'ok': answer.ok, 'message': answer.message}
        elif 'unload' in step:
            answer = call('unload', UnloadController.Request(name=step['unload']))
            result = answer if isinstance(answer, str) else {'ok': answer.ok}
        elif 'hardware' in step:
            name, target = step['hardware']
            answer = call('hardware', SetHardwareComponentState.Request(
                name=name, target_state=State(id=STATE_IDS[target], label=target)))
            result = answer if isinstance(answer, str) else {'ok': answer.ok, 'state': answer.state.label}
        elif 'run' in step:
            done = subprocess.run(step['run'], capture_output=True, text=True, timeout=120, check=False,
                                  env=os.environ)
            result = {'returncode': done.returncode, 'output': (done.stdout + done.stderr)[-1500:]}
        elif 'kill_manager' in step:
            launch = psutil.Process(int(step['kill_manager']))
            killed = [p.pid for p in launch.children(recursive=True)
                      if any('ros2_control_node' in c for c in p.cmdline())]
            for pid in killed:
                os.kill(pid, signal.SIGKILL)
            result = {'killed': killed}
        elif 'until' in step:
            want = {k: str(v) for k, v in step['until'].items()}

            def shows(want: dict[str, str] = want) -> bool:
                with lock:
                    return all(status.get(k) == v for k, v in want.items())
            result = {'seen': wait(shows, float(step.get('timeout', 30.0)))}
        elif 'pause' in step:
            time.sleep(float(step['pause']))
        elif 'moving' in step:
            first = measured[-1][1]
            result = {'seen': wait(lambda first=first: abs(measured[-1][1] - first) > 1e-4,
                                   float(step.get('timeout', 30.0)))}
        with lock:
            log.append({'step': step, 'at': at, 'result': result, 'status': dict(status)})
        if isinstance(result, str) or (isinstance(result, dict) and not result.get('seen', True)):
            break
    with lock:
        out = {'log': log, 'statuses': statuses, 'measured': measured, 'references': references,
               'status': dict(status)}
    Path(out_path).write_text(json.dumps(out), encoding='utf-8')
    return 0


def main(namespace: str, steps_path: str, out_path: str) -> int:
    with probe_node('lifecycle_probe', namespace) as node:
        return _probe(node, namespace, steps_path, out_path)


if __name__ == '__main__':
    sys.exit(main(*sys.argv[1:4]))
