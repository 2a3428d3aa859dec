"""Numeric conventions shared by the core's solvers: array and scalar types, invalid input, tolerances, lengths."""

from __future__ import annotations

import math
import numbers
from typing import Any, Literal, cast

import numpy as np
import numpy.typing as npt

from fourbar_ros.core.errors import InvalidGeometryError

FloatArray = npt.NDArray[np.float64]
#: A Python float (the math-module fast paths) or a float64 array (the vectorized paths); radians or metres.
ArrayLike = float | FloatArray
#: A real scalar: a Python int or float, a numpy integer or floating scalar of any width, or a 0-d array of one.
RealScalar = float | int | np.integer[Any] | np.floating[Any]
#: What the core's entry points take: a real scalar (computed as the Python float of its value) or an array.
RealLike = RealScalar | npt.NDArray[Any]
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


def real(x: RealLike) -> ArrayLike:
    """``x`` as the core computes with it: a real scalar of any type (Python int or float, numpy integer or
    floating scalar of any width, 0-d array of one) as the Python float ``float(x)``, so it takes the math-module
    path and gives bit for bit the results of that float; an array (ndim >= 1, or anything not a scalar) unchanged.

    Raises TypeError for a bool or a complex scalar (not an angle or a length). The entry points call it first;
    a Python float returns at once (the scalar hot path)."""
    if type(x) is float:
        return x
    return _real_other(x)


def _real_other(x: object) -> ArrayLike:
    """real() for everything but a Python float."""
    if type(x) is int:
        return float(x)
    if isinstance(x, np.ndarray):
        if x.ndim:
            return x
        x = x.item() if x.dtype.kind == 'O' else x[()]  # the 0-d array's scalar
    if isinstance(x, (bool, np.bool_)):
        raise TypeError(f'{x!r} is a bool, not a real number')
    if isinstance(x, numbers.Real):  # numpy registers its integer and floating scalars here
        return float(x)
    if isinstance(x, (numbers.Number, np.generic)):
        raise TypeError(f'{x!r} is not a real number')
    return cast('FloatArray', x)  # a sequence or another array-like: numpy's business, as for arrays
