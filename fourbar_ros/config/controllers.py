"""The ros2_control controllers YAML the drive runs, read for what decides which messages its controllers take.

Read as the controller manager reads it (docs/reference/parameters.md); rad and s. No ROS import."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

from fourbar_ros.config.rcl_yaml import ConfigError, read_text, values_from_yaml
from fourbar_ros.config.share import share_path

__all__ = ['CONTROLLERS_FILE', 'LAST_COMMAND_ON_ACTIVATION', 'ForwardControllerSettings', 'JointTolerances',
           'TrajectoryControllerSettings', 'controllers_path', 'forward_controller', 'trajectory_controller']

#: The package's controllers YAML, inside share/fourbar_ros.
CONTROLLERS_FILE = 'config/controllers.yaml'

#: Command interface sets joint_trajectory_controller accepts (``validate_jtc_parameters.hpp``,
#: ``command_interface_type_combinations``), as sorted tuples.
_JTC_COMBINATIONS = frozenset({('effort',), ('velocity',), ('position',), ('position', 'velocity'),
                               ('acceleration', 'position', 'velocity'), ('effort', 'position')})
#: joint_trajectory_controller's option (default true since 4.16) to hold, on activation, the hardware's last
#: command when it is not NaN (``on_activate``: ``update_state_from_command_interfaces``) instead of the measured
#: state: a plugin whose command starts at 0 would drive the rocker towards 0 rad. Refused unless false.
LAST_COMMAND_ON_ACTIVATION = 'set_last_command_interface_value_as_state_on_activation'
#: joint_trajectory_controller's option (since 4.39) to ramp down at the acceleration limits on a cancel or a
#: tolerance violation instead of holding where the drive is: not modelled, refused when true.
DECELERATE_ON_CANCEL = 'constraints.decelerate_on_cancel'


@dataclass(frozen=True)
class JointTolerances:
    """One joint's ``constraints``: ``trajectory`` (rad from the reference while moving) and ``goal`` (rad from the
    last point once its time has passed); 0 means not checked, as in the controller."""

    trajectory: float = 0.0
    goal: float = 0.0


@dataclass(frozen=True)
class TrajectoryControllerSettings:
    """What of a joint_trajectory_controller's parameters decides what it accepts and how it follows."""

    name: str
    joints: tuple[str, ...]
    command_interfaces: tuple[str, ...]
    state_interfaces: tuple[str, ...]
    allow_partial_joints_goal: bool = False
    allow_nonzero_velocity_at_trajectory_end: bool = False
    allow_integration_in_goal_trajectories: bool = False
    interpolate_from_desired_state: bool = False
    open_loop_control: bool = False  #: deprecated; as interpolate_from_desired_state
    interpolation_method: str = 'splines'  #: or 'none'
    #: any of ``speed_scaling.state_interface`` / ``command_interface`` set, or an initial factor other than 1
    speed_scaling: bool = False
    cmd_timeout: float = 0.0  #: s after the last point at which the controller stops on its own (0: never)
    #: ``constraints.stopped_velocity_tolerance`` (rad/s): checked at the goal with a velocity state interface and a
    #: velocity or effort command interface
    stopped_velocity_tolerance: float = 0.01
    #: ``constraints.goal_time``: s allowed past the last point's time to get within the goal tolerance (0: forever)
    goal_time: float = 0.0
    tolerances: Mapping[str, JointTolerances] = field(default_factory=dict)

    @property
    def has_effort_command_interface(self) -> bool:
        """True when the controller commands effort (then trajectory points may carry effort)."""
        return 'effort' in self.command_interfaces

    def tolerance(self, joint: str) -> JointTolerances:
        """The joint's tolerances (zeros, i.e. not checked, when the file gives none)."""
        return self.tolerances.get(joint, JointTolerances())


@dataclass(frozen=True)
class ForwardControllerSettings:
    """A forward_command_controller (e.g. ``position_controllers/JointGroupPositionController``): its joints; each
    ``Float64MultiArray`` command must hold one value per joint."""

    name: str
    joints: tuple[str, ...]


def controllers_path(path: str) -> Path:
    """The controllers YAML to read: ``path``, or the package's own when ``path`` is empty."""
    return Path(path) if path else share_path(CONTROLLERS_FILE)


def _section(path: str, controller: str, namespace: str) -> tuple[str, dict[str, object]]:
    source = str(controllers_path(path))
    try:
        values = values_from_yaml(read_text(source), source, controller, namespace)
    except ConfigError as exc:
        raise ConfigError(f'controllers_file: {exc}', ('controllers_file',)) from None
    return source, values


def _strings(source: str, controller: str, values: Mapping[str, object], key: str, required: bool) -> tuple[str, ...]:
    value = values.get(key, [])
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value) or (required and not value):
        raise ConfigError(f'controllers_file: {source}: {controller}.{key} must be a non-empty list of strings, '
                          f'got {value!r}', ('controllers_file',))
    return tuple(value)


