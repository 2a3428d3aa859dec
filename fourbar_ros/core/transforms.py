"""Forward kinematics by planar homogeneous transformation matrices, as in the lecture notes.

Joints and the loop-closure residual (m) for floats or broadcast arrays: the independent check of every closed form."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from fourbar_ros.core.numeric import ArrayLike as AngleLike
from fourbar_ros.core.numeric import FloatArray

_ORIGIN = np.array([0.0, 0.0, 1.0])


def rot(alpha: AngleLike) -> FloatArray:
    """R(alpha): rotation by alpha (radians, counter-clockwise), shape (..., 3, 3)."""
    a = np.asarray(alpha, dtype=np.float64)
    m = np.zeros((*a.shape, 3, 3))
    c, s = np.cos(a), np.sin(a)
    m[..., 0, 0], m[..., 0, 1], m[..., 1, 0], m[..., 1, 1], m[..., 2, 2] = c, -s, s, c, 1.0
    return m


def trans(length: AngleLike) -> FloatArray:
    """T(l, 0): translation by l (metres) along the current x axis, shape (..., 3, 3)."""
    x = np.asarray(length, dtype=np.float64)
    m = np.zeros((*x.shape, 3, 3))
    m[..., 0, 0] = m[..., 1, 1] = m[..., 2, 2] = 1.0
    m[..., 0, 2] = x
    return m


def chain(*matrices: FloatArray) -> FloatArray:
    """The product of a chain of transforms, applied to the origin: the chain's end point, shape (..., 2)."""
    out = matrices[0]
    for m in matrices[1:]:
        out = out @ m
    end: FloatArray = (out @ _ORIGIN)[..., :2]
    return end


class JointPositions(NamedTuple):
    """Positions (metres, shape (..., 2)) of the four joints, and the loop-closure residual (metres).

    For the antenna the joints are A, B, C, D; for the general four-bar O2, B, C, O4. C is reached from the
    first ground pivot; residual is its distance from C reached from the other pivot.
    """

    a: FloatArray
    b: FloatArray
    c: FloatArray
    d: FloatArray
    residual: FloatArray


def antenna_joint_positions(frame: float, rocker_ab: float, coupler: float, rocker_cd: float,
                            theta: AngleLike, gamma: AngleLike, delta: AngleLike) -> JointPositions:
    """Joints A, B, C, D of the antenna linkage (Annex A convention) from theta, gamma, delta (radians).

    Left chain A -> B -> C: R(gamma) T(AB) R(-theta - gamma) T(h); right chain D -> C: T(H) R(pi - delta) T(CD).
    """
    th, g, d = np.broadcast_arrays(*(np.asarray(v, dtype=np.float64) for v in (theta, gamma, delta)))
    to_b = rot(g) @ trans(rocker_ab)
    c_left = chain(to_b, rot(-th - g), trans(coupler))
    c_right = chain(trans(frame), rot(np.pi - d), trans(rocker_cd))
    zero = np.zeros((*th.shape, 2))
    return JointPositions(zero, chain(to_b), c_left, chain(trans(frame)) + zero, _distance(c_left, c_right))


def fourbar_joint_positions(ground: float, crank: float, coupler: float, rocker: float,
                            t2: AngleLike, t3: AngleLike, t4: AngleLike) -> JointPositions:
    """Joints O2, B, C, O4 of the general four-bar from absolute angles t2, t3, t4 (radians).

    Left chain O2 -> B -> C: R(t2) T(l2) R(t3 - t2) T(l3); right chain O4 -> C: T(l1) R(t4) T(l4).
    """
    a2, a3, a4 = np.broadcast_arrays(*(np.asarray(v, dtype=np.float64) for v in (t2, t3, t4)))
    to_b = rot(a2) @ trans(crank)
    c_left = chain(to_b, rot(a3 - a2), trans(coupler))
    c_right = chain(trans(ground), rot(a4), trans(rocker))
    zero = np.zeros((*a2.shape, 2))
    return JointPositions(zero, chain(to_b), c_left, chain(trans(ground)) + zero, _distance(c_left, c_right))


def _distance(p: FloatArray, q: FloatArray) -> FloatArray:
    diff = p - q
    return np.asarray(np.hypot(diff[..., 0], diff[..., 1]))
