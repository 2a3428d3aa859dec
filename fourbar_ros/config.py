"""Antenna configuration: validated node parameters, from a ROS 2 parameter file or a name->value map.

``load_config(path)`` reads the same YAML that ``fourbar_node --ros-args --params-file`` reads and
applies the same rules the node applies to its parameters (at startup and on every run-time
change): rclpy's type and range checks from ``fourbar_ros.params`` plus the cross-parameter
checks in ``config_from_values`` (the linkage assembles over the whole tilt range, no dead point
of the driven rocker inside it, enumerations, distinct joint names).
Units: metres, radians, N m, kg, seconds.
"""

from __future__ import annotations

import math
import re
import sys
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from fourbar_ros.antenna import AntennaLinkage, Branch, Driven
from fourbar_ros.errors import FourBarError
from fourbar_ros.params import (
    PARAMETERS,
    PARAMETERS_BY_NAME,
    RANGE_REL_TOL,
    ParamSpec,
    ParamValue,
    is_foreign,
)

#: Node name the loader looks for besides the ``/**`` wildcard section.
NODE_NAME = 'fourbar_node'

#: Samples (plus both ends) used to check that the driven rocker has no dead point in the range.
_RANGE_SAMPLES = 512


class ConfigError(FourBarError):
    """Invalid parameter file or parameter values; the message is one line naming the parameter."""


