"""Kinematics and statics of a four-bar antenna tilt linkage, with ROS 2 glue; the root imports the pure core only."""

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

__all__ = [
    'AntennaLinkage', 'Branch', 'DeadPointError', 'Driven', 'FourBar', 'FourBarAngles', 'FourBarError',
    'InvalidGeometryError', 'InverseSolution', 'LinkageState', 'Reach', 'RockerAngles', 'RockerRates',
    'SingularPositionError',
    'UnreachableError',
]
