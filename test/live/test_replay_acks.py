"""The replay's wait for acknowledgements keeps the executor running: a recorder on the same executor (the demo's)
stamps what arrives during the wait when it arrives, not when the wait ends. In process, with the publisher's
acknowledgement query replaced by one that reports acknowledged only once the executor has run a callback that was
ready before the wait."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import ReliabilityPolicy
from support.bag_support import DEMO_BAG
from support.ros_support import DomainLease

from fourbar_ros.bags.storage import read_commands
from fourbar_ros.live.replay import Replayer
from fourbar_ros.live.ros_context import close_context, init_context

pytestmark = [pytest.mark.ros]


class AckedAfter:
    """Stands in for the replay's publisher in ``confirm_delivery``: its profile, and ``wait_for_all_acked`` that
    answers whether ``acked()`` holds, at once (blocking here could only end by its timeout: no callback runs while
    the caller blocks in it), recording each timeout asked (ns)."""

    def __init__(self, real: Any, acked: Any) -> None:
        self.qos_profile = real.qos_profile
        self.acked = acked
        self.timeouts_ns: list[int] = []

    def wait_for_all_acked(self, timeout: Any) -> bool:
        self.timeouts_ns.append(int(timeout.nanoseconds))
        return bool(self.acked())


@pytest.fixture
def replay_node(lease: DomainLease) -> Iterator[tuple[Node, SingleThreadedExecutor]]:
    context = init_context(domain_id=lease.domain_id)
    node = Node('replay_acks', context=context, start_parameter_services=False)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    try:
        yield node, executor
    finally:
        executor.shutdown()
        close_context(context, node)


def test_the_executor_runs_callbacks_while_acknowledgements_are_awaited(
        replay_node: tuple[Node, SingleThreadedExecutor]) -> None:
    node, executor = replay_node
    replayer = Replayer(node, read_commands(DEMO_BAG), topic='replay_acks_cmd')
    assert replayer.publisher.qos_profile.reliability == ReliabilityPolicy.RELIABLE  # the wait applies
    ran: list[bool] = []
    # Ready before the wait: a message that arrived for a recorder while the last commands await acknowledgement.
    ready = node.create_guard_condition(lambda: ran.append(True))
    ready.trigger()
    stand_in = AckedAfter(replayer.publisher, lambda: bool(ran))
    replayer.publisher = stand_in
    replayer.confirm_delivery(executor, 10.0)
    assert ran and stand_in.acked(), (
        f'confirm_delivery returned with the ready callback run: {bool(ran)} (the executor must keep running '
        f'while acknowledgements are outstanding); wait_for_all_acked asked with timeouts (ns) '
        f'{stand_in.timeouts_ns}')
