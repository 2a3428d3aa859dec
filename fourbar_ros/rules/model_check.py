"""The live check of the model: an antenna angle sensor's readings against the angle completed at their times. No ROS.

The mismatch is ``core.calibration.model_mismatch``, the joint paired as ``fourbar calibrate`` pairs it (the
sensor's latency applied). With the calibration's noise estimate, the window's bias and scatter are tested apart, in
sds (``window_test``); without, its RMS against absolute limits. A mean beyond ``slip_stop_mismatch`` stops the motion
(``SlipStop``). docs/how-to/calibrate.md and docs/reference/diagnostics.md."""

from __future__ import annotations

import bisect
import enum
import math
from collections import deque
from dataclasses import asdict, dataclass

from fourbar_ros.config.antenna_config import AntennaConfig
from fourbar_ros.core.calibration import imu_tilt, imu_valid, model_mismatch
from fourbar_ros.core.errors import FourBarError
from fourbar_ros.interface.stamps import seconds_to_ns

__all__ = ['HISTORY', 'WINDOW_READINGS', 'ModelCheck', 'SensorCounters', 'SensorSkipped', 'SlipEvent', 'SlipReading',
           'SlipStop', 'WindowTest', 'imu_theta', 'window_test']

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


def imu_theta(ax: float, ay: float, az: float, yaw: float = 0.0) -> float | SensorSkipped:
    """The antenna angle (rad) from an Imu's linear acceleration at rest (m/s^2) mounted turned by ``yaw`` (rad)
    about its z axis (``core.calibration.imu_tilt``, the same convention as ``fourbar calibrate``, independent of
    the IMU's roll), or why there is none."""
    if not (math.isfinite(ax) and math.isfinite(ay) and math.isfinite(az)):
        return SensorSkipped.NOT_FINITE
    if not imu_valid(ax, ay, az):  # not gravity-sized: an all-zero vector, not at rest
        return SensorSkipped.NO_GRAVITY
    return float(imu_tilt(ax, ay, az, yaw))


@dataclass(frozen=True)
class WindowTest:
    """A window of n mismatches (rad) against the calibration: its ``bias`` (mean) and ``scatter`` (RMS about the
    mean), each in sds: ``bias_sds`` = |bias| / sqrt(map_sd^2 + noise^2 / n_eff), ``scatter_sds`` = (scatter / noise -
    1) sqrt(2 n_eff) (the sample sd of n_eff independent normal readings has a relative sd of 1 / sqrt(2 n_eff)),
    with n_eff = n (1 - c) / (1 + c) for a lag-1 correlation c."""

    bias: float
    scatter: float
    bias_sds: float
    scatter_sds: float


def window_test(mismatches: list[float], noise: float, correlation: float, map_sd: float) -> WindowTest:
    """``WindowTest`` of one or more ``mismatches`` (rad) with the calibration's ``noise`` sd (rad, > 0), its lag-1
    ``correlation`` (in [0, 1)) and the map's sd ``map_sd`` (rad)."""
    n = len(mismatches)
    bias = math.fsum(mismatches) / n
    scatter = math.sqrt(math.fsum((r - bias) ** 2 for r in mismatches) / n)
    n_eff = max(n * (1.0 - correlation) / (1.0 + correlation), 1.0)
    bias_sds = abs(bias) / math.hypot(map_sd, noise / math.sqrt(n_eff))
    return WindowTest(bias, scatter, bias_sds, (scatter / noise - 1.0) * math.sqrt(2.0 * n_eff))


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
        q = self.q_at(stamp_ns - seconds_to_ns(cfg.antenna_sensor_latency), seconds_to_ns(cfg.measurement_timeout))
        if q is None:
            return SensorSkipped.NO_MEASUREMENT
        try:
            return float(model_mismatch(self._link, q, sensor_theta, self._driven, self._branch, 0.0,
                                        cfg.antenna_sensor_offset))
        except FourBarError:
            return SensorSkipped.OUT_OF_REACH

    def window(self, now_s: float, window_s: float) -> list[float]:
        """The mismatches (rad) received over the last ``window_s`` s."""
        window = self._window
        while window and window[0][0] < now_s - window_s:
            window.popleft()
        return [r for _, r in window]

    def diagnostics(self, cfg: AntennaConfig, now_s: float) -> tuple[int, str, list[tuple[str, str]]]:
        """(level 0 OK / 1 WARN / 2 ERROR, message, key/value pairs): the level from the window's bias and scatter
        in sds with ``cfg.antenna_sensor_noise``, else from its RMS."""
        values = [(k, str(v)) for k, v in asdict(self.counters).items()]
        window = self.window(now_s, cfg.tracking_window)
        n = len(window)
        rms = math.sqrt(math.fsum(r * r for r in window) / n) if window else None
        values += [('model_mismatch_rad', repr(self.latest) if self.latest is not None else 'none'),
                   ('model_mismatch_rms_rad', repr(rms) if rms is not None else 'none'),
                   ('model_mismatch_window_readings', str(n))]
        if rms is None:
            return 0, 'ok', values
        about = f'antenna sensor minus model over {n} readings in {cfg.tracking_window:g} s'
        if cfg.antenna_sensor_noise > 0.0:
            test = window_test(window, cfg.antenna_sensor_noise, cfg.antenna_sensor_noise_correlation,
                               cfg.antenna_sensor_map_sd)
            values += [('model_mismatch_bias_rad', repr(test.bias)),
                       ('model_mismatch_bias_sds', f'{test.bias_sds:.3g}'),
                       ('model_mismatch_scatter_rad', repr(test.scatter)),
                       ('model_mismatch_scatter_sds', f'{test.scatter_sds:.3g}')]
            for level, limit, name in ((2, cfg.model_mismatch_error_sds, 'model_mismatch_error_sds'),
                                       (1, cfg.model_mismatch_warn_sds, 'model_mismatch_warn_sds')):
                if test.bias_sds > limit:
                    return (level, f'{about}: bias {test.bias:.3g} rad, {test.bias_sds:.3g} sds from 0, above {name} '
                            f'{limit:g} (the model or an offset moved: recalibrate, fourbar calibrate, or re-zero, '
                            'fourbar zero)', values)
                if test.scatter_sds > limit:
                    return (level, f'{about}: scatter {test.scatter:.3g} rad against a noise of '
                            f'{cfg.antenna_sensor_noise:.3g} rad, {test.scatter_sds:.3g} sds above it, above {name} '
                            f'{limit:g} (a noisier or loose sensor, or backlash)', values)
            return 0, 'ok', values
        for level, limit, name in ((2, cfg.model_mismatch_error, 'model_mismatch_error'),
                                   (1, cfg.model_mismatch_warn, 'model_mismatch_warn')):
            if rms > limit:
                return (level, f'antenna sensor minus model: RMS {rms:.3g} rad over {n} readings in '
                        f'{cfg.tracking_window:g} s, above {name} {limit:g} rad (recalibrate: fourbar calibrate)',
                        values)
        return 0, 'ok', values


