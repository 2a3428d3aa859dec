"""A calibration recording read and paired: the measured driven joint and an antenna angle sensor (no rclpy).

Messages are timed by their header stamps (a Float64 by its receive time) and the encoder interpolated at the
sensor's times; a problem of the data raises ``CalibrationError`` (one line). See docs/how-to/calibrate.md."""

from __future__ import annotations

import math
import os
import struct
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from fourbar_ros.bags.storage import FLOAT64, JOINT_STATE, MEASURED, BagError, jazzy_typestore, open_bag
from fourbar_ros.core.calibration import CalibrationError, imu_roll, imu_tilt, imu_valid, imu_yaw
from fourbar_ros.core.errors import one_line
from fourbar_ros.core.numeric import FloatArray
from fourbar_ros.interface.cdr import (
    MalformedCdrError,
    decode_float64s,
    decode_joint_states,
    read_joint_state_arrays,
    read_joint_state_head,
)
from fourbar_ros.interface.topics import IMU

__all__ = ['IMU', 'SENSOR_TYPES', 'CalibrationData', 'imu_tilt', 'pair', 'read_calibration_data']

#: The antenna angle sensors read.
SENSOR_TYPES = (FLOAT64, IMU)
#: The encoder is not interpolated across a gap longer than this many of its median intervals.
GAP_FACTOR = 10.0
_STAMP = struct.Struct('<iI')
_UINT32 = struct.Struct('<I')
_ACCEL = struct.Struct('<3d')
#: Bytes from the (8-aligned) orientation to linear_acceleration in an Imu: orientation (4 doubles), its covariance
#: (9), angular_velocity (3) and its covariance (9).
_ACCEL_AT = 8 * (4 + 9 + 3 + 9)


@dataclass(frozen=True)
class CalibrationData:
    """A recording's streams and their pairs. Times in s from ``t0_ns`` (ns, the first message's time).

    ``q``: the driven joint at the sensor's paired times (rad, interpolated); ``theta``: the sensor's readings there
    (rad); ``joint_times``/``joint_q``/``joint_velocity``/``joint_effort``: the encoder's own stream (rad, rad/s,
    N m; velocity and effort NaN where not measured). ``sensor_invalid`` / ``joint_invalid``: readings dropped
    (non-finite; for an IMU also an acceleration not gravity-sized, ``imu_valid``); ``imu_yaw``: the IMU's yaw about
    its z axis found from the sweep (rad, ``imu_yaw``; NaN for a Float64 sensor or without an arc: the tilt then
    takes 0); ``imu_roll``: its median roll about its x axis (rad, ``imu_roll``; NaN for a Float64 sensor).
    """

    path: Path
    joint_topic: str
    sensor_topic: str
    sensor_type: str
    t0_ns: int
    joint_times: FloatArray
    joint_q: FloatArray
    joint_velocity: FloatArray
    joint_effort: FloatArray
    sensor_times: FloatArray
    sensor_theta: FloatArray
    times: FloatArray
    q: FloatArray
    theta: FloatArray
    sensor_invalid: int = 0
    joint_invalid: int = 0
    imu_roll: float = math.nan
    imu_yaw: float = math.nan

    @property
    def outside(self) -> int:
        """Sensor readings left out: outside the encoder's span or in one of its gaps."""
        return self.sensor_times.size - self.times.size

    @property
    def velocity_measured(self) -> bool:
        """Whether every joint state carries the joint's velocity."""
        return bool(np.isfinite(self.joint_velocity).all())

    def joint_rate(self) -> FloatArray:
        """The driven joint's rate on the encoder's stream (rad/s): its measured velocity where every message
        carries one, else the derivative of its positions."""
        if self.velocity_measured:
            return self.joint_velocity
        rate: FloatArray = np.gradient(self.joint_q, self.joint_times)
        return rate

    def paired_rate(self) -> FloatArray:
        """The driven joint's rate at the paired times (rad/s, ``joint_rate`` interpolated)."""
        rate: FloatArray = np.interp(self.times, self.joint_times, self.joint_rate())
        return rate

    def summary(self) -> str:
        return (f'{self.joint_times.size} joint states on {self.joint_topic}, {self.sensor_times.size} readings '
                f'[{self.sensor_type}] on {self.sensor_topic}: {self.times.size} paired ({self.outside} outside the '
                f'encoder\'s span or its gaps)')


