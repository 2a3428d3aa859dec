"""The live check of the model: an antenna angle sensor's readings against the angle completed at their times. No ROS.

The mismatch is ``core.calibration.model_mismatch``, the joint paired as ``fourbar calibrate`` pairs it;
docs/how-to/calibrate.md and docs/reference/diagnostics.md."""

from __future__ import annotations

import bisect
import enum
import math
from collections import deque
from dataclasses import asdict, dataclass

from fourbar_ros.config.antenna_config import AntennaConfig
from fourbar_ros.core.calibration import imu_tilt, imu_valid, model_mismatch
from fourbar_ros.core.errors import FourBarError

__all__ = ['HISTORY', 'WINDOW_READINGS', 'ModelCheck', 'SensorCounters', 'SensorSkipped',
           'imu_theta']

#: Completed measurements held for pairing: 10 s of joint_state_broadcaster at 100 Hz.
HISTORY = 1000
#: Most readings the window RMS is taken over (bounds memory under a long tracking_window and a fast sensor).
WINDOW_READINGS = 10000


class SensorSkipped(enum.Enum):
    """Why a sensor reading is not compared; the value names its counter (``sensor_readings_skipped_<value>``)."""

    NOT_FINITE = 'not_finite'
    NO_GRAVITY = 'no_gravity'
    NO_MEASUREMENT = 'no_measurement'
    OUT_OF_REACH = 'out_of_reach'


@dataclass
class SensorCounters:
    """Counts of the model check, reported in diagnostics."""

    sensor_readings_compared: int = 0
    sensor_readings_skipped_not_finite: int = 0
    sensor_readings_skipped_no_gravity: int = 0
    sensor_readings_skipped_no_measurement: int = 0
    sensor_readings_skipped_out_of_reach: int = 0


def imu_theta(ax: float, ay: float, az: float) -> float | SensorSkipped:
    """The antenna angle (rad) from an Imu's linear acceleration at rest (m/s^2; ``core.calibration.imu_tilt``, the
    same convention as ``fourbar calibrate``, independent of the IMU's roll), or why there is none."""
    if not (math.isfinite(ax) and math.isfinite(ay) and math.isfinite(az)):
        return SensorSkipped.NOT_FINITE
    if not imu_valid(ax, ay, az):  # not gravity-sized: an all-zero vector, not at rest
        return SensorSkipped.NO_GRAVITY
    return float(imu_tilt(ax, ay, az))


class ModelCheck:
    """The held measurements, the counters and the window of mismatches (see the module docstring)."""

    def __init__(self, cfg: AntennaConfig) -> None:
        """``cfg``: the configuration the completion uses (its linkage, driven rocker and branch)."""
        self._link, self._driven, self._branch = cfg.linkage, cfg.driven, cfg.measured_branch
        self.counters = SensorCounters()
        self._stamps: deque[int] = deque(maxlen=HISTORY)
        self._q: deque[float] = deque(maxlen=HISTORY)
        self._window: deque[tuple[float, float]] = deque(maxlen=WINDOW_READINGS)  # (steady s, mismatch rad)
        self.latest: float | None = None  # the last mismatch, rad

    def note_measured(self, stamp_ns: int, q: float) -> None:
        """A completed measurement: the measured driven joint ``q`` (rad) at ``stamp_ns``. A stamp before the last
        held one (a restarted drive, a replayed clock) drops the history."""
        stamps = self._stamps
        if stamps and stamp_ns <= stamps[-1]:
            if stamp_ns == stamps[-1]:
                self._q[-1] = q
                return
            stamps.clear()
            self._q.clear()
        stamps.append(stamp_ns)
        self._q.append(q)

    def q_at(self, stamp_ns: int, max_age_ns: int) -> float | None:
        """The measured joint (rad) at ``stamp_ns``: interpolated between the held measurements around it, else the
        latest at or before it if at most ``max_age_ns`` older; None without one."""
        stamps, qs = self._stamps, self._q
        i = bisect.bisect_right(stamps, stamp_ns)
        if i == 0:
            return None
        t0, q0 = stamps[i - 1], qs[i - 1]
        if i == len(stamps) or t0 == stamp_ns:
            return q0 if stamp_ns - t0 <= max_age_ns else None
        t1, q1 = stamps[i], qs[i]
        return q0 + (q1 - q0) * ((stamp_ns - t0) / (t1 - t0))

    def compare(self, cfg: AntennaConfig, stamp_ns: int, sensor_theta: float | SensorSkipped,
                now_s: float) -> float | SensorSkipped:
        """Compare one reading (rad, or why it has none) at ``stamp_ns`` with the model, received at steady time
        ``now_s``; ``cfg``: the running configuration (the sensor's offset, the timeout). The mismatch (rad), or
        why it was skipped (counted either way)."""
        outcome = self._mismatch(cfg, stamp_ns, sensor_theta)
        if isinstance(outcome, SensorSkipped):
            key = f'sensor_readings_skipped_{outcome.value}'
            setattr(self.counters, key, getattr(self.counters, key) + 1)
            return outcome
        self.counters.sensor_readings_compared += 1
        self.latest = outcome
        self._window.append((now_s, outcome))
        return outcome

    def _mismatch(self, cfg: AntennaConfig, stamp_ns: int,
                  sensor_theta: float | SensorSkipped) -> float | SensorSkipped:
        if isinstance(sensor_theta, SensorSkipped):
            return sensor_theta
        if not math.isfinite(sensor_theta):
            return SensorSkipped.NOT_FINITE
        q = self.q_at(stamp_ns, round(cfg.measurement_timeout * 1e9))
        if q is None:
            return SensorSkipped.NO_MEASUREMENT
        try:
            return float(model_mismatch(self._link, q, sensor_theta, self._driven, self._branch, 0.0,
                                        cfg.antenna_sensor_offset))
        except FourBarError:
            return SensorSkipped.OUT_OF_REACH

    def window_rms(self, now_s: float, window_s: float) -> tuple[float | None, int]:
        """(RMS rad of the mismatches received over the last ``window_s`` s, or None; how many)."""
        window = self._window
        while window and window[0][0] < now_s - window_s:
            window.popleft()
        if not window:
            return None, 0
        return math.sqrt(math.fsum(r * r for _, r in window) / len(window)), len(window)

    def diagnostics(self, cfg: AntennaConfig, now_s: float) -> tuple[int, str, list[tuple[str, str]]]:
        """(level 0 OK / 1 WARN / 2 ERROR, message, key/value pairs): the level from the window's RMS."""
        values = [(k, str(v)) for k, v in asdict(self.counters).items()]
        rms, n = self.window_rms(now_s, cfg.tracking_window)
        values += [('model_mismatch_rad', repr(self.latest) if self.latest is not None else 'none'),
                   ('model_mismatch_rms_rad', repr(rms) if rms is not None else 'none'),
                   ('model_mismatch_window_readings', str(n))]
        if rms is None:
            return 0, 'ok', values
        for level, limit, name in ((2, cfg.model_mismatch_error, 'model_mismatch_error'),
                                   (1, cfg.model_mismatch_warn, 'model_mismatch_warn')):
            if rms > limit:
                return (level, f'antenna sensor minus model: RMS {rms:.3g} rad over {n} readings in '
                        f'{cfg.tracking_window:g} s, above {name} {limit:g} rad (recalibrate: fourbar calibrate)',
                        values)
        return 0, 'ok', values
