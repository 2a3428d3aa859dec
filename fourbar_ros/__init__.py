"""Kinematics and statics of a four-bar antenna tilt linkage, with ROS 2 glue; the root imports the pure core only."""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from fourbar_ros.core.antenna import (
        AntennaLinkage,
        Branch,
        Driven,
        InverseSolution,
        LinkageState,
        Reach,
        RockerAngles,
        RockerRates,
    )
    from fourbar_ros.core.errors import (
        DeadPointError,
        FourBarError,
        InvalidGeometryError,
        SingularPositionError,
        UnreachableError,
    )
    from fourbar_ros.core.general import FourBar, FourBarAngles

# The names load on first use: the node's console script imports fourbar_ros.node, and a root importing numpy
# first would delay its stop handlers by that import (docs/explanation/node.md, "Stopping").
#: The module of each name of the root.
_SOURCES = {
    **dict.fromkeys(('AntennaLinkage', 'Branch', 'Driven', 'InverseSolution', 'LinkageState', 'Reach',
                     'RockerAngles', 'RockerRates'), 'fourbar_ros.core.antenna'),
    **dict.fromkeys(('DeadPointError', 'FourBarError', 'InvalidGeometryError', 'SingularPositionError',
                     'UnreachableError'), 'fourbar_ros.core.errors'),
    **dict.fromkeys(('FourBar', 'FourBarAngles'), 'fourbar_ros.core.general'),
}

__all__ = [
    'AntennaLinkage', 'Branch', 'DeadPointError', 'Driven', 'FourBar', 'FourBarAngles', 'FourBarError',
    'InvalidGeometryError', 'InverseSolution', 'LinkageState', 'Reach', 'RockerAngles', 'RockerRates',
    'SingularPositionError',
    'UnreachableError',
]


def __getattr__(name: str) -> Any:
    source = _SOURCES.get(name)
    if source is None:
        raise AttributeError(f'module {__name__!r} has no attribute {name!r}')
    value = getattr(importlib.import_module(source), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted([*globals(), *__all__])