def _typed(source: str, controller: str, values: Mapping[str, object], key: str, kind: type, default: object) -> object:
    value = values.get(key, default)
    if kind is float and isinstance(value, int) and not isinstance(value, bool):
        value = float(value)
    if not isinstance(value, kind) or (kind is not bool and isinstance(value, bool)):
        raise ConfigError(f'controllers_file: {source}: {controller}.{key} must be a {kind.__name__}, got {value!r}',
                          ('controllers_file',))
    return value


def trajectory_controller(path: str, controller: str, namespace: str = '/') -> TrajectoryControllerSettings:
    """The joint_trajectory_controller ``controller`` of the controllers YAML ``path`` (empty: the package's), as the
    controller node ``namespace``/``controller`` receives it (the namespace of its controller manager).

    Raises ConfigError (one line) for an unreadable file, no section for ``controller``, a value of the wrong
    type, an interface combination the controller refuses at configuration, or ``LAST_COMMAND_ON_ACTIVATION`` not
    set false (activation would hold the hardware's last command, not the measured position); what the node does
    not model: a velocity or effort command interface alone (the controller's PID adapter),
    ``DECELERATE_ON_CANCEL`` true."""
    source, values = _section(path, controller, namespace)
    if _typed(source, controller, values, LAST_COMMAND_ON_ACTIVATION, bool, True):
        given = 'is true' if LAST_COMMAND_ON_ACTIVATION in values else 'is not set (the controller\'s default: true)'
        raise ConfigError(f'controllers_file: {source}: {controller}.{LAST_COMMAND_ON_ACTIVATION} {given}: on '
                          'activation the controller then holds the hardware\'s last command, not the measured '
                          'position (a command starting at 0 drives the rocker towards 0 rad); set it false',
                          ('controllers_file',))
    joints = _strings(source, controller, values, 'joints', True)
    commands = _strings(source, controller, values, 'command_interfaces', True)
    if tuple(sorted(commands)) not in _JTC_COMBINATIONS or len(set(commands)) != len(commands):
        raise ConfigError(f'controllers_file: {source}: {controller}.command_interfaces {list(commands)} is not a '
                          'combination joint_trajectory_controller accepts (effort; velocity; position [velocity '
                          '[acceleration]]; position, effort)', ('controllers_file',))
    flags = {key: bool(_typed(source, controller, values, key, bool, False))
             for key in ('allow_partial_joints_goal', 'allow_nonzero_velocity_at_trajectory_end',
                         'allow_integration_in_goal_trajectories', 'interpolate_from_desired_state',
                         'open_loop_control')}
    if commands == ('effort',) or (commands == ('velocity',) and not flags['open_loop_control']):
        raise ConfigError(f'controllers_file: {source}: {controller}.command_interfaces {list(commands)} alone: the '
                          'controller then closes a PID loop on the position error (its gains), which the node does '
                          'not model; command position', ('controllers_file',))
    if _typed(source, controller, values, DECELERATE_ON_CANCEL, bool, False):
        raise ConfigError(f'controllers_file: {source}: {controller}.{DECELERATE_ON_CANCEL} is true: the controller '
                          'then ramps down on a cancel or a tolerance violation instead of holding, which the node '
                          'does not model; set it false', ('controllers_file',))
    scaling = (str(_typed(source, controller, values, 'speed_scaling.state_interface', str, '')),
               str(_typed(source, controller, values, 'speed_scaling.command_interface', str, '')),
               float(_typed(source, controller, values, 'speed_scaling.initial_scaling_factor',  # type: ignore[arg-type]
                            float, 1.0)))
    motion = {'interpolation_method': str(_typed(source, controller, values, 'interpolation_method', str, 'splines')),
              'speed_scaling': scaling != ('', '', 1.0),
              'cmd_timeout': float(_typed(source, controller, values, 'cmd_timeout', float, 0.0)),  # type: ignore[arg-type]
              'stopped_velocity_tolerance': float(_typed(  # type: ignore[arg-type]
                  source, controller, values, 'constraints.stopped_velocity_tolerance', float, 0.01))}
    goal_time = float(_typed(source, controller, values, 'constraints.goal_time', float, 0.0))  # type: ignore[arg-type]
    tolerances = {j: JointTolerances(
        float(_typed(source, controller, values, f'constraints.{j}.trajectory', float, 0.0)),  # type: ignore[arg-type]
        float(_typed(source, controller, values, f'constraints.{j}.goal', float, 0.0)))  # type: ignore[arg-type]
        for j in joints}
    return TrajectoryControllerSettings(controller, joints, commands,
                                        _strings(source, controller, values, 'state_interfaces', True),
                                        goal_time=goal_time, tolerances=tolerances,
                                        **flags, **motion)  # type: ignore[arg-type]


def forward_controller(path: str, controller: str, namespace: str = '/') -> ForwardControllerSettings:
    """The forward_command_controller ``controller`` of the controllers YAML ``path`` (empty: the package's), in
    ``namespace`` as ``trajectory_controller``. Raises ConfigError (one line) as ``trajectory_controller``."""
    source, values = _section(path, controller, namespace)
    return ForwardControllerSettings(controller, _strings(source, controller, values, 'joints', True))
