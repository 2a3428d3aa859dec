"""visualization_msgs/MarkerArray of the linkage: frame, rockers, coupler, joints and the antenna arrow."""

from __future__ import annotations

from builtin_interfaces.msg import Time
from geometry_msgs.msg import Point, Vector3
from std_msgs.msg import ColorRGBA
from visualization_msgs.msg import Marker, MarkerArray

from fourbar_ros.rules.marker_geometry import LinkagePoints

NAMESPACE = 'fourbar'
_LINE_WIDTH = 0.004  # m
_JOINT_DIAMETER = 0.008  # m


def _marker(marker_id: int, kind: int, frame_id: str, color: tuple[float, float, float],
            scale: tuple[float, float, float], npoints: int) -> Marker:
    m = Marker()
    m.header.frame_id = frame_id
    m.ns = NAMESPACE
    m.id = marker_id
    m.type = kind
    m.action = Marker.ADD
    m.pose.orientation.w = 1.0
    m.scale = Vector3(x=scale[0], y=scale[1], z=scale[2])
    m.color = ColorRGBA(r=color[0], g=color[1], b=color[2], a=1.0)
    m.points = [Point() for _ in range(npoints)]
    return m


class LinkageMarkers:
    """A reusable MarkerArray: ``update`` moves its points and stamps; publish the ``array``."""

    def __init__(self, frame_id: str) -> None:
        self.frame = _marker(0, Marker.LINE_STRIP, frame_id, (0.5, 0.5, 0.5), (_LINE_WIDTH, 0.0, 0.0), 2)
        self.rockers = _marker(1, Marker.LINE_LIST, frame_id, (0.1, 0.4, 0.9), (_LINE_WIDTH, 0.0, 0.0), 4)
        self.coupler = _marker(2, Marker.LINE_STRIP, frame_id, (0.9, 0.5, 0.1), (_LINE_WIDTH, 0.0, 0.0), 2)
        self.joints = _marker(3, Marker.SPHERE_LIST, frame_id, (0.2, 0.2, 0.2),
                              (_JOINT_DIAMETER,) * 3, 4)
        self.antenna = _marker(4, Marker.ARROW, frame_id, (0.8, 0.1, 0.1),
                               (_LINE_WIDTH, 2 * _LINE_WIDTH, 3 * _LINE_WIDTH), 2)
        self.array = MarkerArray(markers=[self.frame, self.rockers, self.coupler, self.joints, self.antenna])

    def update(self, pts: LinkagePoints, stamp: Time) -> MarkerArray:
        """Set every marker's points and stamp; return the array. The drawing's (along A->D, up) metres go to
        (x, z), y = 0: the linkage in the x-z plane of ``frame_id``, z up (REP-103), as in `fourbar urdf`'s model."""
        for marker, seq in ((self.frame, (pts.a, pts.d)), (self.rockers, (pts.a, pts.b, pts.d, pts.c)),
                            (self.coupler, (pts.b, pts.c)), (self.joints, (pts.a, pts.b, pts.c, pts.d)),
                            (self.antenna, (pts.antenna_tail, pts.antenna_tip))):
            marker.header.stamp = stamp
            for point, (x, up) in zip(marker.points, seq, strict=True):
                point.x = x
                point.z = up
        return self.array
