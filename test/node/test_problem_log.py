"""Logs throttled per problem kind, and the callback boundary: an exception is counted, logged, swallowed."""

from __future__ import annotations

import pytest
from support.ros_support import RosSession

from fourbar_ros.node.fourbar_node import FourBarNode
from fourbar_ros.runtime.problem_log import MAX_KINDS, CallbackGuard, ProblemLog


class Clock:
    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


def test_two_problems_from_one_line_are_both_logged() -> None:
    """rclpy's throttle is per call site: a second, different refusal within the period from the same line was
    never logged. Here each kind has its own throttle."""
    lines: list[tuple[str, str]] = []
    clock = Clock()
    problems = ProblemLog(lambda level, line: lines.append((level, line)), 1.0, clock)
    for kind in ('antenna trajectory over_limits', 'antenna trajectory out_of_reach'):  # the same call site
        assert problems.warn(kind, f'refused: {kind}')
    assert [line for _, line in lines] == ['refused: antenna trajectory over_limits',
                                           'refused: antenna trajectory out_of_reach']
    assert not problems.warn('antenna trajectory over_limits', 'again')  # the same kind within the period: held
    assert not problems.warn('antenna trajectory over_limits', 'again')
    clock.t = 1.5
    assert problems.error('antenna trajectory over_limits', 'later')
    assert lines[-1] == ('error', 'later (2 more of this kind held back)')


def test_the_kinds_remembered_are_bounded() -> None:
    problems = ProblemLog(lambda level, line: None, 1.0, Clock())
    for k in range(3 * MAX_KINDS):
        problems.warn(f'kind {k}', 'x')
    assert len(problems._kinds) == MAX_KINDS


def test_an_exception_in_a_callback_is_counted_logged_once_per_kind_and_swallowed() -> None:
    lines: list[str] = []
    guard = CallbackGuard(ProblemLog(lambda level, line: lines.append(line), 1.0, Clock()))

    def on_message(msg: object, info: object) -> None:
        raise IndexError('index 1 is out of bounds for axis 0 with size 1')

    wrapped = guard.wrap('sub_antenna_trajectory', on_message)
    for _ in range(3):
        assert wrapped('msg', 'info') is None
    assert guard.errors == {'sub_antenna_trajectory': 3} and guard.total == 3
    assert lines == ['callback sub_antenna_trajectory failed (1 so far): IndexError: index 1 is out of bounds for '
                     'axis 0 with size 1']
    assert ('callback_errors_sub_antenna_trajectory', '3') in guard.diagnostic_values()
    import inspect
    assert list(inspect.signature(wrapped).parameters) == ['msg', 'info']  # rclpy reads it to pass message info


@pytest.mark.ros
def test_the_node_logs_both_severities_through_its_problem_log(ros: RosSession) -> None:
    """rclpy's logger refuses a second severity from one call site (ValueError): the node's problem log writes
    warnings and errors from separate calls, so both reach the log."""
    node = FourBarNode(context=ros.context, namespace='/problem_log')
    try:
        assert node.problems.warn('a warning', 'a warning line')
        assert node.problems.error('an error', 'an error line')
        assert node.problems.warn('another warning', 'another warning line')
    finally:
        node.destroy_node()


def test_a_guarded_callback_answers_what_failed_says_and_keeps_one_parameter() -> None:
    guard = ProblemLog(lambda level, line: None, 1.0, Clock()).guard
    wrapped = guard.wrap('set_parameters', lambda params: params[0], lambda exc: type(exc).__name__)
    assert wrapped([7]) == 7 and wrapped([]) == 'IndexError'
    assert guard.errors == {'set_parameters': 1}
    import inspect
    assert list(inspect.signature(wrapped).parameters) == ['params']