class SlipEvent(enum.Enum):
    """What a reading did to the slip stop."""

    STOP = 'stop'  # the mean went beyond slip_stop_mismatch: stop the motion
    CLEARED = 'cleared'  # the mean is back within it (or the stop was turned off): commands may go again


@dataclass(frozen=True)
class SlipReading:
    """One compared reading as the slip stop holds it: its stamp (ns, node clock), the mismatch (rad, sensor minus
    model) and the sensor's antenna angle less its offset (rad)."""

    stamp_ns: int
    mismatch: float
    sensor: float


class SlipStop:
    """The slip stop over compared readings, by their stamps (no ROS).

    A reading at ``t`` looks at the readings stamped in [t - slip_stop_time, t]: with at least two there and one
    before (the sensor read across the whole time), their mean mismatch beyond ``slip_stop_mismatch`` (strictly) is
    a STOP; once stopped, a mean within it over such a window is CLEARED. So when every reading from t1 on is beyond
    the threshold on one side, the stop comes at the first reading stamped at or after t1 + slip_stop_time with
    another in the slip_stop_time before it (readings closer than slip_stop_time: the first at or after); while
    every reading is within it, never. A reading stamped at or before the latest taken, by at most slip_stop_time,
    is late and left out (``late``); one stamped further back is a clock that went back (a replayed or restarted
    clock): the window starts afresh from it (``restarts``), a stop in force stays. ``slip_stop_mismatch`` 0 turns
    the stop off and clears one in force."""

    def __init__(self) -> None:
        self._readings: deque[SlipReading] = deque()
        self._before: SlipReading | None = None  # the latest reading older than the window
        self.stopped = ''  # why the motion stopped ('' while not stopped)
        self.stops = 0
        self.late = 0
        self.restarts = 0  # readings stamped more than slip_stop_time before the latest: the window started afresh
        self.mean: float | None = None  # the window's mean mismatch at the latest reading, rad (None: no window)
        self.last_ns: int | None = None  # the stamp of the latest reading taken (ns)

    def update(self, cfg: AntennaConfig, reading: SlipReading) -> SlipEvent | None:
        """Take one compared reading under the running configuration ``cfg`` (its slip_stop_mismatch and
        slip_stop_time); the event it causes, if any."""
        readings, window_ns = self._readings, seconds_to_ns(cfg.slip_stop_time)
        self.last_ns = reading.stamp_ns
        if readings and reading.stamp_ns < readings[-1].stamp_ns - window_ns:  # the clock went back: start afresh
            readings.clear()
            self._before = None
            self.restarts += 1
        elif readings and reading.stamp_ns <= readings[-1].stamp_ns:
            self.late += 1
            return None
        readings.append(reading)
        start = reading.stamp_ns - window_ns
        while readings[0].stamp_ns < start:
            self._before = readings.popleft()
        covered = self._before is not None and len(readings) >= 2
        self.mean = math.fsum(r.mismatch for r in readings) / len(readings) if covered else None
        limit = cfg.slip_stop_mismatch
        if limit <= 0.0:
            return self._clear()
        if self.mean is None:
            return None
        if not self.stopped and abs(self.mean) > limit:
            sensor = math.fsum(r.sensor for r in readings) / len(readings)
            self.stopped = (f'the antenna sensor reads {sensor:.6g} rad, the model {sensor - self.mean:.6g} rad from '
                            f'the measured joint ({self.mean:+.3g} rad over {len(readings)} readings in '
                            f'{cfg.slip_stop_time:g} s, beyond slip_stop_mismatch {limit:g} rad): the drive may have '
                            'slipped')
            self.stops += 1
            return SlipEvent.STOP
        if self.stopped and abs(self.mean) <= limit:
            return self._clear()
        return None

    def _clear(self) -> SlipEvent | None:
        if not self.stopped:
            return None
        self.stopped = ''
        return SlipEvent.CLEARED

    def values(self) -> list[tuple[str, str]]:
        """Diagnostic key/value pairs: whether stopped and why, the stops, the window's mean, the late readings."""
        return [('slip_stop', f'stopped: {self.stopped}' if self.stopped else 'no'),
                ('slip_stops', str(self.stops)),
                ('slip_stop_mean_rad', repr(self.mean) if self.mean is not None else 'none'),
                ('slip_stop_readings_late', str(self.late)),
                ('slip_stop_restarts', str(self.restarts))]
