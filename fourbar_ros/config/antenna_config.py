"""Antenna configuration: validated node parameters, from a ROS 2 parameter file or a name->value map.

The rules the node applies, applied the same way: docs/reference/parameters.md. Metres, radians, N m, kg, s."""

from __future__ import annotations

import math
import re
from collections.abc import Collection, Mapping
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

from fourbar_ros.config.params import (
    MIN_REDUCTION,
    PARAMETERS,
    PARAMETERS_BY_NAME,
    RANGE_REL_TOL,
    ParamSpec,
    ParamValue,
    is_foreign,
)
from fourbar_ros.config.rcl_yaml import (
    ConfigError,
    node_sections,
    rcl_scalar,
    read_text,
    section_pattern,
    values_from_yaml,
)
from fourbar_ros.core.antenna import AntennaLinkage, Branch, Driven
from fourbar_ros.core.completion import inverse_branch
from fourbar_ros.core.errors import FourBarError
from fourbar_ros.core.loads import has_gravity_load
from fourbar_ros.interface.topics import NODE_NAME

__all__ = [
    'AntennaConfig', 'ConfigError', 'check_value', 'config_from_values', 'declared_values',
    'default_config', 'load_config', 'rcl_scalar', 'unknown_in_node_sections', 'values_from_yaml',
]

#: Samples (plus both ends) used to check that the driven rocker has no dead point in the range.
_RANGE_SAMPLES = 512


@dataclass(frozen=True)
class AntennaConfig:
    """A validated configuration (build it with ``config_from_values`` or ``load_config``).

    One field per entry of ``fourbar_ros.config.params.PARAMETERS`` (named by its ``attribute``; the table holds
    each one's unit, range and description, and a test holds these fields to it), plus the linkage they make.
    Angles in rad, lengths in m, torques in N m (``load_torque`` about theta,
    ``output_torque_limit`` at the driven rocker, ``motor_torque_limit`` before the reducer).
    """

    frame_length: float
    rocker_ab_length: float
    coupler_length: float
    rocker_cd_length: float
    theta_min: float
    theta_max: float
    driven: Driven
    branch: Branch
    load_torque: float
    antenna_mass: float
    com_offset_along: float
    com_offset_normal: float
    gravity: float
    reducer_ratio: float
    driven_joint_offset: float
    reducer_efficiency: float
    motor_torque_limit: float
    output_torque_limit: float
    motor_speed_limit: float
    motor_acceleration_limit: float
    motor_jerk_limit: float
    trajectory_tolerance: float
    limit_policy: str
    control_rate: float
    max_trajectory_points: int
    mode: str
    trajectory_controller: str
    trajectory_interface: str
    forward_controller: str
    controllers_file: str
    controller_manager: str
    command_hold_timeout: float
    resume_interrupted: bool
    reached_tolerance: float
    reach_timeout: float
    follow_tolerance: float
    follow_timeout: float
    effort_feedforward: bool
    replan_tolerance: float
    measured_range_tolerance: float
    measurement_timeout: float
    tracking_window: float
    antenna_sensor_type: str
    antenna_sensor_offset: float
    antenna_imu_yaw: float
    antenna_sensor_latency: float
    antenna_sensor_noise: float
    antenna_sensor_noise_correlation: float
    antenna_sensor_map_sd: float
    model_mismatch_warn_sds: float
    model_mismatch_error_sds: float
    model_mismatch_warn: float
    model_mismatch_error: float
    slip_stop_mismatch: float
    slip_stop_time: float
    gamma_joint: str
    delta_joint: str
    coupler_joint: str
    hardware_id: str
    hardware_parameters: tuple[str, ...]
    frame_id: str
    out_of_limits: str
    transmission_angle_min: float
    velocity_timeout: float
    marker_period: float
    diagnostics_period: float
    joint_state_rate: float
    linkage: AntennaLinkage = field(compare=False, repr=False)

    @property
    def has_gravity_load(self) -> bool:
        """True when the antenna weight adds an angle-dependent load."""
        return has_gravity_load(self)

    @property
    def reduction(self) -> float:
        """Motor turns per rocker turn whichever way the motor turns: |reducer_ratio|. The motor's speed,
        acceleration and jerk limits (rad/s^n at the motor) over it are the driven rocker's."""
        return abs(self.reducer_ratio)

    @property
    def joint_names(self) -> tuple[str, str, str]:
        """JointState names, in the order the node publishes them: rocker AB (gamma), rocker CD (delta), coupler."""
        return self.gamma_joint, self.delta_joint, self.coupler_joint

    @property
    def driven_joint(self) -> str:
        """JointState name of the driven rocker: ``gamma_joint`` or ``delta_joint``, as ``driven_rocker`` says."""
        return self.gamma_joint if self.driven is Driven.GAMMA else self.delta_joint

    @cached_property
    def measured_branch(self) -> Branch:
        """The branch to pass to ``from_rocker`` (and ``complete``) when the driven rocker is given: the one that
        gives back the configured ``branch``'s pose (``core.completion.inverse_branch``; the two count branches
        differently, so they differ for some geometries, e.g. a coupler longer than the frame). Found at mid-range:
        it holds over the whole tilt range, which has no dead point of the driven rocker (checked at load)."""
        return inverse_branch(self.linkage, 0.5 * (self.theta_min + self.theta_max), self.driven, self.branch)

    def as_values(self) -> dict[str, ParamValue]:
        """Parameter name -> value (the inverse of ``config_from_values``)."""
        return {spec.name: spec.to_value(getattr(self, spec.attribute)) for spec in PARAMETERS}


