"""The controllers' contract (rules/controller_contract.py) and the settings it reads (config/controllers.py).

Each rule of joint_trajectory_controller's validate_trajectory_msg (Jazzy) has a message that breaks it alone, in
the controller's order of checks; the shipped controllers YAML is read with the controller's defaults; and what the
actuator modes make of commands and antenna trajectories passes the contract the shipped YAML gives.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from support.paths import REPO
from support.trajectory_points import Duration, Point

from fourbar_ros.config.antenna_config import ConfigError, config_from_values, default_config
from fourbar_ros.config.controllers import (
    ForwardControllerSettings,
    JointTolerances,
    TrajectoryControllerSettings,
    forward_controller,
    trajectory_controller,
)
from fourbar_ros.interface.stamps import from_ns, seconds_to_ns
from fourbar_ros.interface.topics import ANTENNA_JOINT
from fourbar_ros.motion.planner import JointMotionState
from fourbar_ros.rules.antenna_trajectory import EndMovingError, EndsInPastError
from fourbar_ros.rules.controller_contract import (
    FLOAT_EPSILON,
    ContractRule,
    check_forward_command,
    check_trajectory,
)
from fourbar_ros.rules.motion_plan import plan_command, planned_points
from fourbar_ros.rules.outgoing import actuation_contract, outgoing_refusal, point_fields
from fourbar_ros.rules.serve import antenna_motion
from fourbar_ros.rules.takeover import ARRIVAL_MARGIN_S

CFG = default_config()
JOINT = CFG.driven_joint
JTC = trajectory_controller('', CFG.trajectory_controller)
NOW = 1_000 * 10**9  # ns


def pts(times: list[float], positions: list[float], **fields: list[list[float]]) -> list[Point]:
    return [Point([p], time_from_start=Duration(*from_ns(seconds_to_ns(t))), **{k: v[i] for k, v in fields.items()})
            for i, (t, p) in enumerate(zip(times, positions, strict=True))]


GOOD = pts([0.0, 1.0], [0.8, 0.9], velocities=[[0.0], [0.0]])

#: One message per rule, each breaking that rule alone: (joint_names, points, stamp ns).
BREAKS: dict[ContractRule, tuple[list[str], list[Point], int]] = {
    ContractRule.PARTIAL_JOINTS: ([JOINT, 'other_joint'], GOOD, 0),
    ContractRule.NO_POINTS: ([JOINT], [], 0),
    ContractRule.FOREIGN_JOINT: (['elbow_joint'], GOOD, 0),
    ContractRule.END_MOVING: ([JOINT], pts([0.0, 1.0], [0.8, 0.9], velocities=[[0.0], [2.0 * FLOAT_EPSILON]]), 0),
    ContractRule.ENDS_IN_PAST: ([JOINT], GOOD, NOW - 2 * 10**9),
    ContractRule.TIME_NOT_INCREASING: ([JOINT], pts([0.0, 1.0, 1.0], [0.8, 0.9, 0.95]), 0),
    ContractRule.FIELD_SIZE: ([JOINT], [*GOOD[:1], Point([0.9, 1.0], time_from_start=Duration(1, 0))], 0),
    ContractRule.EFFORT_FIELD: ([JOINT], pts([0.0, 1.0], [0.8, 0.9], effort=[[0.1], [0.2]]), 0),
    # Stricter than the controller, which takes it over and commands 0 rad (no interpolation branch handles it).
    ContractRule.ACCELERATIONS_WITHOUT_VELOCITIES: ([JOINT], pts([0.0, 1.0], [0.8, 0.9],
                                                                 accelerations=[[0.0], [0.0]]), 0),
}


def test_the_shipped_yaml_gives_the_controllers_settings_with_jazzy_defaults() -> None:
    assert JTC.joints == (JOINT,) and JTC.command_interfaces == ('position',)
    assert not JTC.allow_partial_joints_goal and not JTC.allow_nonzero_velocity_at_trajectory_end
    assert not JTC.allow_integration_in_goal_trajectories and not JTC.interpolate_from_desired_state
    assert JTC.goal_time > 0.0 and JTC.tolerance(JOINT).trajectory > 0.0 and JTC.tolerance(JOINT).goal > 0.0
    assert JTC.tolerance('not_a_joint') == JointTolerances(0.0, 0.0)  # the controller's default: not checked
    assert forward_controller('', CFG.forward_controller) == ForwardControllerSettings(CFG.forward_controller, (JOINT,))


def test_a_good_message_passes() -> None:
    assert check_trajectory(JTC, [JOINT], GOOD, 0, NOW) is None
    assert check_trajectory(JTC, [JOINT], GOOD, NOW - 10**9, NOW) is None  # ends exactly now: not in the past


@pytest.mark.parametrize('rule', list(BREAKS), ids=lambda r: r.value)
def test_each_rule_refuses_its_message(rule: ContractRule) -> None:
    names, points, stamp = BREAKS[rule]
    refusal = check_trajectory(JTC, names, points, stamp, NOW)
    assert refusal is not None and refusal.rule is rule
    assert '\n' not in refusal.reason and refusal.reason


def test_no_joint_names_is_its_own_rule_when_partial_goals_are_allowed() -> None:
    # Without allow_partial_joints_goal an empty name list already breaks the joint count (checked first).
    assert check_trajectory(JTC, [], GOOD, 0, NOW).rule is ContractRule.PARTIAL_JOINTS  # type: ignore[union-attr]
    partial = replace(JTC, allow_partial_joints_goal=True)
    assert check_trajectory(partial, [], GOOD, 0, NOW).rule is ContractRule.NO_JOINT_NAMES  # type: ignore[union-attr]


def test_the_options_admit_what_they_name() -> None:
    names, moving, _ = BREAKS[ContractRule.END_MOVING]
    assert check_trajectory(replace(JTC, allow_nonzero_velocity_at_trajectory_end=True), names, moving, 0, NOW) is None
    names, effort, _ = BREAKS[ContractRule.EFFORT_FIELD]
    assert check_trajectory(replace(JTC, command_interfaces=('position', 'effort')), names, effort, 0, NOW) is None
    # A last velocity at float epsilon is still at rest for the controller (it compares with >).
    at_eps = pts([0.0, 1.0], [0.8, 0.9], velocities=[[0.0], [FLOAT_EPSILON]])
    assert check_trajectory(JTC, [JOINT], at_eps, 0, NOW) is None
    # Integration in goals: a later point may leave out positions, not every field; a first point may not (the
    # controller crashes when such a point is due as it takes the trajectory over).
    integrating = replace(JTC, allow_integration_in_goal_trajectories=True)
    velocities_later = [Point([0.8], [0.0]), Point([], [0.0], time_from_start=Duration(1, 0))]
    assert check_trajectory(integrating, [JOINT], velocities_later, 0, NOW) is None
    velocities_only = [Point([], [0.0]), Point([], [0.0], time_from_start=Duration(1, 0))]
    assert check_trajectory(integrating, [JOINT], velocities_only, 0, NOW).rule is ContractRule.MISHANDLED  # type: ignore[union-attr]
    assert check_trajectory(JTC, [JOINT], velocities_only, 0, NOW).rule is ContractRule.FIELD_SIZE  # type: ignore[union-attr]
    empty = [Point([]), Point([], time_from_start=Duration(1, 0))]
    assert check_trajectory(integrating, [JOINT], empty, 0, NOW).rule is ContractRule.FIELD_SIZE  # type: ignore[union-attr]


def test_the_checks_run_in_the_controllers_order() -> None:
    # Broken twice: the controller reports the check it makes first (point by point: time, sizes, effort).
    both = pts([0.0, 1.0, 1.0], [0.8, 0.9, 0.95], effort=[[], [], [0.3]])
    assert check_trajectory(JTC, [JOINT], both, 0, NOW).rule is ContractRule.TIME_NOT_INCREASING  # type: ignore[union-attr]
    moving_foreign = pts([0.0, 1.0], [0.8, 0.9], velocities=[[0.0], [1.0]])
    assert check_trajectory(JTC, ['elbow_joint'], moving_foreign, 0, NOW).rule is ContractRule.FOREIGN_JOINT  # type: ignore[union-attr]


def test_times_compare_in_whole_nanoseconds() -> None:
    # 1 ns apart is increasing; the same ns is not.
    p = [Point([0.8], time_from_start=Duration(0, 5)), Point([0.9], time_from_start=Duration(0, 6))]
    assert check_trajectory(JTC, [JOINT], p, 0, NOW) is None
    p[1].time_from_start = Duration(0, 5)
    assert check_trajectory(JTC, [JOINT], p, 0, NOW).rule is ContractRule.TIME_NOT_INCREASING  # type: ignore[union-attr]


def test_the_forward_controller_takes_one_value_per_joint() -> None:
    fwd = ForwardControllerSettings('fwd', (JOINT,))
    assert check_forward_command(fwd, [0.8]) is None
    for data in ([], [0.8, 0.9]):
        assert check_forward_command(fwd, data).rule is ContractRule.COMMAND_SIZE  # type: ignore[union-attr]


# --------------------------------------------------------------------------- reading the YAML

#: The line every controllers file must carry (config/controllers.py refuses the controller's default, true).
HOLD_MEASURED = '    set_last_command_interface_value_as_state_on_activation: false\n'


def controllers_yaml(tmp_path: Path, body: str) -> str:
    path = tmp_path / 'controllers.yaml'
    path.write_text(body)
    return str(path)


def test_interface_combinations_the_controller_refuses_are_refused_at_load(tmp_path: Path) -> None:
    for interfaces in ('[velocity, effort]', '[effort, velocity, position]', '[acceleration]', '[position, position]'):
        path = controllers_yaml(tmp_path, f'jtc:\n  ros__parameters:\n    joints: [{JOINT}]\n'
                                          f'    command_interfaces: {interfaces}\n    state_interfaces: [position]\n'
                                          + HOLD_MEASURED)
        with pytest.raises(ConfigError, match='command_interfaces'):
            trajectory_controller(path, 'jtc')
    path = controllers_yaml(tmp_path, f'jtc:\n  ros__parameters:\n    joints: [{JOINT}]\n'
                                      '    command_interfaces: [position, effort]\n    state_interfaces: [position]\n'
                                  + HOLD_MEASURED)
    assert trajectory_controller(path, 'jtc').has_effort_command_interface


def test_a_missing_section_or_a_wrong_type_is_one_line(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match='controllers_file') as missing:
        trajectory_controller('', 'no_such_controller')
    assert '\n' not in str(missing.value)
    path = controllers_yaml(tmp_path, f'jtc:\n  ros__parameters:\n    joints: [{JOINT}]\n    command_interfaces: '
                                      '[position]\n    state_interfaces: [position]\n'
                                      '    allow_partial_joints_goal: 1\n' + HOLD_MEASURED)
    with pytest.raises(ConfigError, match='allow_partial_joints_goal must be a bool'):
        trajectory_controller(path, 'jtc')


@pytest.mark.parametrize(('interfaces', 'more', 'match'), [
    ('[velocity]', '', 'PID loop'), ('[effort]', '', 'PID loop'), ('[effort]', '    open_loop_control: true\n', 'PID'),
    ('[position]', '    constraints:\n      decelerate_on_cancel: true\n', 'decelerate_on_cancel is true'),
])
def test_what_the_node_does_not_model_is_refused_in_one_line(tmp_path: Path, interfaces: str, more: str,
                                                             match: str) -> None:
    # The PID adapter (a velocity or effort command interface alone; velocity in open loop has none) and a ramp
    # down on cancel change what the drive is commanded, which neither the model nor the simulated actuator has.
    body = f'jtc:\n  ros__parameters:\n    joints: [{JOINT}]\n    command_interfaces: {interfaces}\n' \
           '    state_interfaces: [position]\n' + HOLD_MEASURED
    with pytest.raises(ConfigError, match=match) as bad:
        trajectory_controller(controllers_yaml(tmp_path, body + more), 'jtc')
    assert '\n' not in str(bad.value)
    assert trajectory_controller(controllers_yaml(tmp_path, body.replace(interfaces, '[position]')), 'jtc')
    velocity = body.replace(interfaces, '[velocity]') + '    open_loop_control: true\n'
    assert trajectory_controller(controllers_yaml(tmp_path, velocity), 'jtc').open_loop_control


@pytest.mark.parametrize('line', ['', '    set_last_command_interface_value_as_state_on_activation: true\n'])
def test_activation_from_the_last_command_is_refused_in_one_line_naming_the_key(tmp_path: Path, line: str) -> None:
    # Set true, or not set (the controller's default since 4.16 is true): on activation the controller would hold
    # the hardware's last command, not the measured position. The same file with it false is read.
    body = f'jtc:\n  ros__parameters:\n    joints: [{JOINT}]\n    command_interfaces: [position]\n' \
           '    state_interfaces: [position]\n'
    with pytest.raises(ConfigError, match=r'jtc\.set_last_command_interface_value_as_state_on_activation is') as bad:
        trajectory_controller(controllers_yaml(tmp_path, body + line), 'jtc')
    assert '\n' not in str(bad.value) and 'set it false' in str(bad.value)
    assert ('is true' if line else 'is not set') in str(bad.value), str(bad.value)
    assert trajectory_controller(controllers_yaml(tmp_path, body + HOLD_MEASURED), 'jtc').joints == (JOINT,)
    node = controllers_yaml(tmp_path, (body + line).replace('jtc:', 'joint_trajectory_controller:'))
    with pytest.raises(ConfigError, match='set_last_command_interface_value_as_state_on_activation'):
        actuation_contract(config_from_values({'mode': 'trajectory', 'controllers_file': node}))


def test_the_node_refuses_to_start_with_a_contract_it_cannot_meet(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match='effort_feedforward'):
        actuation_contract(config_from_values({'mode': 'trajectory', 'effort_feedforward': True}))
    other = controllers_yaml(tmp_path, 'joint_trajectory_controller:\n  ros__parameters:\n    joints: [a, b]\n'
                                       '    command_interfaces: [position]\n    state_interfaces: [position]\n'
                                       + HOLD_MEASURED)
    with pytest.raises(ConfigError, match='joints'):
        actuation_contract(config_from_values({'mode': 'trajectory', 'controllers_file': other}))


def test_a_replan_tolerance_at_or_above_the_path_tolerance_is_refused_in_one_line(tmp_path: Path) -> None:
    # The shipped file's path tolerance at the driven joint is 1 deg: a drive held off the motion by more than that
    # must count as off it for the node, so replan_tolerance must stay below. No path tolerance: anything goes.
    path = trajectory_controller('', 'joint_trajectory_controller').tolerance('rocker_ab_joint').trajectory
    assert path == pytest.approx(math.radians(1.0))
    actuation_contract(config_from_values({'mode': 'trajectory', 'replan_tolerance': 0.999 * path}))
    for tolerance in (path, 0.05):
        with pytest.raises(ConfigError, match=r'^replan_tolerance: .* must be below the path tolerance') as bad:
            actuation_contract(config_from_values({'mode': 'trajectory', 'replan_tolerance': tolerance}))
        assert '\n' not in str(bad.value) and repr(path) in str(bad.value)
    loose = controllers_yaml(tmp_path, f'joint_trajectory_controller:\n  ros__parameters:\n    joints: [{JOINT}]\n'
                                       '    command_interfaces: [position]\n    state_interfaces: [position]\n'
                                       + HOLD_MEASURED)
    actuation_contract(config_from_values({'mode': 'trajectory', 'replan_tolerance': 0.05, 'controllers_file': loose}))
    actuation_contract(config_from_values({'mode': 'forward', 'replan_tolerance': 0.05}))


# --------------------------------------------------------------------------- what the node makes passes


def effort_contract(tmp_path: Path) -> TrajectoryControllerSettings:
    text = (REPO / 'config' / 'controllers.yaml').read_text()
    assert text.count('      - position\n    state_interfaces:') == 1
    path = controllers_yaml(tmp_path, text.replace('      - position\n    state_interfaces:',
                                                   '      - position\n      - effort\n    state_interfaces:'))
    cfg = config_from_values({'mode': 'trajectory', 'effort_feedforward': True, 'controllers_file': path})
    contract = actuation_contract(cfg)
    assert isinstance(contract, TrajectoryControllerSettings)
    return contract


@pytest.mark.parametrize('q0', [0.75, 0.85, 0.95])
def test_planned_commands_pass_the_contract_with_and_without_effort(tmp_path: Path, q0: float) -> None:
    plan = plan_command(CFG, JointMotionState(q0), 0.5 * (CFG.theta_min + CFG.theta_max))
    traj = planned_points(CFG, plan)
    plain = point_fields(traj, effort=False)
    assert all(not p.effort for p in plain)
    assert outgoing_refusal(JTC, JOINT, plain, 0, NOW) is None
    with_effort = point_fields(traj, effort=True)
    assert [p.effort[0] for p in with_effort] == traj.efforts.tolist()
    assert outgoing_refusal(JTC, JOINT, with_effort, 0, NOW).rule is ContractRule.EFFORT_FIELD  # type: ignore[union-attr]
    assert outgoing_refusal(effort_contract(tmp_path), JOINT, with_effort, 0, NOW) is None


def antenna(times: list[float], theta: list[float], theta_dot: list[float]) -> list[Point]:
    return pts(times, theta, velocities=[[v] for v in theta_dot])


def test_an_antenna_trajectory_ending_in_motion_is_refused_unless_the_controller_allows_it() -> None:
    moving = antenna([0.0, 1.0, 2.0], [0.0, 0.01, 0.02], [0.0, 0.01, 0.004])
    with pytest.raises(EndMovingError, match=r'theta_dot = 0\.004'):
        antenna_motion(CFG, False, [ANTENNA_JOINT], moving, 0, NOW)
    converted = antenna_motion(CFG, True, [ANTENNA_JOINT], moving, 0, NOW)
    last = point_fields(converted.trajectory, effort=False)[-1]
    theta = np.array([0.02])
    q1 = float(CFG.linkage.rates_at(theta, *CFG.linkage.rocker_angles(theta, CFG.branch)).dgamma_dtheta[0])
    # The chain rule q' theta_dot: the same q' evaluated twice (array paths), within a few ulps.
    assert math.isclose(last.velocities[0], 0.004 * q1, rel_tol=1e-14)
    allowing = replace(JTC, allow_nonzero_velocity_at_trajectory_end=True)
    assert outgoing_refusal(allowing, JOINT, point_fields(converted.trajectory, False), 0, NOW) is None
    assert outgoing_refusal(JTC, JOINT, point_fields(converted.trajectory, False), 0, NOW).rule \
        is ContractRule.END_MOVING  # type: ignore[union-attr]


def test_an_antenna_trajectory_ending_in_the_past_is_refused_and_stamp_0_starts_on_arrival() -> None:
    rest = antenna([0.0, 1.0, 2.0], [0.0, 0.01, 0.02], [0.0, 0.01, 0.0])
    # Ending in the past, or now: it could arrive ended (within ARRIVAL_MARGIN_S), and the controller would refuse
    # it.
    for stamp in (NOW - 3 * 10**9, NOW - 2 * 10**9):
        with pytest.raises(EndsInPastError):
            antenna_motion(CFG, False, [ANTENNA_JOINT], rest, stamp, NOW)
    lead = round(ARRIVAL_MARGIN_S * 1e9)
    for stamp in (0, NOW - 2 * 10**9 + lead, NOW + 10**9):  # on arrival; ending a lead from now; in the future
        converted = antenna_motion(CFG, False, [ANTENNA_JOINT], rest, stamp, NOW)
        assert outgoing_refusal(JTC, JOINT, point_fields(converted.trajectory, False), stamp, NOW) is None
