"""Numeric conventions shared by the core's solvers: array types, invalid input, dead-point tolerance, lengths."""

from __future__ import annotations

import math
from typing import Literal

import numpy as np
import numpy.typing as npt

from fourbar_ros.core.errors import InvalidGeometryError

FloatArray = npt.NDArray[np.float64]
#: A Python float (the math-module fast paths) or a float64 array (the vectorized paths); radians or metres.
ArrayLike = float | FloatArray
#: What a vectorized solve does with an element it cannot solve: raise, or return NaN there.
OnInvalid = Literal['raise', 'nan']

#: A sine (of an angle sum, dimensionless) within this many ulps per radian of its angles counts as zero: the
#: dead-point test of the statics (multiply by 1 + the angles' magnitudes, in rad).
DEAD_TOL = 4.0 * math.ulp(1.0)


def check_length(name: str, value: float) -> float:
    """``value`` as a float if it is a finite positive number (a link length in metres); else InvalidGeometryError
    naming ``name``."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InvalidGeometryError(f'{name}={value!r} must be a number (metres)')
    v = float(value)
    if not (math.isfinite(v) and v > 0.0):
        raise InvalidGeometryError(f'{name}={v!r} m must be finite and positive')
    return v
