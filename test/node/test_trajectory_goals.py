"""The FollowJointTrajectory side of trajectory mode in-process: how each answer of the controller is counted and
logged (a stand-in action client whose futures the test resolves, in any order), the outcome rules, and the node's
one-line refusal to start where control_msgs cannot be imported. The real controller: test/package/test_real_goals.py.
"""

from __future__ import annotations

import sys
from types import SimpleNamespace
from typing import Any

import pytest
from rclpy.parameter import Parameter
from rclpy.task import Future
from support.ros_support import RosSession

from fourbar_ros.config.antenna_config import ConfigError
from fourbar_ros.node import trajectory_goals
from fourbar_ros.node.fourbar_node import FourBarNode
from fourbar_ros.rules.goal_outcomes import (
    STATUS_ABORTED,
    STATUS_CANCELED,
    STATUS_SUCCEEDED,
    GoalCounters,
    GoalOutcome,
    outcome,
)
from fourbar_ros.runtime.problem_log import ProblemLog

PREEMPTED = (-1, 'Current goal preempted by new incoming action.')  # joint_trajectory_controller's, jazzy


class FakeAction:
    """Stands in for control_msgs' FollowJointTrajectory: only ``Goal`` is used."""

    Goal = SimpleNamespace


class FakeClient:
    """An action client whose goal and result futures the test resolves."""

    def __init__(self, node: Any, action: Any, name: str) -> None:
        self.name = name
        self.ready = True
        self.goals: list[tuple[Any, Future]] = []

    def server_is_ready(self) -> bool:
        return self.ready

    def send_goal_async(self, goal: Any) -> Future:
        future = Future()
        self.goals.append((goal, future))
        return future

    def destroy(self) -> None:
        pass


def accept(future: Future) -> Future:
    result = Future()
    future.set_result(SimpleNamespace(accepted=True, get_result_async=lambda: result))
    return result


def finish(result: Future, status: int, code: int, text: str) -> None:
    result.set_result(SimpleNamespace(status=status, result=SimpleNamespace(error_code=code, error_string=text)))


@pytest.fixture
def goals(monkeypatch: pytest.MonkeyPatch) -> tuple[trajectory_goals.TrajectoryGoals, FakeClient, list[str]]:
    monkeypatch.setattr(trajectory_goals, 'follow_joint_trajectory', lambda: FakeAction)
    clients: list[FakeClient] = []
    monkeypatch.setattr(trajectory_goals, 'ActionClient', lambda *a: clients.append(FakeClient(*a)) or clients[-1])
    lines: list[str] = []
    problems = ProblemLog(lambda level, line: lines.append(f'{level} {line}'), period=0.0)
    sent = trajectory_goals.TrajectoryGoals(SimpleNamespace(), 'jtc', problems)
    return sent, clients[0], lines


def counts(goals: trajectory_goals.TrajectoryGoals) -> dict[str, int]:
    return {k: v for k, v in vars(goals.counters).items() if isinstance(v, int) and v}


def test_the_action_is_the_controllers(goals: Any) -> None:
    _, client, _ = goals
    assert client.name == 'jtc/follow_joint_trajectory'


def test_a_goal_that_succeeds(goals: Any) -> None:
    sent, client, lines = goals
    assert sent.send('trajectory') is True
    assert client.goals[0][0].trajectory == 'trajectory'
    assert counts(sent) == {'goals_sent': 1}
    result = accept(client.goals[0][1])
    assert counts(sent) == {'goals_sent': 1, 'goals_accepted': 1}
    finish(result, STATUS_SUCCEEDED, 0, 'Goal successfully reached!')
    assert counts(sent) == {'goals_sent': 1, 'goals_accepted': 1, 'goals_succeeded': 1}
    assert sent.counters.last_goal_failure == 'none' and lines == []


def test_a_superseded_goal_is_preempted_and_a_late_answer_is_counted(goals: Any) -> None:
    sent, client, lines = goals
    sent.send('first')
    sent.send('second')  # before the first is even accepted
    second = accept(client.goals[1][1])
    first = accept(client.goals[0][1])  # answers out of order
    finish(second, STATUS_SUCCEEDED, 0, 'Goal successfully reached!')
    finish(first, STATUS_ABORTED, *PREEMPTED)
    assert counts(sent) == {'goals_sent': 2, 'goals_accepted': 2, 'goals_succeeded': 1, 'goals_preempted': 1}
    assert sent.counters.last_goal_failure == 'none' and lines == []  # a preemption is no failure


