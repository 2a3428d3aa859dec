"""The reason the controller manager gave for deactivating the controller, from its log lines (no ROS): only its
own logger's ERROR lines naming the controller as a word count, those around the latest deactivation, in order."""

from __future__ import annotations

from fourbar_ros.interface.stamps import seconds_to_ns
from fourbar_ros.rules.manager_errors import AROUND_S, LOG_ERROR, ManagerErrors, manager_logger

JTC = 'joint_trajectory_controller'
#: What the Jazzy controller manager logs when a joint read outside its limits fails the controller's update.
CAUGHT = (f"Caught exception of type : St13runtime_error while updating controller '{JTC}': Joint position is out "
          "of bounds for the joint : 'rocker_ab_joint' actual position: 0.6 limits: [0.714, 1.0006].")
DEACTIVATING = f'Deactivating controllers : [ {JTC} ] as their update resulted in an error!'
S = seconds_to_ns(1.0)


def test_the_logger_of_a_manager_is_its_full_name_with_dots() -> None:
    assert manager_logger('/controller_manager') == 'controller_manager'
    assert manager_logger('/tilt/controller_manager') == 'tilt.controller_manager'
    assert manager_logger('/a/b/controller_manager') == 'a.b.controller_manager'


def test_only_the_manager_s_error_lines_naming_the_controller_are_kept() -> None:
    errors = ManagerErrors('tilt.controller_manager', JTC)
    assert errors.line('tilt.controller_manager', LOG_ERROR, CAUGHT, 0)
    assert errors.line('tilt.controller_manager', 50, DEACTIVATING, 0)  # FATAL counts too
    assert not errors.line('tilt.controller_manager', 30, CAUGHT, 0), 'a WARN'
    assert not errors.line('controller_manager', LOG_ERROR, CAUGHT, 0), 'another namespace\'s manager'
    assert not errors.line('joint_limiter_interface', LOG_ERROR, CAUGHT, 0), 'another logger'
    assert not errors.line('tilt.controller_manager', LOG_ERROR, f"while updating controller '{JTC}_2'", 0)
    assert not errors.line('tilt.controller_manager', LOG_ERROR, f'/tilt/{JTC}/joint_trajectory lost', 0)
    errors.active(False, 0)
    assert errors.reason() == f'{CAUGHT}; {DEACTIVATING}'


def test_the_reason_is_the_lines_around_the_latest_deactivation_while_inactive() -> None:
    errors = ManagerErrors('controller_manager', JTC)
    assert errors.reason() == '', 'never seen inactive'
    errors.line('controller_manager', LOG_ERROR, 'old ' + CAUGHT, 0)
    errors.active(True, 5 * S)
    errors.line('controller_manager', LOG_ERROR, CAUGHT, 9 * S)  # before the node sees the deactivation
    assert errors.reason() == '', 'active'
    errors.active(False, 9 * S + 1)
    errors.line('controller_manager', LOG_ERROR, DEACTIVATING, 10 * S)  # after it
    assert errors.reason() == f'{CAUGHT}; {DEACTIVATING}', 'the line stamped 9 s before is left out'
    errors.active(False, 20 * S)  # still inactive: the leaving stays the one at 9 s
    assert errors.reason() == f'{CAUGHT}; {DEACTIVATING}'
    errors.active(True, 21 * S)
    assert errors.reason() == ''
    errors.active(False, 21 * S + seconds_to_ns(AROUND_S) + 9 * S)  # switched off on request: nothing logged
    assert errors.reason() == ''
