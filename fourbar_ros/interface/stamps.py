"""Stamps and durations on the wire: ``builtin_interfaces`` (sec, nanosec) and int nanoseconds, both ways."""

from __future__ import annotations

from typing import Protocol, overload

import numpy as np
import numpy.typing as npt

#: Nanoseconds in a second.
NS_PER_S = 1_000_000_000
_INT32_MAX = 2**31 - 1


class StampLike(Protocol):
    """``builtin_interfaces/msg/Time`` or ``Duration``: whole seconds and nanoseconds."""

    @property
    def sec(self) -> int: ...

    @property
    def nanosec(self) -> int: ...


def to_ns(stamp: StampLike) -> int:
    """Nanoseconds of a Time or Duration message (``sec * 1e9 + nanosec``, exact)."""
    return int(stamp.sec) * NS_PER_S + int(stamp.nanosec)


def from_ns(ns: int) -> tuple[int, int]:
    """(sec, nanosec) of nanoseconds, as rclpy's ``Time.to_msg`` splits them (nanosec in [0, 1e9))."""
    sec, nanosec = divmod(int(ns), NS_PER_S)
    return sec, nanosec


@overload
def seconds_to_ns(t: float) -> int: ...
@overload
def seconds_to_ns(t: npt.NDArray[np.float64]) -> npt.NDArray[np.int64]: ...
def seconds_to_ns(t: float | npt.NDArray[np.float64]) -> int | npt.NDArray[np.int64]:
    """Seconds to the nearest nanosecond (elementwise on an array)."""
    if isinstance(t, np.ndarray):
        return np.round(t * NS_PER_S).astype(np.int64)
    return round(t * NS_PER_S)


@overload
def ns_to_seconds(ns: int) -> float: ...
@overload
def ns_to_seconds(ns: npt.NDArray[np.int64]) -> npt.NDArray[np.float64]: ...
def ns_to_seconds(ns: int | npt.NDArray[np.int64]) -> float | npt.NDArray[np.float64]:
    """Nanoseconds to seconds (elementwise on an array)."""
    return ns * 1e-9  # type: ignore[return-value]  # numpy types the product floating[Any]


def split_ns(stamps_ns: npt.NDArray[np.int64]) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64]]:
    """(sec, nanosec) arrays of nanosecond stamps, as ``from_ns`` per element.

    Raises ValueError for a stamp whose seconds do not fit the message's int32.
    """
    sec, nanosec = np.divmod(np.asarray(stamps_ns, dtype=np.int64), NS_PER_S)
    if sec.size and (sec.min() < -_INT32_MAX - 1 or sec.max() > _INT32_MAX):
        raise ValueError('a stamp does not fit builtin_interfaces/Time (int32 seconds)')
    return sec, nanosec


def join_ns(sec: npt.NDArray[np.integer], nanosec: npt.NDArray[np.integer]) -> npt.NDArray[np.int64]:
    """Nanosecond stamps of (sec, nanosec) arrays, as ``to_ns`` per element."""
    return np.asarray(sec, dtype=np.int64) * NS_PER_S + np.asarray(nanosec, dtype=np.int64)
