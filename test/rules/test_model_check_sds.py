"""The live model check in the calibration's sds (``rules.model_check``): the window's bias and scatter tested apart,
the sensor's latency applied, and the RMS limits kept where no noise estimate is given."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from fourbar_ros.config.antenna_config import AntennaConfig, default_config
from fourbar_ros.rules.model_check import ModelCheck, window_test

NS = 1_000_000_000


def test_the_window_test_by_hand() -> None:
    # bias 2, scatter 1; two independent readings of noise 1: the mean's sd 1/sqrt(2)
    test = window_test([1.0, 3.0], noise=1.0, correlation=0.0, map_sd=0.0)
    assert (test.bias, test.scatter) == (2.0, 1.0)
    assert test.bias_sds == pytest.approx(2.0 * math.sqrt(2.0), rel=1e-15)
    assert test.scatter_sds == 0.0
    # the map's sd adds to the mean's in quadrature; correlation 0.5 makes 4 readings count as 4/3
    test = window_test([0.0, 0.0, 0.0, 4.0], noise=2.0, correlation=0.5, map_sd=1.5)
    assert test.bias_sds == pytest.approx(1.0 / math.hypot(1.5, 2.0 / math.sqrt(4.0 / 3.0)), rel=1e-15)


@pytest.mark.parametrize('rho', [0.0, 0.9])
def test_the_bias_in_sds_of_pure_noise_has_a_spread_near_1(rho: float) -> None:
    """1000 windows of 250 readings of AR(1) noise (sd 1 mrad, lag-1 correlation rho), the map exact: the signed
    bias in sds has an sd near 1 (its sampling sd over 1000 windows is about 2%; the n_eff approximation of an
    AR(1) mean's variance is within a few % at n = 250), so a 4-sd limit almost never trips on a good sensor."""
    rng = np.random.default_rng(40)
    noise, n, windows = 1e-3, 250, 1000
    innovations = rng.normal(0.0, noise * math.sqrt(1.0 - rho * rho), (windows, n))
    x = np.empty_like(innovations)
    x[:, 0] = rng.normal(0.0, noise, windows)
    for k in range(1, n):
        x[:, k] = rho * x[:, k - 1] + innovations[:, k]
    z = [math.copysign(t.bias_sds, t.bias) for t in (window_test(list(w), noise, rho, 0.0) for w in x)]
    assert 0.9 < float(np.std(z)) < 1.1, float(np.std(z))
    assert sum(abs(v) > 4.0 for v in z) <= 2


def _cfg(**values: float) -> AntennaConfig:
    return dataclasses.replace(default_config(), **values)  # type: ignore[arg-type]


def _fed(cfg: AntennaConfig, sensor: list[tuple[int, float]], joint: list[tuple[int, float]]) -> ModelCheck:
    check = ModelCheck(cfg)
    for stamp, q in joint:
        check.note_measured(stamp, q)
    for stamp, theta in sensor:
        check.compare(cfg, stamp, theta, stamp / NS)
    return check


def _theta(cfg: AntennaConfig, q: float) -> float:
    return float(cfg.linkage.from_rocker(q, cfg.driven, cfg.measured_branch).theta)


def _sweep(cfg: AntennaConfig, lag_s: float, bias: float = 0.0, noise: float = 0.0
           ) -> tuple[list[tuple[int, float]], list[tuple[int, float]]]:
    """A joint moving 0.05 rad/s from 0.85 rad, measured at 100 Hz for 4 s; the sensor at 50 Hz seeing it
    ``lag_s`` late, plus ``bias`` and normal noise of sd ``noise`` (rad)."""
    rng = np.random.default_rng(7)
    joint = [(k * NS // 100, 0.85 + 0.05 * k / 100) for k in range(400)]
    sensor = [(k * NS // 50, _theta(cfg, 0.85 + 0.05 * (k / 50 - lag_s)) + bias + float(rng.normal(0.0, noise)))
              for k in range(25, 190)]
    return sensor, joint


def test_the_latency_is_applied() -> None:
    cfg = _cfg(antenna_sensor_latency=0.2)
    sensor, joint = _sweep(cfg, lag_s=0.2)
    late = _fed(dataclasses.replace(cfg, antenna_sensor_latency=0.0), sensor, joint)
    assert late.window(4.0, 5.0) and max(abs(r) for r in late.window(4.0, 5.0)) > 1e-3  # 0.2 s * 0.05 rad/s, mapped
    applied = _fed(cfg, sensor, joint).window(4.0, 5.0)
    # the joint is interpolated linearly between 10 ms samples of a linear motion: only the map's curvature remains
    assert max(abs(r) for r in applied) < 1e-9, max(abs(r) for r in applied)


@pytest.mark.parametrize(('bias_sds', 'level'), [(0.0, 0), (6.0, 1), (12.0, 2)])
def test_a_bias_in_sds_of_the_calibration_sets_the_level(bias_sds: float, level: int) -> None:
    noise, map_sd = 1e-3, 2e-4
    cfg = _cfg(antenna_sensor_noise=noise, antenna_sensor_map_sd=map_sd, tracking_window=10.0)
    n = 165
    sd = math.hypot(map_sd, noise / math.sqrt(n))
    sensor, joint = _sweep(cfg, 0.0, bias=bias_sds * sd, noise=noise)
    got, message, values = _fed(cfg, sensor, joint).diagnostics(cfg, 4.0)
    shown = dict(values)
    assert shown['model_mismatch_window_readings'] == str(n)
    assert got == level, (message, shown)
    if level:
        limit = 'model_mismatch_error_sds' if level == 2 else 'model_mismatch_warn_sds'
        assert 'bias' in message and limit in message, message
        # the RMS (about 1.2 mrad at 6 sds) is well below the absolute model_mismatch_warn (5 mrad): only the sds see it
        assert float(shown['model_mismatch_rms_rad']) < cfg.model_mismatch_warn


def test_a_scatter_above_the_noise_warns_and_the_rms_limits_stay_without_a_noise_estimate() -> None:
    cfg = _cfg(antenna_sensor_noise=1e-3, antenna_sensor_map_sd=2e-4, tracking_window=10.0)
    sensor, joint = _sweep(cfg, 0.0, noise=2e-3)  # twice the calibrated noise, no bias
    level, message, _ = _fed(cfg, sensor, joint).diagnostics(cfg, 4.0)
    assert level == 2 and 'scatter' in message, message
    plain = dataclasses.replace(cfg, antenna_sensor_noise=0.0)
    level, message, values = _fed(plain, sensor, joint).diagnostics(plain, 4.0)
    assert level == 0 and 'model_mismatch_bias_sds' not in dict(values), message
