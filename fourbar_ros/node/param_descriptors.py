"""ROS parameter descriptors built from ``fourbar_ros.config.params.PARAMETERS`` (declaration only)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, ParameterType
from rclpy.parameter import Parameter

from fourbar_ros.config.params import PARAMETERS, ParamSpec, ParamValue

_TYPES = {float: ParameterType.PARAMETER_DOUBLE, str: ParameterType.PARAMETER_STRING,
          int: ParameterType.PARAMETER_INTEGER, bool: ParameterType.PARAMETER_BOOL,
          list: ParameterType.PARAMETER_STRING_ARRAY}


def descriptor(spec: ParamSpec) -> ParameterDescriptor:
    """The descriptor rclpy enforces (type, inclusive range, read-only) and shows (description, unit)."""
    d = ParameterDescriptor(name=spec.name, type=_TYPES[spec.type], description=spec.describe(),
                            read_only=spec.read_only)
    if spec.type is float and spec.minimum is not None and spec.maximum is not None:
        d.floating_point_range = [FloatingPointRange(from_value=float(spec.minimum),
                                                     to_value=float(spec.maximum), step=0.0)]
    if spec.type is int and spec.minimum is not None and spec.maximum is not None:
        d.integer_range = [IntegerRange(from_value=int(spec.minimum), to_value=int(spec.maximum), step=1)]
    if spec.choices:
        d.additional_constraints = 'one of: ' + ', '.join(spec.choices)
    return d


def declarations(values: dict[str, ParamValue], specs: Sequence[ParamSpec] = PARAMETERS,
                 read_only: bool = False) -> list[tuple[str, Any, Any]]:
    """(name, value, descriptor) for ``Node.declare_parameters('', ...)``, values from a validated config;
    ``read_only``: every one of them (else as its spec says)."""
    out = []
    for spec in specs:
        d = descriptor(spec)
        d.read_only = d.read_only or read_only
        value: Any = values[spec.name]
        if spec.type is list and not value:  # rclpy would take an empty list for a byte array: declare the type
            value = Parameter.Type.STRING_ARRAY
        out.append((spec.name, value, d))
    return out