@dataclass(frozen=True)
class AntennaConfig:
    """A validated configuration (build it with ``config_from_values`` or ``load_config``).

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
    reducer_efficiency: float
    motor_torque_limit: float
    output_torque_limit: float
    joint_names: tuple[str, str]
    frame_id: str
    out_of_limits: str
    transmission_angle_min: float
    velocity_timeout: float
    marker_period: float
    diagnostics_period: float
    linkage: AntennaLinkage = field(compare=False, repr=False)

    @property
    def has_gravity_load(self) -> bool:
        """True when the antenna weight adds an angle-dependent load."""
        return self.antenna_mass > 0.0 and self.gravity > 0.0

    def as_values(self) -> dict[str, ParamValue]:
        """Parameter name -> value (the inverse of ``config_from_values``)."""
        return {
            'frame_length': self.frame_length,
            'rocker_ab_length': self.rocker_ab_length,
            'coupler_length': self.coupler_length,
            'rocker_cd_length': self.rocker_cd_length,
            'theta_min': self.theta_min,
            'theta_max': self.theta_max,
            'driven_rocker': self.driven.value,
            'branch': self.branch.name.lower(),
            'load_torque': self.load_torque,
            'antenna_mass': self.antenna_mass,
            'com_offset_along': self.com_offset_along,
            'com_offset_normal': self.com_offset_normal,
            'gravity': self.gravity,
            'reducer_ratio': self.reducer_ratio,
            'reducer_efficiency': self.reducer_efficiency,
            'motor_torque_limit': self.motor_torque_limit,
            'output_torque_limit': self.output_torque_limit,
            'gamma_joint': self.joint_names[0],
            'delta_joint': self.joint_names[1],
            'frame_id': self.frame_id,
            'out_of_limits': self.out_of_limits,
            'transmission_angle_min': self.transmission_angle_min,
            'velocity_timeout': self.velocity_timeout,
            'marker_period': self.marker_period,
            'diagnostics_period': self.diagnostics_period,
        }


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


def check_value(spec: ParamSpec, value: object) -> ParamValue:
    """Check one value against its spec (type as rclpy enforces it, range, choices); return it.

    Raises ``ConfigError`` (``"<name>: <why>"``). Like rclpy, an integer is not a double:
    write ``500.0``, not ``500``.
    """
    name = spec.name
    if spec.type is float:
        if isinstance(value, bool) or not isinstance(value, float):
            hint = f' (write {value}.0)' if isinstance(value, int) and not isinstance(value, bool) else ''
            raise ConfigError(f'{name}: expected a double{hint}, got {_type_name(value)} {value!r}')
        if not math.isfinite(value):
            raise ConfigError(f'{name}: must be finite, got {value!r}')
        lo, hi = spec.minimum, spec.maximum
        if lo is not None and value < lo and not math.isclose(value, lo, rel_tol=RANGE_REL_TOL):
            raise ConfigError(f'{name}: {value!r} {spec.unit} is below the minimum {lo!r}'.replace('  ', ' '))
        if hi is not None and value > hi and not math.isclose(value, hi, rel_tol=RANGE_REL_TOL):
            raise ConfigError(f'{name}: {value!r} {spec.unit} is above the maximum {hi!r}'.replace('  ', ' '))
        return value
    if spec.type is str:
        if not isinstance(value, str):
            raise ConfigError(f'{name}: expected a string, got {_type_name(value)} {value!r}')
        if spec.choices and value not in spec.choices:
            raise ConfigError(f"{name}: {value!r} is not one of {', '.join(spec.choices)}")
        if not value.strip():
            raise ConfigError(f'{name}: must not be empty')
        return value
    raise ConfigError(f'{name}: unsupported parameter type {spec.type.__name__}')  # pragma: no cover


def _deg(angle: float) -> str:
    return f'{angle:.6g} rad ({math.degrees(angle):.4g} deg)'


def _check_tilt_range(linkage: AntennaLinkage, theta_min: float, theta_max: float,
                      driven: Driven, branch: Branch) -> None:
    """Raise ConfigError unless the linkage assembles on ``branch`` over [theta_min, theta_max]
    and the driven rocker has no dead point (d q/d theta = 0) inside it."""
    if not theta_min < theta_max:
        raise ConfigError(f'theta_min: {_deg(theta_min)} must be below theta_max {_deg(theta_max)}')
    reach = linkage.reach()
    for name, theta in (('theta_min', theta_min), ('theta_max', theta_max)):
        if not reach.contains(theta):
            raise ConfigError(
                f'{name}: {_deg(theta)} is out of the linkage reach {reach.describe()}')
    if reach.theta_gap > 0.0 and theta_min < reach.theta_gap and theta_max > -reach.theta_gap:
        raise ConfigError(
            f'theta_min: [{_deg(theta_min)}, {_deg(theta_max)}] crosses the unreachable band '
            f'|theta| < {_deg(reach.theta_gap)}')
    samples = [theta_min + (theta_max - theta_min) * i / _RANGE_SAMPLES
               for i in range(_RANGE_SAMPLES + 1)]
    sign = 0.0
    for theta in samples:
        try:
            advantage = linkage.mechanical_advantage(theta, driven=driven, branch=branch)
        except FourBarError as exc:
            raise ConfigError(
                f'theta_min: the linkage does not assemble at theta = {_deg(theta)} '
                f'inside [theta_min, theta_max]: {exc}') from None
        if not math.isfinite(advantage) or advantage == 0.0 or (sign and advantage * sign < 0.0):
            raise ConfigError(
                f'driven_rocker: {driven.name.lower()} has a dead point near theta = {_deg(theta)} '
                'inside [theta_min, theta_max] (unbounded input torque)')
        sign = math.copysign(1.0, advantage)


def config_from_values(values: Mapping[str, object]) -> AntennaConfig:
    """Validate a complete or partial name->value map (missing names take their defaults).

    Unknown names raise ``ConfigError`` (rclpy's own ``use_sim_time``/``qos_overrides.*`` are ignored).
    """
    for name in values:
        if name not in PARAMETERS_BY_NAME and not is_foreign(name):
            raise ConfigError(f'{name}: unknown parameter (known: {", ".join(PARAMETERS_BY_NAME)})')
    v: dict[str, Any] = {}
    for spec in PARAMETERS:
        v[spec.name] = check_value(spec, values.get(spec.name, spec.default))
    driven = Driven(v['driven_rocker'])
    branch = Branch[v['branch'].upper()]
    try:
        linkage = AntennaLinkage(frame=v['frame_length'], rocker_ab=v['rocker_ab_length'],
                                 coupler=v['coupler_length'], rocker_cd=v['rocker_cd_length'])
    except FourBarError as exc:
        raise ConfigError(f'frame_length: the lengths do not form a linkage: {exc}') from None
    _check_tilt_range(linkage, v['theta_min'], v['theta_max'], driven, branch)
    if v['gamma_joint'] == v['delta_joint']:
        raise ConfigError(f"delta_joint: {v['delta_joint']!r} is also gamma_joint; names must differ")
    return AntennaConfig(
        frame_length=v['frame_length'], rocker_ab_length=v['rocker_ab_length'],
        coupler_length=v['coupler_length'], rocker_cd_length=v['rocker_cd_length'],
        theta_min=v['theta_min'], theta_max=v['theta_max'], driven=driven, branch=branch,
        load_torque=v['load_torque'], antenna_mass=v['antenna_mass'],
        com_offset_along=v['com_offset_along'], com_offset_normal=v['com_offset_normal'],
        gravity=v['gravity'], reducer_ratio=v['reducer_ratio'],
        reducer_efficiency=v['reducer_efficiency'], motor_torque_limit=v['motor_torque_limit'],
        output_torque_limit=v['output_torque_limit'],
        joint_names=(v['gamma_joint'], v['delta_joint']), frame_id=v['frame_id'],
        out_of_limits=v['out_of_limits'], transmission_angle_min=v['transmission_angle_min'],
        velocity_timeout=v['velocity_timeout'], marker_period=v['marker_period'],
        diagnostics_period=v['diagnostics_period'], linkage=linkage)


def default_config() -> AntennaConfig:
    """The configuration with every parameter at its default (Turnantenna)."""
    return config_from_values({})


_TRUE = frozenset({'Y', 'y', 'yes', 'Yes', 'YES', 'true', 'True', 'TRUE', 'on', 'On', 'ON'})
_FALSE = frozenset({'N', 'n', 'no', 'No', 'NO', 'false', 'False', 'FALSE', 'off', 'Off', 'OFF'})
_INT_RE = re.compile(r'\s*([+-]?)(0[xX][0-9a-fA-F]+|0[0-7]*|[1-9][0-9]*)')
_DEC_RE = re.compile(r'\s*[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?')
_HEX_RE = re.compile(r'\s*[+-]?0[xX]([0-9a-fA-F]+\.?[0-9a-fA-F]*|\.[0-9a-fA-F]+)([pP][+-]?\d+)?')
_SPECIAL_RE = re.compile(r'\s*[+-]?(inf|infinity|nan(\([0-9A-Za-z_]*\))?)', re.IGNORECASE)
_YAML_SPECIAL = {'.nan': math.nan, '.NaN': math.nan, '.NAN': math.nan}
_YAML_SPECIAL.update({f'{sign}.{inf}': (-math.inf if sign == '-' else math.inf)
                      for sign in ('', '+', '-') for inf in ('inf', 'Inf', 'INF')})


def _nonzero_mantissa(text: str) -> bool:
    """True if a decimal or hex float literal has a non-zero digit before its exponent."""
    body = text.strip().lstrip('+-')
    if body[:2] in ('0x', '0X'):
        return any(c in '123456789abcdefABCDEF' for c in re.split('[pP]', body[2:])[0])
    return any(c in '123456789' for c in re.split('[eE]', body)[0])


def rcl_scalar(text: str, quoted: bool) -> bool | int | float | str:
    """The value rcl's YAML parameter parser gives a scalar (``get_value`` in rcl_yaml_param_parser).

    Quoted scalars are strings. Plain ones are tried as a bool word (true/yes/on/y ...), a C ``strtol``
    integer (base prefix 0x or 0 for octal), a C ``strtod`` double (also 1e-3, inf, nan, hex floats,
    .nan/.inf), else a string. This differs from PyYAML's YAML 1.1 rules (``1e-3`` and ``1_000``).
    """
    if quoted:
        return text
    if text in _TRUE:
        return True
    if text in _FALSE:
        return False
    m = _INT_RE.fullmatch(text)
    if m:
        digits = m.group(2)
        if digits[:2] in ('0x', '0X'):
            value = int(digits, 16)
        elif len(digits) > 1 and digits[0] == '0':
            value = int(digits, 8)
        else:
            value = int(digits)
        value = -value if m.group(1) == '-' else value
        if -(2**63) <= value < 2**63:  # otherwise strtol sets ERANGE and rcl tries a double
            return value
    if text in _YAML_SPECIAL:
        return _YAML_SPECIAL[text]
    if _DEC_RE.fullmatch(text) or _SPECIAL_RE.fullmatch(text):
        number = float(text.strip())
    elif _HEX_RE.fullmatch(text):
        stripped = text.strip()
        sign = -1.0 if stripped.startswith('-') else 1.0
        body = stripped.lstrip('+-')
        number = sign * float.fromhex(body if 'p' in body.lower() else body + 'p0')
    else:
        return text
    if not _SPECIAL_RE.fullmatch(text) and (
            math.isinf(number) or (abs(number) < sys.float_info.min and (number != 0.0 or _nonzero_mantissa(text)))):
        return text  # strtod overflow or underflow (also to a subnormal): ERANGE, so rcl keeps the string
    return number


def _plain_values(node: Any, source: str) -> Any:
    """Convert a composed PyYAML node tree to Python values with rcl's scalar rules."""
    import yaml

    if isinstance(node, yaml.MappingNode):
        out: dict[str, Any] = {}
        for key_node, value_node in node.value:
            out[str(key_node.value)] = _plain_values(value_node, source)
        return out
    if isinstance(node, yaml.SequenceNode):
        return [_plain_values(item, source) for item in node.value]
    if node.style not in ("'", '"') and node.value == '':
        raise ConfigError(f'{source}: no value at line {node.start_mark.line + 1}')
    return rcl_scalar(node.value, quoted=node.style in ("'", '"'))


def _flatten(prefix: str, mapping: Mapping[str, Any], out: dict[str, object]) -> None:
    """rcl's nesting rule: ``a: {b: 1}`` under ros__parameters is the parameter ``a.b``."""
    for key, value in mapping.items():
        name = f'{prefix}{key}'
        if isinstance(value, dict):
            _flatten(name + '.', value, out)
        else:
            out[name] = value


def _matches_node(key: str, fqn: str) -> bool:
    """rcl's rule: does section ``key`` (``/**``, ``/ns/name``, ``name`` = ``/name``, ``/*/name``,
    ``/**/name``) apply to the node with fully qualified name ``fqn``? ``*`` is one namespace level,
    ``**`` any number of them."""
    pattern = [t for t in ('/' + key.strip().lstrip('/')).split('/') if t]
    target = [t for t in fqn.split('/') if t]

    def match(p: list[str], t: list[str]) -> bool:
        if not p:
            return not t
        if p[0] == '**':
            return any(match(p[1:], t[i:]) for i in range(len(t) + 1))
        return bool(t) and (p[0] == '*' or p[0] == t[0]) and match(p[1:], t[1:])

    return match(pattern, target)


def _node_sections(doc: Mapping[str, Any], prefix: str = '') -> Iterator[tuple[str, Any]]:
    """(node key, section) in file order; nested mappings without ros__parameters are namespace levels."""
    for key, section in doc.items():
        name = f'{prefix}/{key.strip("/")}' if prefix else key
        if isinstance(section, dict) and 'ros__parameters' not in section and all(
                isinstance(v, dict) for v in section.values()) and section:
            yield from _node_sections(section, name)
        else:
            yield name, section


def values_from_yaml(text: str, source: str = '<string>', node_name: str = NODE_NAME,
                     namespace: str = '/') -> dict[str, object]:
    """The parameter values the node ``namespace``/``node_name`` receives from a ROS 2 parameter file.

    Scalars are typed as rcl types them (see ``rcl_scalar``); the sections that apply to the node
    (``/**``, its name, wildcards) are merged in file order, a later one overriding an earlier one.
    """
    import yaml  # PyYAML, only for its parser; imported here to keep `import fourbar_ros.config` light

    try:
        root = yaml.compose(text, Loader=yaml.SafeLoader)
    except yaml.YAMLError as exc:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else 'syntax error'
        raise ConfigError(f'{source}: not valid YAML: {first}') from None
    doc = _plain_values(root, source) if root is not None else None
    if not isinstance(doc, dict):
        raise ConfigError(f"{source}: expected a mapping with a '/**:' or '{node_name}:' section")
    fqn = f"{namespace.rstrip('/')}/{node_name}"
    values: dict[str, object] = {}
    found = False
    for key, section in _node_sections(doc):
        if not _matches_node(key, fqn):
            continue
        if not isinstance(section, dict) or not isinstance(section.get('ros__parameters'), dict):
            raise ConfigError(f"{source}: section {key!r} has no 'ros__parameters:' mapping")
        found = True
        _flatten('', section['ros__parameters'], values)
    if not found:
        raise ConfigError(f"{source}: no '/**:' or '{fqn}' section with 'ros__parameters:'")
    return values


def load_config(path: str | Path, node_name: str = NODE_NAME, namespace: str = '/') -> AntennaConfig:
    """Read and validate a ROS 2 parameter file (``/**:`` or ``<node_name>:`` -> ``ros__parameters:``)
    as the node ``namespace``/``node_name`` would receive it.

    Raises ``ConfigError`` with a one-line message naming the parameter (or the file) and why.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding='utf-8')
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f'{path}: cannot read: {exc.__class__.__name__}: {exc}'.splitlines()[0]) from None
    values = values_from_yaml(text, str(path), node_name, namespace)
    try:
        return config_from_values(values)
    except ConfigError as exc:
        raise ConfigError(f'{path}: {exc}') from None
