"""Trajectories as FollowJointTrajectory goals (trajectory mode, ``trajectory_interface: action``).

The rclpy side of ``fourbar_ros.rules.goal_outcomes``. Never waits: every answer arrives in a future's done
callback; only the latest goal's number is kept. See docs/how-to/ros2-control.md#trajectories-as-action-goals.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

from rclpy.action.client import ActionClient
from rclpy.node import Node

from fourbar_ros.config.antenna_config import ConfigError
from fourbar_ros.core.errors import one_line
from fourbar_ros.interface.topics import trajectory_action
from fourbar_ros.rules.goal_outcomes import GoalCounters, GoalOutcome, outcome, outcome_line
from fourbar_ros.runtime.problem_log import ProblemLog


def follow_joint_trajectory() -> Any:
    """control_msgs' FollowJointTrajectory action type, imported now; ConfigError (one line) when it cannot be."""
    try:
        from control_msgs.action import FollowJointTrajectory  # type: ignore[import-not-found,unused-ignore]
    except Exception as exc:  # ImportError, or a message library that does not load
        raise ConfigError(f'trajectory_interface: action needs control_msgs (FollowJointTrajectory), which cannot be '
                          f'imported here ({type(exc).__name__}: {one_line(exc)}); install ros-jazzy-control-msgs '
                          'or use trajectory_interface: topic', ('trajectory_interface',)) from None
    return FollowJointTrajectory


class TrajectoryGoals:
    """Sends each trajectory as a goal to ``<controller>/follow_joint_trajectory`` and counts how each ends
    (``counters``). A new goal supersedes the previous one: the controller preempts it, nothing is cancelled."""

    def __init__(self, node: Node, controller: str, problems: ProblemLog) -> None:
        self._action = follow_joint_trajectory()
        self._controller = controller
        self._problems = problems
        make_client: Callable[..., Any] = ActionClient  # rclpy's action client is unannotated
        self._client: Any = make_client(node, self._action, trajectory_action(controller))
        self.counters = GoalCounters()
        self._latest = 0  # number of the latest goal sent; goals are numbered from 1
        #: called with how the latest goal ended, and the line logged, when it ended otherwise than succeeded
        self.on_end: Callable[[GoalOutcome, str], None] | None = None
        wrap = problems.guard.wrap
        self._on_response = wrap('goal_response', self._response)
        self._on_result = wrap('goal_result', self._result)

    def send(self, trajectory: Any) -> bool:
        """Send ``trajectory`` (a JointTrajectory) as a goal; False (counted, one throttled line) when no action
        server is there to take it."""
        if not self._client.server_is_ready():
            self.counters.goals_not_sent_no_server += 1
            self._problems.warn('goal no server', f'no FollowJointTrajectory server on '
                                f'{trajectory_action(self._controller)}: trajectory not sent '
                                f'({self.counters.goals_not_sent_no_server} so far)')
            return False
        self._latest += 1
        future = self._client.send_goal_async(self._action.Goal(trajectory=trajectory))
        self.counters.goals_sent += 1
        future.add_done_callback(functools.partial(self._on_response, self._latest))
        return True

    def _response(self, number: int, future: Any) -> None:
        handle = future.result() if future.exception() is None and not future.cancelled() else None
        if handle is None:
            self.counters.goals_lost += 1
            return
        if not handle.accepted:
            self._ended(GoalOutcome.REJECTED, None, '', number == self._latest)
            return
        self.counters.goals_accepted += 1
        handle.get_result_async().add_done_callback(functools.partial(self._on_result, number))

    def _result(self, number: int, future: Any) -> None:
        response = future.result() if future.exception() is None and not future.cancelled() else None
        if response is None:
            self.counters.goals_lost += 1
            return
        result = response.result
        code, text = int(result.error_code), str(result.error_string)
        self._ended(outcome(int(response.status), code, number < self._latest), code, text, number == self._latest)

    def _ended(self, how: GoalOutcome, code: int | None, text: str, latest: bool) -> None:
        self.counters.ended(how, code, text)
        if how in (GoalOutcome.REJECTED, GoalOutcome.ABORTED, GoalOutcome.CANCELED):
            line = outcome_line(self._controller, how, code, text)
            self._problems.warn(f'goal {how.value}', line)
            if latest and self.on_end is not None:
                self.on_end(how, line)

    def diagnostic_values(self) -> list[tuple[str, str]]:
        """The goal counters and the last goal that did not succeed."""
        return self.counters.as_pairs()
