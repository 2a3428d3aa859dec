"""A running fourbar_node's parameters over its services: a discovery handshake, and which commands it will answer."""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from typing import Any

from rclpy.executors import Executor
from rclpy.node import Node

from fourbar_ros.core.antenna import Reach
from fourbar_ros.live.graph import ReplayError, spin_until
from fourbar_ros.rules.policy import Policy, decide

Predictor = Callable[[float], bool]


def predictor(theta_min: float, theta_max: float, out_of_limits: str) -> Predictor:
    """True for commands the node answers (accepted or clamped), by the node's own policy."""
    policy = Policy(out_of_limits)
    reach = Reach(0.0, math.pi)  # only labels out-of-limit commands; no effect on the outcome

    def answers(theta: float) -> bool:
        return not decide(theta, theta_min, theta_max, policy, reach).outcome.rejected
    return answers


def fetch_parameters(node: Node, executor: Executor, target: str, names: Sequence[str],
                     timeout_s: float) -> dict[str, Any]:
    """Read parameters of node ``target`` (fully qualified name) through its parameter services.

    Also a discovery handshake: the reply travels on a reader this node created after its other
    subscriptions, and a DDS participant processes another's endpoint announcements in order, so
    once ``target`` has answered, its publishers have matched every subscription created before
    this call. Requests are repeated (idempotent reads) until ``timeout_s``.
    """
    from rcl_interfaces.srv import GetParameters
    from rclpy.parameter import parameter_value_to_python

    client = node.create_client(GetParameters, f'{target}/get_parameters')
    end = time.monotonic() + timeout_s
    try:
        if not spin_until(executor, client.service_is_ready, timeout_s):
            raise ReplayError(f'{target} offers no get_parameters service within {timeout_s:g} s')
        while True:
            left = end - time.monotonic()
            if left <= 0.0:
                raise ReplayError(f'{target} did not return its parameters within {timeout_s:g} s')
            future = client.call_async(GetParameters.Request(names=list(names)))
            get_result: Callable[[], Any] = future.result
            if spin_until(executor, future.done, min(left, 1.0)) and get_result() is not None:
                values = get_result().values
                return {n: parameter_value_to_python(v) for n, v in zip(names, values, strict=False)}
            client.remove_pending_request(future)
    finally:
        node.destroy_client(client)


def handshake(node: Node, executor: Executor, targets: Sequence[str], timeout_s: float) -> None:
    """Make sure each target node has discovered every subscription ``node`` created so far."""
    for target in targets:
        fetch_parameters(node, executor, target, ['use_sim_time'], timeout_s)


LIMIT_PARAMETERS = ('theta_min', 'theta_max', 'out_of_limits')


def predictor_from_values(values: dict[str, Any], source: str) -> Predictor:
    """A Predictor from ``theta_min``, ``theta_max`` (rad) and ``out_of_limits`` values."""
    try:
        return predictor(float(values['theta_min']), float(values['theta_max']),
                         str(values['out_of_limits']))
    except (KeyError, TypeError, ValueError) as exc:
        raise ReplayError(f'{source} is not a fourbar_node (parameters {values!r}): {exc}') from None
