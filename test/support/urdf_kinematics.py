"""Forward kinematics read from URDF text alone (XML origins, rpy, axes; numpy rotation matrices): it shares no code
with the core, so a wrong axis, sign or zero angle in the robot model shows up as a loop that does not close."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import numpy as np
import numpy.typing as npt

Matrix = npt.NDArray[np.float64]


def _rpy(roll: float, pitch: float, yaw: float) -> Matrix:
    """URDF's fixed-axis roll, pitch, yaw: R = Rz(yaw) Ry(pitch) Rx(roll)."""
    cr, sr, cp, sp, cy, sy = (math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch),
                              math.cos(yaw), math.sin(yaw))
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]], dtype=np.float64)
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]], dtype=np.float64)
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]], dtype=np.float64)
    out: Matrix = rz @ ry @ rx
    return out


def _axis_angle(axis: Matrix, angle: float) -> Matrix:
    """Rotation by ``angle`` about the unit vector ``axis`` (Rodrigues)."""
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]], dtype=np.float64)
    out: Matrix = np.eye(3) + math.sin(angle) * k + (1.0 - math.cos(angle)) * (k @ k)
    return out


def _homogeneous(rotation: Matrix, translation: Matrix) -> Matrix:
    m = np.eye(4)
    m[:3, :3] = rotation
    m[:3, 3] = translation
    return m


def vector(text: str | None, default: str = '0 0 0') -> Matrix:
    """A URDF attribute's space-separated numbers (``default`` when absent)."""
    return np.array([float(v) for v in (text or default).split()], dtype=np.float64)


def link_poses(urdf: str, positions: dict[str, float]) -> dict[str, Matrix]:
    """Pose (4x4, in the root link's frame) of every link for the given revolute joint positions (rad)."""
    robot = ET.fromstring(urdf)
    links = [link.attrib['name'] for link in robot.findall('link')]
    joints = {j.find('child').attrib['link']: j for j in robot.findall('joint')}  # type: ignore[union-attr]
    roots = [name for name in links if name not in joints]
    assert len(roots) == 1, roots
    poses: dict[str, Matrix] = {roots[0]: np.eye(4)}

    def pose(link: str) -> Matrix:
        if link not in poses:
            joint = joints[link]
            parent = joint.find('parent').attrib['link']  # type: ignore[union-attr]
            origin = joint.find('origin')
            xyz = vector(None if origin is None else origin.attrib.get('xyz'))
            rpy = vector(None if origin is None else origin.attrib.get('rpy'))
            m = pose(parent) @ _homogeneous(_rpy(*rpy), xyz)
            kind = joint.attrib['type']
            if kind == 'revolute':
                axis = vector(joint.find('axis').attrib['xyz'])  # type: ignore[union-attr]
                m = m @ _homogeneous(_axis_angle(axis / np.linalg.norm(axis), positions[joint.attrib['name']]),
                                     np.zeros(3))
            else:
                assert kind == 'fixed', kind
            poses[link] = m
        return poses[link]

    for name in links:
        pose(name)
    return poses
