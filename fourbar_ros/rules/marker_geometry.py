"""Points of the linkage drawing (frame, rockers, coupler, antenna) in the marker frame. No ROS.

Plane coordinates (along A->D, up) in metres from pivot A, put in the x-z plane of ``frame_id``; the antenna an
arrow from the coupler's midpoint along B->C, one coupler length long (docs/reference/topics.md)."""

from __future__ import annotations

import math
from typing import NamedTuple

Point = tuple[float, float]


class LinkagePoints(NamedTuple):
    """Joint positions A, B, C, D and the antenna arrow's tail and tip (x, y in metres)."""

    a: Point
    b: Point
    c: Point
    d: Point
    antenna_tail: Point
    antenna_tip: Point


def linkage_points(frame: float, rocker_ab: float, coupler: float, rocker_cd: float,
                   theta: float, gamma: float, delta: float) -> LinkagePoints:
    """Points from the link lengths (m) and the solved angles (rad). C is placed from D, so the
    coupler drawn is the real B->C (its length checks the solve)."""
    b = (rocker_ab * math.cos(gamma), rocker_ab * math.sin(gamma))
    c = (frame - rocker_cd * math.cos(delta), rocker_cd * math.sin(delta))
    tail = (0.5 * (b[0] + c[0]), 0.5 * (b[1] + c[1]))
    tip = (tail[0] + coupler * math.cos(theta), tail[1] - coupler * math.sin(theta))
    return LinkagePoints((0.0, 0.0), b, c, (frame, 0.0), tail, tip)