def test_an_aborted_goal_is_logged_with_the_controllers_reason(goals: Any) -> None:
    sent, client, lines = goals
    sent.send('only')
    finish(accept(client.goals[0][1]), STATUS_ABORTED, -4, 'Aborted due to path tolerance violation')
    assert counts(sent) == {'goals_sent': 1, 'goals_accepted': 1, 'goals_aborted': 1}
    c = sent.counters
    assert (c.last_goal_failure, c.last_goal_error_code, c.last_goal_error_string) == (
        'aborted', '-4 (PATH_TOLERANCE_VIOLATED)', 'Aborted due to path tolerance violation')
    assert lines == ['warn jtc aborted a FollowJointTrajectory goal: error_code -4 (PATH_TOLERANCE_VIOLATED): '
                     'Aborted due to path tolerance violation']
    assert ('last_goal_error_string', 'Aborted due to path tolerance violation') in sent.diagnostic_values()


def test_a_rejected_goal_and_a_failed_request(goals: Any) -> None:
    sent, client, lines = goals
    sent.send('refused')
    client.goals[0][1].set_result(SimpleNamespace(accepted=False))
    sent.send('lost')
    client.goals[1][1].set_exception(RuntimeError('gone'))
    assert counts(sent) == {'goals_sent': 2, 'goals_rejected': 1, 'goals_lost': 1}
    assert sent.counters.last_goal_failure == 'rejected' and len(lines) == 1 and 'rejected' in lines[0]


def test_no_server_no_goal(goals: Any) -> None:
    sent, client, lines = goals
    client.ready = False
    assert sent.send('nobody') is False
    assert counts(sent) == {'goals_not_sent_no_server': 1} and client.goals == []
    assert 'no FollowJointTrajectory server on jtc/follow_joint_trajectory' in lines[0]


@pytest.mark.parametrize(('status', 'code', 'superseded', 'expected'), [
    (STATUS_SUCCEEDED, 0, False, GoalOutcome.SUCCEEDED),
    (STATUS_SUCCEEDED, 0, True, GoalOutcome.SUCCEEDED),
    (STATUS_ABORTED, -1, True, GoalOutcome.PREEMPTED),
    (STATUS_ABORTED, -1, False, GoalOutcome.ABORTED),  # the controller deactivated: nothing newer took over
    (STATUS_ABORTED, -5, True, GoalOutcome.ABORTED),  # a tolerance, even if a newer goal follows
    (STATUS_CANCELED, 0, False, GoalOutcome.CANCELED),
])
def test_outcome(status: int, code: int, superseded: bool, expected: GoalOutcome) -> None:
    assert outcome(status, code, superseded) is expected


def test_counters_keep_only_the_last_failure() -> None:
    c = GoalCounters()
    c.ended(GoalOutcome.ABORTED, -5, 'Aborted due to goal_time_tolerance exceeding by 0.1 seconds')
    c.ended(GoalOutcome.CANCELED, 0, '')
    c.ended(GoalOutcome.SUCCEEDED, 0, 'Goal successfully reached!')
    assert (c.goals_aborted, c.goals_canceled, c.goals_succeeded) == (1, 1, 1)
    assert (c.last_goal_failure, c.last_goal_error_code, c.last_goal_error_string) == ('canceled', '0 (SUCCESSFUL)',
                                                                                       '')


def test_without_control_msgs_the_node_refuses_to_start(ros: RosSession, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, 'control_msgs', None)  # import control_msgs raises ImportError
    with pytest.raises(ConfigError) as err:
        FourBarNode(context=ros.context, namespace='/no_action', parameter_overrides=[
            Parameter('mode', value='trajectory'), Parameter('trajectory_interface', value='action')])
    assert str(err.value).startswith('trajectory_interface: action needs control_msgs') and '\n' not in str(err.value)
