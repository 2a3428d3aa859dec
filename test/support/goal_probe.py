"""Send antenna angle commands to a running fourbar_node and wait until its diagnostics show given goal counters.

    python goal_probe.py NAMESPACE STEPS.json OUT.json

A process of its own (started with the ros2_control stack on its paths, as the bringup's). STEPS.json:
``{"commands": [{"command": theta, "after": s}, ...], "until": {"goals_succeeded": 2, ...}, "timeout": s}``: each
command ``after`` s after the previous one (the first once the node's status arrives); then it waits until every
``until`` key of the status has grown by at least that much. OUT.json: the node's status before the commands and the
last one (``before``, ``status``: key -> value, plus ``level`` and ``message``) and the last measured position of
the driven joint (``measured``, rad).
"""

from __future__ import annotations

import json
import sys
import threading
import time
from pathlib import Path
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from probe_node import probe_node
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64

from fourbar_ros.rules.diagnostics import status_name

DISCOVERY_S = 60.0
JOINT = 'rocker_ab_joint'


def _probe(node: Node, steps_path: str, out_path: str) -> int:
    steps = json.loads(Path(steps_path).read_text(encoding='utf-8'))
    status: dict[str, Any] = {}
    measured: list[float] = []
    lock = threading.Lock()
    ours = status_name(f'{node.get_namespace().rstrip("/")}/fourbar_node')  # this namespace's node

    def on_diagnostics(msg: DiagnosticArray) -> None:
        for s in msg.status:
            values = {kv.key: kv.value for kv in s.values}
            if s.name == ours and 'goals_sent' in values:
                with lock:
                    status.clear()
                    status.update(values, level=int.from_bytes(bytes(s.level), 'little'), message=s.message)

    def on_joints(msg: JointState) -> None:
        if JOINT in msg.name and msg.position:
            measured.append(float(msg.position[list(msg.name).index(JOINT)]))
            del measured[:-1]

    reliable = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
    node.create_subscription(DiagnosticArray, '/diagnostics', on_diagnostics, reliable)
    node.create_subscription(JointState, 'joint_state_broadcaster/joint_states', on_joints, 10)
    to_node = node.create_publisher(Float64, 'antenna_angle_cmd', reliable)

    def snapshot() -> dict[str, Any]:
        with lock:
            return dict(status)
    deadline = time.monotonic() + DISCOVERY_S
    while (not snapshot() or not measured or to_node.get_subscription_count() < 1) and time.monotonic() < deadline:
        time.sleep(0.05)  # polls the callback thread, bounded by the deadline
    if not snapshot() or not measured:
        print(f'goal_probe: no status or no measurement in {DISCOVERY_S} s', file=sys.stderr)
        return 1
    before = snapshot()
    for step in steps['commands']:
        time.sleep(float(step['after']))
        to_node.publish(Float64(data=float(step['command'])))

    def reached() -> bool:
        now = snapshot()
        return all(int(now.get(k, '0')) - int(before.get(k, '0')) >= int(v) for k, v in steps['until'].items())
    deadline = time.monotonic() + float(steps.get('timeout', 30.0))
    while not reached() and time.monotonic() < deadline:
        time.sleep(0.05)
    time.sleep(float(steps.get('settle', 0.0)))
    Path(out_path).write_text(json.dumps({'before': before, 'status': snapshot(),
                                               'measured': measured[-1]}), encoding='utf-8')
    return 0


def main(namespace: str, steps_path: str, out_path: str) -> int:
    with probe_node('goal_probe', namespace) as node:
        return _probe(node, steps_path, out_path)


if __name__ == '__main__':
    sys.exit(main(*sys.argv[1:4]))