def _type_name(value: object) -> str:
    if isinstance(value, bool):
        return 'bool'
    if isinstance(value, int):
        return 'integer'
    if isinstance(value, float):
        return 'double'
    if isinstance(value, str):
        return 'string'
    if isinstance(value, list):
        return 'array'
    if isinstance(value, dict):
        return 'mapping'
    return type(value).__name__


def _in_range(spec: ParamSpec, value: float, rel_tol: float) -> float:
    """``value`` if within the spec's inclusive bounds (doubles: up to rclpy's relative tolerance), else ConfigError."""
    name, lo, hi = spec.name, spec.minimum, spec.maximum
    if lo is not None and value < lo and not math.isclose(value, lo, rel_tol=rel_tol):
        raise ConfigError(f'{name}: {value!r} {spec.unit} is below the minimum {lo!r}'.replace('  ', ' '), (name,))
    if hi is not None and value > hi and not math.isclose(value, hi, rel_tol=rel_tol):
        raise ConfigError(f'{name}: {value!r} {spec.unit} is above the maximum {hi!r}'.replace('  ', ' '), (name,))
    return value


def check_value(spec: ParamSpec, value: object) -> ParamValue:
    """Check one value against its spec (type as rclpy enforces it, range, choices); return it.

    Raises ``ConfigError`` (``"<name>: <why>"``). Like rclpy, an integer is not a double:
    write ``500.0``, not ``500``; nor is a double an integer.
    """
    name = spec.name
    if spec.type is float:
        if isinstance(value, bool) or not isinstance(value, float):
            hint = f' (write {value}.0)' if isinstance(value, int) and not isinstance(value, bool) else ''
            raise ConfigError(f'{name}: expected a double{hint}, got {_type_name(value)} {value!r}', (name,))
        if not math.isfinite(value):
            raise ConfigError(f'{name}: must be finite, got {value!r}', (name,))
        return _in_range(spec, value, RANGE_REL_TOL)
    if spec.type is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(f'{name}: expected an integer, got {_type_name(value)} {value!r}', (name,))
        return _in_range(spec, value, 0.0)
    if spec.type is bool:
        if not isinstance(value, bool):
            raise ConfigError(f'{name}: expected a bool (true or false), got {_type_name(value)} {value!r}', (name,))
        return value
    if spec.type is list:
        return _name_values(spec, value)
    if spec.type is str:
        if not isinstance(value, str):
            raise ConfigError(f'{name}: expected a string, got {_type_name(value)} {value!r}', (name,))
        if spec.choices and value not in spec.choices:
            raise ConfigError(f"{name}: {value!r} is not one of {', '.join(spec.choices)}", (name,))
        if not value.strip() and spec.default != '':
            raise ConfigError(f'{name}: must not be empty', (name,))
        return value
    raise ConfigError(f'{name}: unsupported parameter type {spec.type.__name__}')  # pragma: no cover


_PARAM_NAME = re.compile(r'[A-Za-z_][A-Za-z0-9_.\-]*')


