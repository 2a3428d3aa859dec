"""What joint_trajectory_controller says of a FollowJointTrajectory goal, as the node counts it (no ROS).

``outcome`` names a goal's end from its action status and result code; ``GoalCounters`` counts them and keeps the last
goal that did not succeed. The controller's codes: docs/how-to/ros2-control.md#trajectories-as-action-goals.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

#: action_msgs/GoalStatus values of a finished goal.
STATUS_SUCCEEDED, STATUS_CANCELED, STATUS_ABORTED = 4, 5, 6
#: control_msgs/FollowJointTrajectory result codes (``error_code``).
ERROR_CODES = {0: 'SUCCESSFUL', -1: 'INVALID_GOAL', -2: 'INVALID_JOINTS', -3: 'OLD_HEADER_TIMESTAMP',
               -4: 'PATH_TOLERANCE_VIOLATED', -5: 'GOAL_TOLERANCE_VIOLATED'}
INVALID_GOAL = -1


class GoalOutcome(Enum):
    """How a goal ended."""

    SUCCEEDED = 'succeeded'
    ABORTED = 'aborted'
    PREEMPTED = 'preempted'  # aborted by the controller because a newer goal of ours was accepted
    CANCELED = 'canceled'
    REJECTED = 'rejected'


def outcome(status: int, error_code: int, superseded: bool) -> GoalOutcome:
    """The end of a goal from its final ``status`` and the result's ``error_code``; ``superseded``: a newer goal was
    sent after it. joint_trajectory_controller (jazzy) ends the goal a new one preempts as ABORTED with INVALID_GOAL
    ("Current goal preempted by new incoming action."), so that is a preemption when a newer goal exists."""
    if status == STATUS_SUCCEEDED:
        return GoalOutcome.SUCCEEDED
    if status == STATUS_CANCELED:
        return GoalOutcome.CANCELED
    if superseded and error_code == INVALID_GOAL:
        return GoalOutcome.PREEMPTED
    return GoalOutcome.ABORTED


def code_name(error_code: int) -> str:
    """``PATH_TOLERANCE_VIOLATED`` for -4; the number itself for a code the action does not define."""
    return ERROR_CODES.get(error_code, str(error_code))


@dataclass
class GoalCounters:
    """FollowJointTrajectory goals sent and how they ended; the last goal that ended otherwise than succeeded or
    preempted (its outcome, the result's ``error_code`` and ``error_string``; a rejection has neither)."""

    goals_sent: int = 0
    goals_not_sent_no_server: int = 0
    goals_accepted: int = 0
    goals_rejected: int = 0
    goals_succeeded: int = 0
    goals_aborted: int = 0
    goals_preempted: int = 0
    goals_canceled: int = 0
    goals_lost: int = 0  # the goal request or the result request failed in the client
    last_goal_failure: str = 'none'
    last_goal_error_code: str = 'none'
    last_goal_error_string: str = ''

    def ended(self, how: GoalOutcome, error_code: int | None = None, error_string: str = '') -> None:
        """Count a goal's end (REJECTED: the goal response; every other: the result)."""
        attribute = f'goals_{how.value}'
        setattr(self, attribute, getattr(self, attribute) + 1)
        if how not in (GoalOutcome.SUCCEEDED, GoalOutcome.PREEMPTED):
            self.last_goal_failure = how.value
            self.last_goal_error_code = 'none' if error_code is None else f'{error_code} ({code_name(error_code)})'
            self.last_goal_error_string = error_string

    def as_pairs(self) -> list[tuple[str, str]]:
        """Diagnostics key/value pairs, in the order above."""
        return [(k, str(v)) for k, v in vars(self).items()]


def outcome_line(controller: str, how: GoalOutcome, error_code: int | None, error_string: str) -> str:
    """One log line for a goal that was rejected, aborted or canceled, with the controller's reason."""
    if how is GoalOutcome.REJECTED:
        return (f'{controller} rejected a FollowJointTrajectory goal (the action gives no reason; the controller '
                'logs it: not active, or a trajectory it refuses)')
    code = '' if error_code is None else f' error_code {error_code} ({code_name(error_code)})'
    return f'{controller} {how.value} a FollowJointTrajectory goal:{code}: {error_string or "(no error_string)"}'