def pair(joint_times: FloatArray, joint_q: FloatArray, sensor_times: FloatArray,
         sensor_theta: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """(times, q, theta): the encoder interpolated linearly at the sensor's times (s) inside its span and not across
    a gap longer than GAP_FACTOR median intervals; raises CalibrationError when no reading falls there."""
    order = np.argsort(joint_times, kind='stable')
    tj, qj = joint_times[order], joint_q[order]
    keep = np.concatenate(([True], np.diff(tj) > 0.0))  # one value per time
    tj, qj = tj[keep], qj[keep]
    ts = sensor_times
    if tj.size < 2 or ts.size == 0 or ts.max() < tj[0] or ts.min() > tj[-1]:
        raise CalibrationError(
            f'the streams do not overlap in time: joint states {_span(tj)}, sensor {_span(ts)} (s from the first '
            'message); record both at once, with their clocks agreeing')
    inside = (ts >= tj[0]) & (ts <= tj[-1])
    dt = np.diff(tj)
    gap = GAP_FACTOR * float(np.median(dt))
    at = np.clip(np.searchsorted(tj, ts, side='right') - 1, 0, tj.size - 2)
    inside &= dt[at] <= gap
    if not inside.any():
        raise CalibrationError(f'no sensor reading falls inside the joint states\' span {_span(tj)} s outside its '
                               'gaps: the streams do not overlap in time')
    t = ts[inside]
    return t, np.interp(t, tj, qj), sensor_theta[inside]


def _span(t: FloatArray) -> str:
    return f'[{float(t.min()):.3f}, {float(t.max()):.3f}]' if t.size else '(no messages)'


def read_calibration_data(path: str | os.PathLike[str], driven_joint: str, angle_topic: str,
                          joint_topic: str | None = None) -> CalibrationData:
    """Read a recording (see the module docstring) and pair its streams. Raises BagError for an unreadable bag and
    CalibrationError (one line) for data that cannot calibrate."""
    with open_bag(path) as bag:
        p, types = bag.path, bag.types
        if angle_topic not in types:
            raise CalibrationError(f'{p}: no sensor topic {angle_topic} ({_topics(types)})')
        sensor_type = types[angle_topic]
        if sensor_type not in SENSOR_TYPES:
            raise CalibrationError(f'{p}: sensor topic {angle_topic} has type {sensor_type}, expected '
                                   f'{" or ".join(SENSOR_TYPES)}')
        try:
            chosen = bag.find(MEASURED, joint_topic)
        except BagError as exc:
            raise CalibrationError(str(exc)) from None
        raws: dict[str, list[bytes]] = {chosen: [], angle_topic: []}
        logs: dict[str, list[int]] = {chosen: [], angle_topic: []}
        # one pass, each message appended to its topic's lists: no per-message tuple, no second pass
        streams = {c.id: (raws[c.topic].append, logs[c.topic].append) for c in bag.connections
                   if c.topic in raws}
        for conn, log, data in bag.messages([chosen, angle_topic]):
            add_raw, add_log = streams[conn.id]
            add_raw(bytes(data))
            add_log(log)
    if not raws[chosen]:
        raise CalibrationError(f'{p}: topic {chosen} has no messages')
    if not raws[angle_topic]:
        raise CalibrationError(f'{p}: topic {angle_topic} has no messages')
    j_ns, q, velocity, effort = _joint_states(p, chosen, raws[chosen], np.array(logs[chosen], dtype=np.int64),
                                              driven_joint)
    s_log = np.array(logs[angle_topic], dtype=np.int64)
    s_ns: Any
    theta: FloatArray
    roll = yaw = math.nan
    if sensor_type == IMU:
        s_ns, acc = _imus(p, angle_topic, raws[angle_topic], s_log)
        ax, ay, az = acc.T
        valid = imu_valid(ax, ay, az)
        yaw = imu_yaw(ax[valid], ay[valid], az[valid])
        turn = yaw if math.isfinite(yaw) else 0.0
        theta = np.where(valid, imu_tilt(ax, ay, az, turn), np.nan)
        if valid.any():
            roll = float(np.median(imu_roll(ax[valid], ay[valid], az[valid], turn)))
    else:
        s_ns, theta = s_log, _float64s(p, angle_topic, raws[angle_topic])
    finite_j, finite_s = np.isfinite(q), np.isfinite(theta)
    j_ns, q, velocity, effort = j_ns[finite_j], q[finite_j], velocity[finite_j], effort[finite_j]
    order = np.argsort(j_ns, kind='stable')
    j_ns, q, velocity, effort = j_ns[order], q[order], velocity[order], effort[order]
    s_ns, theta = s_ns[finite_s], theta[finite_s]
    if q.size == 0 or theta.size == 0:
        raise CalibrationError(f'{p}: no finite {"joint position" if q.size == 0 else "sensor reading"}'
                               + ('' if q.size or sensor_type != IMU else ' (an IMU reading counts when its '
                                  'acceleration is gravity-sized, m/s^2)'))
    t0 = int(min(j_ns.min(), s_ns.min()))
    jt = (j_ns - t0) * 1e-9
    st = (s_ns - t0) * 1e-9
    times, qp, thp = pair(jt, q, st, theta)
    return CalibrationData(p, chosen, angle_topic, sensor_type, t0, jt, q, velocity, effort, st, theta, times, qp,
                           thp, int(np.count_nonzero(~finite_s)), int(np.count_nonzero(~finite_j)), roll, yaw)


def _topics(types: dict[str, str]) -> str:
    return 'topics: ' + ', '.join(f'{t} [{m}]' for t, m in sorted(types.items())) if types else 'the bag has no topics'


def _joint_states(p: Path, topic: str, raws: list[bytes], logs: Any,
                  driven_joint: str) -> tuple[Any, FloatArray, FloatArray, FloatArray]:
    """(times ns, position rad, velocity rad/s or NaN, effort N m or NaN) of the driven joint: the header stamp,
    else the receive time."""
    try:
        sec, nanosec, frame_id, names, _ = read_joint_state_head(raws[0])
    except MalformedCdrError as exc:
        raise CalibrationError(f'{p}: message 0 on {topic} is not a valid {JOINT_STATE} ({one_line(exc)})') from None
    fast = decode_joint_states(raws, frame_id, tuple(names)) if driven_joint in names else None
    if fast is not None:
        i = names.index(driven_joint)
        stamps, q, effort = fast.stamps_ns, fast.position[:, i].copy(), fast.effort[:, i].copy()
        velocity = fast.velocity[:, i].copy()
    else:
        n = len(raws)
        stamps = np.zeros(n, dtype=np.int64)
        q, velocity, effort = np.full(n, np.nan), np.full(n, np.nan), np.full(n, np.nan)
        for k, raw in enumerate(raws):
            try:
                sec, nanosec, _, names, at = read_joint_state_head(raw)
                position, velocities, efforts = read_joint_state_arrays(raw, at)
            except MalformedCdrError:
                continue
            if driven_joint in names:
                i = names.index(driven_joint)
                stamps[k] = sec * 1_000_000_000 + nanosec
                q[k] = position[i] if i < len(position) else math.nan
                effort[k] = efforts[i] if i < len(efforts) else math.nan
                velocity[k] = velocities[i] if i < len(velocities) else math.nan
        if not np.isfinite(q).any():
            raise CalibrationError(f'{p}: no JointState on {topic} has the driven joint {driven_joint!r}')
    stamps = np.where(stamps != 0, stamps, logs)
    return stamps, q, velocity, effort


def _float64s(p: Path, topic: str, raws: list[bytes]) -> FloatArray:
    values = decode_float64s(raws)
    if values is not None:
        return values
    store = jazzy_typestore()
    try:
        msgs: list[Any] = [store.deserialize_cdr(r, FLOAT64) for r in raws]
        return np.array([float(m.data) for m in msgs], dtype=np.float64)
    except Exception as exc:
        raise CalibrationError(f'{p}: a message on {topic} is not a valid {FLOAT64} ({one_line(exc)})') from None


def _imus(p: Path, topic: str, raws: list[bytes], logs: Any) -> tuple[Any, FloatArray]:
    """(times ns, linear_acceleration (N, 3) m/s^2) of little-endian CDR Imu messages: the header stamp, else the
    receive time."""
    n = len(raws)
    stamps = np.empty(n, dtype=np.int64)
    acc = np.empty((n, 3))
    for k, raw in enumerate(raws):
        try:
            if len(raw) < 16 or raw[1] != 1:
                raise ValueError('not little-endian CDR')
            sec, nanosec = _STAMP.unpack_from(raw, 4)
            length = _UINT32.unpack_from(raw, 12)[0]
            at = 16 + length
            at += -(at - 4) % 8
            acc[k] = _ACCEL.unpack_from(raw, at + _ACCEL_AT)
        except (ValueError, struct.error) as exc:
            raise CalibrationError(f'{p}: message {k} on {topic} is not a valid {IMU} ({one_line(exc)})') from None
        stamps[k] = sec * 1_000_000_000 + nanosec
    stamps = np.where(stamps != 0, stamps, logs)
    return stamps, acc
