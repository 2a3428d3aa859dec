"""fourbar_ros: kinematics and statics of a four-bar antenna tilt linkage, with ROS 2 glue.

The package root imports only the pure core (standard library and numpy); the rclpy node lives in
fourbar_ros.node.fourbar_node and is imported only when used.
"""

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