def _name_values(spec: ParamSpec, value: object) -> list[str]:
    """A list of ``name=value`` strings, names distinct and plain (an XML attribute needs no escaping then).
    ``None`` is the empty list: rcl reads ``[]`` in a parameter file as a parameter not set."""
    name = spec.name
    if value is None:
        return []
    if not isinstance(value, list | tuple) or not all(isinstance(v, str) for v in value):
        raise ConfigError(f'{name}: expected a list of name=value strings, got {_type_name(value)} {value!r}',
                          (name,))
    seen: set[str] = set()
    for entry in value:
        key, equals, _ = entry.partition('=')
        key = key.strip()
        if not equals or not _PARAM_NAME.fullmatch(key):
            raise ConfigError(f'{name}: {entry!r} is not name=value (a name of letters, digits, _, ., -)', (name,))
        if key in seen:
            raise ConfigError(f'{name}: {key!r} is given twice', (name,))
        seen.add(key)
    return list(value)


def _deg(angle: float) -> str:
    return f'{angle!r} rad ({math.degrees(angle):.6g} deg)'


_LENGTHS = ('frame_length', 'rocker_ab_length', 'coupler_length', 'rocker_cd_length')


def _fault(why: str, primary: tuple[str, ...], involved: tuple[str, ...],
           changed: Collection[str] | None) -> ConfigError:
    """A cross-parameter rejection naming the parameters at fault: those of ``involved`` the caller changed,
    else ``primary`` (the ones a reader would fix first)."""
    names = tuple(n for n in involved if n in changed) if changed else ()
    names = names or primary
    return ConfigError(f"{', '.join(names)}: {why}", names)


def _check_tilt_range(linkage: AntennaLinkage, theta_min: float, theta_max: float,
                      driven: Driven, branch: Branch, changed: Collection[str] | None) -> None:
    """Raise ConfigError unless the linkage assembles on ``branch`` over [theta_min, theta_max]
    and the driven rocker has no dead point (d q/d theta = 0) inside it."""
    tilt = ('theta_min', 'theta_max')
    if not theta_min < theta_max:
        raise _fault(f'theta_min {_deg(theta_min)} must be below theta_max {_deg(theta_max)}', tilt, tilt, changed)
    reach = linkage.reach()
    for name, theta in (('theta_min', theta_min), ('theta_max', theta_max)):
        if not reach.contains(theta):
            raise _fault(f'{name} {_deg(theta)} is out of the linkage reach {reach.describe()}',
                         (name,), (name, *_LENGTHS), changed)
    if reach.theta_gap > 0.0 and theta_min < reach.theta_gap and theta_max > -reach.theta_gap:
        raise _fault(f'[theta_min, theta_max] = [{_deg(theta_min)}, {_deg(theta_max)}] crosses the unreachable '
                     f'band |theta| < {_deg(reach.theta_gap)}', tilt, (*tilt, *_LENGTHS), changed)
    samples = [theta_min + (theta_max - theta_min) * i / _RANGE_SAMPLES
               for i in range(_RANGE_SAMPLES + 1)]
    sign = 0.0
    for theta in samples:
        try:
            advantage = linkage.mechanical_advantage(theta, driven=driven, branch=branch)
        except FourBarError as exc:
            raise _fault(f'the linkage does not assemble at theta = {_deg(theta)} inside [theta_min, theta_max]: '
                         f'{exc}', tilt, (*tilt, *_LENGTHS, 'branch'), changed) from None
        if not math.isfinite(advantage) or advantage == 0.0 or (sign and advantage * sign < 0.0):
            raise _fault(f'the {driven.value} rocker (driven_rocker) has a dead point near theta = {_deg(theta)} '
                         f'inside [theta_min, theta_max] = [{_deg(theta_min)}, {_deg(theta_max)}] (unbounded input '
                         'torque): narrow the range or drive the other rocker',
                         (*tilt, 'driven_rocker'), (*tilt, 'driven_rocker', *_LENGTHS, 'branch'), changed)
        sign = math.copysign(1.0, advantage)


def declared_values(values: Mapping[str, object]) -> dict[str, object]:
    """The entries of ``values`` that name a fourbar_node parameter (ROS convention: others are ignored)."""
    return {name: value for name, value in values.items() if name in PARAMETERS_BY_NAME}


