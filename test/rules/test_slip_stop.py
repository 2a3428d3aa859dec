"""The slip stop of the live model check (``rules.model_check.SlipStop``), no ROS: an open-loop stepper's count goes
on while the antenna stays; the sensor's mean mismatch over slip_stop_time beyond slip_stop_mismatch stops the motion,
at the first reading stamped slip_stop_time after the first one beyond it at the latest; never while every reading is
within it. Readings are timed by their stamps; a late one is left out."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fourbar_ros.config.antenna_config import AntennaConfig, default_config
from fourbar_ros.rules.model_check import ModelCheck, SlipEvent, SlipReading, SlipStop

NS = 1_000_000_000
#: One electrical cycle of the default stepper at the rocker (rad): 2 pi / 50 teeth / 500:1.
CYCLE = 2.0 * math.pi / 50 / 500


def _cfg(**values: float) -> AntennaConfig:
    return dataclasses.replace(default_config(), **values)  # type: ignore[arg-type]


def _theta(cfg: AntennaConfig, q: float) -> float:
    return float(cfg.linkage.from_rocker(q, cfg.driven, cfg.measured_branch).theta)


def _feed(stop: SlipStop, cfg: AntennaConfig, readings: list[tuple[int, float]]) -> list[tuple[int, SlipEvent]]:
    """Feed (stamp ns, mismatch rad) readings; the events with the stamps of the readings that caused them."""
    out = []
    for stamp, m in readings:
        event = stop.update(cfg, SlipReading(stamp, m, m))
        if event is not None:
            out.append((stamp, event))
    return out


def test_the_defaults_and_one_electrical_cycle_in_theta() -> None:
    """One electrical cycle is 2.51e-4 rad at the rocker: 1.65e-4 to 2.74e-4 rad of theta over the default range
    (dtheta/dgamma from 0.66 to 1.09), a fifth of the 1 mrad noise of the calibration how-to's inclinometer and a
    hundredth of the default slip_stop_mismatch (0.02 rad): a slip the stop can see is 73 to 121 cycles by default."""
    cfg = default_config()
    assert (cfg.slip_stop_mismatch, cfg.slip_stop_time) == (0.02, 0.2)
    thetas = np.linspace(cfg.theta_min, cfg.theta_max, 41)
    qs = [float(cfg.linkage.rocker_angles(t, cfg.branch)[0]) for t in thetas]
    per_cycle = [_theta(cfg, q + CYCLE) - _theta(cfg, q) for q in qs]
    assert min(per_cycle) > 1.6e-4 and max(per_cycle) < 2.8e-4, (min(per_cycle), max(per_cycle))
    cycles = [math.ceil(cfg.slip_stop_mismatch / p) for p in per_cycle]
    assert (min(cycles), max(cycles)) == (73, 121), (min(cycles), max(cycles))


def _slipped_run(cfg: AntennaConfig, cycles: int, noise: float, latency: float, seed: int = 3, q0: float = 0.85,
                 speed: float = 0.05) -> tuple[list[tuple[int, SlipEvent]], int]:
    """A rocker counted moving ``speed`` rad/s from ``q0`` rad, measured at 100 Hz for 3 s; at 1.5 s the stepper slips
    ``cycles`` electrical cycles at once (the antenna's rocker stays that far behind the count). The antenna sensor
    reads at 100 Hz, offset 5 ms from the measurements, with normal noise of sd ``noise`` rad, each reading stamped
    ``latency`` s after the moment it saw (declared: antenna_sensor_latency). The events, and the slip's stamp (ns)."""
    rng = np.random.default_rng(seed)
    check, stop = ModelCheck(cfg), SlipStop()
    slip_ns = 3 * NS // 2
    events = []
    for k in range(300):
        check.note_measured(k * NS // 100, q0 + speed * k / 100)
        seen_ns = k * NS // 100 + 5_000_000
        q_true = q0 + speed * seen_ns / NS - (cycles * CYCLE if seen_ns >= slip_ns else 0.0)
        stamp = seen_ns + round(latency * NS)
        sensor = _theta(cfg, q_true) + float(rng.normal(0.0, noise))
        m = check.compare(cfg, stamp, sensor, stamp / NS)
        if isinstance(m, float):
            event = stop.update(cfg, SlipReading(stamp, m, sensor))
            if event is not None:
                events.append((stamp, event))
    return events, slip_ns


@pytest.mark.parametrize('latency', [0.0, 0.02])
def test_a_slip_of_200_cycles_stops_within_slip_stop_time_and_a_period(latency: float) -> None:
    """200 cycles (0.039 rad of theta here, 19 noise sds beyond the 0.02 rad threshold) seen by a sensor with 1 mrad
    of noise: the stop's reading is stamped at most slip_stop_time + one 10 ms period after the first reading that saw
    the slip, itself within a period (and the latency) of it; nothing before. (pytest -s prints the figures.)"""
    cfg = _cfg(antenna_sensor_latency=latency)
    events, slip_ns = _slipped_run(cfg, 200, noise=1e-3, latency=latency)
    assert [e for _, e in events] == [SlipEvent.STOP], events
    stamp = events[0][0]
    first_seen = slip_ns + 5_000_000 + round(latency * NS)  # the first reading of the slipped antenna
    delay = (stamp - slip_ns) / NS
    print(f'\nslip of 200 cycles, latency {latency:g} s: stop at the reading stamped {delay:.3f} s after the slip '
          f'({(stamp - first_seen) / NS:.3f} s after the first reading that saw it)')
    assert first_seen <= stamp <= first_seen + seconds(cfg.slip_stop_time) + NS // 100, (stamp, first_seen)


def seconds(s: float) -> int:
    return round(s * NS)


def test_the_smallest_slip_seen_without_noise() -> None:
    """Noiseless and at rest, the stop sees a slip whose theta exceeds slip_stop_mismatch: at gamma = 0.8745 rad
    (theta 0.009 rad, dtheta/dgamma 0.778, falling behind the count: 1.9e-4 rad of theta per cycle) 0.02 rad takes
    105 cycles and not 104; 0.005 rad (a calibrated sensor's setting) 26; 0.002 rad 11."""
    for limit, seen in ((0.02, 105), (0.005, 26), (0.002, 11)):
        cfg = _cfg(slip_stop_mismatch=limit)
        drop = abs(_theta(cfg, 0.8745 - seen * CYCLE) - _theta(cfg, 0.8745))
        less = abs(_theta(cfg, 0.8745 - (seen - 1) * CYCLE) - _theta(cfg, 0.8745))
        assert less <= limit < drop, (limit, seen, less, drop)  # the count's lie in theta, by the core
        assert _slipped_run(cfg, seen, noise=0.0, latency=0.0, q0=0.8745, speed=0.0)[0], (limit, seen)
        assert not _slipped_run(cfg, seen - 1, noise=0.0, latency=0.0, q0=0.8745, speed=0.0)[0], (limit, seen - 1)


def test_a_reading_at_the_threshold_is_not_beyond_it() -> None:
    cfg = _cfg(slip_stop_mismatch=0.02, slip_stop_time=0.1)
    at = [(k * 10_000_000, 0.02) for k in range(50)]
    assert _feed(SlipStop(), cfg, at) == []
    above = [(k * 10_000_000, math.nextafter(0.02, 1.0)) for k in range(50)]
    # the window [t - 0.1 s, t] with a reading before it: first at the reading stamped 0.11 s
    assert _feed(SlipStop(), cfg, above) == [(110_000_000, SlipEvent.STOP)]
    assert _feed(SlipStop(), cfg, [(s, -m) for s, m in above]) == [(110_000_000, SlipEvent.STOP)]


def test_no_readings_or_too_few_stop_nothing() -> None:
    cfg = _cfg(slip_stop_time=0.1)
    stop = SlipStop()
    assert _feed(stop, cfg, []) == [] and stop.mean is None and not stop.stopped
    # one reading far off, then silence: no window of two readings with one before it
    assert _feed(stop, cfg, [(0, 1.0)]) == [] and stop.mean is None
    # a second one 1 s later: one before the window, but one in it
    assert _feed(stop, cfg, [(NS, 1.0)]) == [] and stop.mean is None
    assert _feed(stop, cfg, [(NS + 1, 1.0)]) == [(NS + 1, SlipEvent.STOP)]


def test_late_readings_are_left_out() -> None:
    cfg = _cfg(slip_stop_time=0.1)
    stop = SlipStop()
    agreeing = [(k * 10_000_000, 0.0) for k in range(30)]
    assert _feed(stop, cfg, agreeing) == []
    # readings stamped at or before the latest, by at most slip_stop_time: far off, yet left out
    assert _feed(stop, cfg, [(290_000_000, 1.0), (190_000_000, 1.0)] * 20) == [] and stop.late == 40
    assert stop.mean == 0.0 and stop.restarts == 0
    slipped = [(300_000_000 + k * 10_000_000, 0.05) for k in range(20)]
    assert _feed(stop, cfg, slipped)[0][1] is SlipEvent.STOP and stop.stopped
    # a late agreeing reading does not clear it either
    assert _feed(stop, cfg, [(0, 0.0)] * 5) == [] and stop.stopped


def test_a_mismatch_that_clears_releases_the_stop_after_a_window_within_it() -> None:
    cfg = _cfg(slip_stop_mismatch=0.02, slip_stop_time=0.1)
    stop = SlipStop()
    off = [(k * 10_000_000, 0.05) for k in range(20)]
    events = _feed(stop, cfg, off)
    assert events == [(110_000_000, SlipEvent.STOP)], events  # the first with a reading before its window
    assert 'the drive may have slipped' in stop.stopped and 'reads 0.05 rad, the model 0 rad' in stop.stopped
    # back to agreeing from 0.2 s: the mean over [t - 0.1, t] comes within 0.02 rad once 7 of its 11 readings agree
    # (5 x 0.05 / 11 = 0.0227 > 0.02; 4 x 0.05 / 11 = 0.018)
    back = [(200_000_000 + k * 10_000_000, 0.0) for k in range(20)]
    events = _feed(stop, cfg, back)
    assert events == [(260_000_000, SlipEvent.CLEARED)], events
    assert not stop.stopped and stop.stops == 1


def test_slip_stop_mismatch_0_is_off_and_clears_a_stop() -> None:
    stop = SlipStop()
    off = [(k * 10_000_000, 1.0) for k in range(40)]
    assert _feed(stop, _cfg(slip_stop_mismatch=0.0, slip_stop_time=0.1), off[:20]) == []
    assert _feed(stop, _cfg(slip_stop_time=0.1), off[20:22]) == [(200_000_000, SlipEvent.STOP)]
    assert _feed(stop, _cfg(slip_stop_mismatch=0.0, slip_stop_time=0.1), off[22:]) == [(220_000_000,
                                                                                          SlipEvent.CLEARED)]


_LIMITS = st.floats(1e-4, 0.1)


@settings(max_examples=300, deadline=None)
@given(limit=_LIMITS, window=st.floats(0.02, 1.0), period=st.floats(1e-3, 0.05), within=st.floats(0.0, 0.999),
       seed=st.integers(0, 2 ** 32 - 1))
def test_never_stops_while_every_reading_is_within_the_threshold(limit: float, window: float, period: float,
                                                                within: float, seed: int) -> None:
    """Noise bounded by ``within`` of the threshold (uniform, and at its bounds), any rate: the mean stays within."""
    cfg = _cfg(slip_stop_mismatch=limit, slip_stop_time=window)
    rng = np.random.default_rng(seed)
    n = int(3 * window / period) + 3
    noise = rng.uniform(-within * limit, within * limit, n)
    noise[::7] = np.sign(noise[::7]) * within * limit
    stamps = np.cumsum(rng.uniform(0.5, 1.5, n) * period * NS).astype(np.int64) + 1
    stop = SlipStop()
    assert _feed(stop, cfg, [(int(s), float(e)) for s, e in zip(stamps, noise, strict=True)]) == []
    assert stop.stops == 0


@settings(max_examples=300, deadline=None)
@given(limit=_LIMITS, window=st.floats(0.02, 1.0), period_share=st.floats(0.01, 0.45), beyond=st.floats(1e-6, 1.0),
       within=st.floats(0.0, 0.999), sign=st.sampled_from([1.0, -1.0]), seed=st.integers(0, 2 ** 32 - 1))
def test_always_stops_by_the_first_reading_slip_stop_time_after_the_first_beyond(
        limit: float, window: float, period_share: float, beyond: float, within: float, sign: float,
        seed: int) -> None:
    """Readings within the threshold, then from t1 on every one beyond it on one side (by up to 100%, noise
    included): the stop comes at the first reading stamped at or after t1 + slip_stop_time, or before (the mean can
    pass the threshold earlier), never before t1. Readings at most 0.45 slip_stop_time apart: at least two in each
    window."""
    cfg = _cfg(slip_stop_mismatch=limit, slip_stop_time=window)
    rng = np.random.default_rng(seed)
    period = period_share * window
    n_before, n_after = int(2 * window / period) + 3, int(2 * window / period) + 3
    stamps = np.cumsum(rng.uniform(0.5, 1.0, n_before + n_after) * period * NS).astype(np.int64) + 1
    before = rng.uniform(-within * limit, within * limit, n_before)
    after = sign * limit * (1.0 + rng.uniform(0.0, 1.0, n_after) * beyond)
    after[after == sign * limit] = sign * math.nextafter(limit, 2.0 * limit)
    values = np.concatenate([before, after])
    t1 = int(stamps[n_before])
    due = next(int(s) for s in stamps if s >= t1 + seconds(window))
    events = _feed(SlipStop(), cfg, [(int(s), float(v)) for s, v in zip(stamps, values, strict=True)])
    assert events and events[0][1] is SlipEvent.STOP, events
    assert t1 <= events[0][0] <= due, (events[0][0], t1, due)
    assert len(events) == 1, events


def test_a_clock_that_went_back_starts_the_window_afresh() -> None:
    """A reading stamped more than slip_stop_time before the latest (a replayed clock, a restarted drive's stamps):
    not late but a new time base; the window starts from it, so a stop needs slip_stop_time of readings again, and
    a stop in force stays until such a window agrees."""
    cfg = _cfg(slip_stop_time=0.1)
    stop = SlipStop()
    assert _feed(stop, cfg, [(100 * NS + k * 10_000_000, 0.05) for k in range(20)])[0][1] is SlipEvent.STOP
    back = [(k * 10_000_000, 0.0) for k in range(20)]
    events = _feed(stop, cfg, back)
    assert stop.restarts == 1 and stop.late == 0, (stop.restarts, stop.late)
    assert events == [(110_000_000, SlipEvent.CLEARED)], events  # the first window of the new time base
    fresh = SlipStop()
    assert _feed(fresh, cfg, [(100 * NS + k * 10_000_000, 0.0) for k in range(20)]) == []
    assert _feed(fresh, cfg, [(k * 10_000_000, 0.05) for k in range(20)]) == [(110_000_000, SlipEvent.STOP)]


def test_the_antenna_staying_while_the_count_goes_on_stops_within_the_time_after_the_threshold() -> None:
    """The stepper stalls at theta = 0.009 rad (gamma 0.8745 rad) while its count goes on at 0.1 rad/s of the rocker
    (the antenna stays): the mismatch grows by 0.078 rad/s and passes 0.02 rad 0.26 s in; a 100 Hz sensor with 1 mrad
    of noise, seed fixed: the stop comes within slip_stop_time and a period after the first reading beyond it, well
    under a second after the stall in all."""
    cfg = _cfg()
    rng = np.random.default_rng(11)
    check, stop = ModelCheck(cfg), SlipStop()
    q_stall, speed, stall_s = 0.8745, 0.1, 1.0
    stay = _theta(cfg, q_stall)
    first_beyond: int | None = None
    for k in range(300):
        t = k / 100
        stamp = k * NS // 100
        q = q_stall + speed * max(t - stall_s, 0.0)  # at rest until the stall, then the count alone goes on
        check.note_measured(stamp, q)
        sensor = (_theta(cfg, q) if t <= stall_s else stay) + float(rng.normal(0.0, 1e-3))
        m = check.compare(cfg, stamp, sensor, t)
        assert isinstance(m, float)
        if first_beyond is None and abs(stay - _theta(cfg, q)) > cfg.slip_stop_mismatch:
            first_beyond = stamp
        if stop.update(cfg, SlipReading(stamp, m, sensor)) is SlipEvent.STOP:
            break
    assert first_beyond is not None and stop.stopped, (first_beyond, stop.mean)
    delay, after = stamp / NS - stall_s, (stamp - first_beyond) / NS
    print(f'\nstall at 0.1 rad/s of the count: stop {delay:.3f} s after the stall, {after:.3f} s after the model '
          f'passed the threshold')
    assert 0.0 <= after <= cfg.slip_stop_time + 0.01 and delay < 1.0, (delay, after)
