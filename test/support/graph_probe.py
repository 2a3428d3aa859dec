"""Watch the ROS graph node by node until given nodes show given endpoints, and record everything seen meanwhile.

    python graph_probe.py EXPECTED.json OUT.json READY_FILE

A process of its own (on the bringup's domain). EXPECTED.json: ``{"deadline": s, "nodes": {"/ns/node": {"publish":
[...], "subscribe": [...], "reply": [...], "request": [...]}}}``, names resolved. It writes READY_FILE once its own
node is up (start what it watches after that), then polls the graph until every expected node has shown exactly its
expected endpoints (each kind the union of what the node showed so far; nodes come up piece by piece), or the
deadline passes. OUT.json: every node seen (expected or not, e.g. a spawner that has come and gone), the union of
its endpoints per kind.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path
from typing import Any

from probe_node import probe_node
from rclpy.node import Node

KINDS = ('publish', 'subscribe', 'reply', 'request')


def _endpoints(node: Node, name: str, namespace: str) -> dict[str, set[str]]:
    return {'publish': {t for t, _ in node.get_publisher_names_and_types_by_node(name, namespace)},
            'subscribe': {t for t, _ in node.get_subscriber_names_and_types_by_node(name, namespace)},
            'reply': {t for t, _ in node.get_service_names_and_types_by_node(name, namespace)},
            'request': {t for t, _ in node.get_client_names_and_types_by_node(name, namespace)}}


def _watch(node: Node, expected: dict[str, dict[str, list[str]]], deadline_s: float, ready: Path
           ) -> dict[str, dict[str, set[str]]]:
    seen: dict[str, dict[str, set[str]]] = {}
    own = node.get_fully_qualified_name()
    ready.write_text('ready', encoding='utf-8')
    deadline = time.monotonic() + deadline_s
    while time.monotonic() < deadline:
        for name, namespace in node.get_node_names_and_namespaces():
            fqn = f'{namespace.rstrip("/")}/{name}'
            if fqn == own:
                continue
            try:
                got = _endpoints(node, name, namespace)
            except Exception:  # rclpy's NodeNameNonExistentError: it left between the listing and the query
                continue
            for kind, names in got.items():
                seen.setdefault(fqn, {k: set() for k in KINDS})[kind] |= names
        if all(fqn in seen and all(seen[fqn][k] == set(want.get(k, [])) for k in KINDS)
               for fqn, want in expected.items()):
            break
        time.sleep(0.02)  # polls the graph, bounded by the deadline
    return seen


def main(expected_path: str, out_path: str, ready_path: str) -> int:
    spec: dict[str, Any] = json.loads(Path(expected_path).read_text(encoding='utf-8'))
    with probe_node('graph_probe', '/') as node:
        seen = _watch(node, spec['nodes'], float(spec['deadline']), Path(ready_path))
    Path(out_path).write_text(json.dumps({n: {k: sorted(v) for k, v in e.items()} for n, e in seen.items()}),
                              encoding='utf-8')
    return 0


if __name__ == '__main__':
    sys.exit(main(*sys.argv[1:4]))