def config_from_values(values: Mapping[str, object], changed: Collection[str] | None = None) -> AntennaConfig:
    """Validate a complete or partial name->value map (missing names take their defaults).

    Unknown names raise ``ConfigError`` (rclpy's own ``use_sim_time``/``qos_overrides.*`` are ignored); filter
    a parameter file's values with ``declared_values`` first. ``changed``: the names a run-time change sets;
    a rejection that involves several parameters then names those of them at fault (``ConfigError.names``).
    """
    for name in values:
        if name not in PARAMETERS_BY_NAME and not is_foreign(name):
            raise ConfigError(f'{name}: unknown parameter (known: {", ".join(PARAMETERS_BY_NAME)})', (name,))
    v: dict[str, Any] = {}
    for spec in PARAMETERS:
        v[spec.name] = check_value(spec, values.get(spec.name, spec.default))
    attributes: dict[str, Any] = {spec.attribute: spec.to_attribute(v[spec.name]) for spec in PARAMETERS}
    driven: Driven = attributes['driven']
    branch: Branch = attributes['branch']
    try:
        linkage = AntennaLinkage(frame=v['frame_length'], rocker_ab=v['rocker_ab_length'],
                                 coupler=v['coupler_length'], rocker_cd=v['rocker_cd_length'])
    except FourBarError as exc:
        raise _fault(f'the lengths do not form a linkage: {exc}', _LENGTHS, _LENGTHS, changed) from None
    _check_tilt_range(linkage, v['theta_min'], v['theta_max'], driven, branch, changed)
    if abs(v['reducer_ratio']) < MIN_REDUCTION:
        raise ConfigError(f"reducer_ratio: {v['reducer_ratio']!r} is within {MIN_REDUCTION!r} of 0 (negative: a "
                          'reversed motor)', ('reducer_ratio',))
    if not v['model_mismatch_warn'] < v['model_mismatch_error']:
        mismatch = ('model_mismatch_warn', 'model_mismatch_error')
        raise _fault(f"model_mismatch_warn {v['model_mismatch_warn']!r} rad must be below model_mismatch_error "
                     f"{v['model_mismatch_error']!r} rad", mismatch, mismatch, changed)
    if not v['model_mismatch_warn_sds'] < v['model_mismatch_error_sds']:
        sds = ('model_mismatch_warn_sds', 'model_mismatch_error_sds')
        raise _fault(f"model_mismatch_warn_sds {v['model_mismatch_warn_sds']!r} must be below "
                     f"model_mismatch_error_sds {v['model_mismatch_error_sds']!r}", sds, sds, changed)
    joints = ('gamma_joint', 'delta_joint', 'coupler_joint')
    for i, first in enumerate(joints):
        for second in joints[i + 1:]:
            if v[first] == v[second]:
                raise _fault(f'{first} and {second} are both {v[first]!r}; joint names must differ',
                             (first, second), (first, second), changed)
    return AntennaConfig(**attributes, linkage=linkage)


def default_config() -> AntennaConfig:
    """The configuration with every parameter at its default (Turnantenna)."""
    return config_from_values({})


def load_config(path: str | Path, node_name: str = NODE_NAME, namespace: str = '/') -> AntennaConfig:
    """Read and validate a ROS 2 parameter file (``/**:`` or ``<node_name>:`` -> ``ros__parameters:``)
    as the node ``namespace``/``node_name`` would receive it.

    Names that are not fourbar_node parameters are ignored, as a ROS node ignores parameters it does not declare
    (a ``/**`` section shared by a whole robot carries other nodes' parameters); ``unknown_in_node_sections``
    lists those in sections naming this node, for a warning. At most ``rcl_yaml.MAX_FILE_BYTES`` are read.
    Raises ``ConfigError`` with a one-line message naming the parameter (or the file) and why.
    """
    values = values_from_yaml(read_text(path), str(path), node_name, namespace)
    try:
        return config_from_values(declared_values(values))
    except ConfigError as exc:
        raise ConfigError(f'{path}: {exc}', exc.names) from None


def unknown_in_node_sections(path: str | Path, node_name: str = NODE_NAME, namespace: str = '/') -> list[str]:
    """Names that are not fourbar_node parameters (nor rclpy's own) in the sections of a parameter file that name
    this node explicitly (``fourbar_node:``, ``/ns/fourbar_node:``, ``/*/fourbar_node:``; not wildcard sections such
    as ``/**:``, which commonly carry other nodes' parameters), in file order: probably typos, worth a warning.

    Raises ``ConfigError`` like ``load_config`` if the file cannot be read or is not a parameter file.
    """
    sections = node_sections(read_text(path), str(path), node_name, namespace)
    unknown: dict[str, None] = {}
    for key, values in sections:
        pattern = section_pattern(key)
        if not pattern or pattern[-1] != node_name:
            continue
        for name in values:
            if name not in PARAMETERS_BY_NAME and not is_foreign(name):
                unknown[name] = None
    return list(unknown)
