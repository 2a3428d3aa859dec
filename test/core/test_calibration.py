"""The calibration fit (fourbar_ros.core.calibration): the exact Jacobian against finite differences, the truth
recovered from synthetic readings (lengths off by tenths of a mm, both offsets, noise, encoder counts), the honest
report of what the data determine, the node's absolute angle and its sd (with a sensor-offset prior, with a
reference), a real sensor's faults (spikes, degrees, a flipped sign, a one-way sweep), and the live check's
residual."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fourbar_ros.config.antenna_config import default_config
from fourbar_ros.core import calibration
from fourbar_ros.core.antenna import AntennaLinkage, Branch, Driven
from fourbar_ros.core.calibration import (
    BOTH_WAYS_FRACTION,
    LENGTH_BOUND,
    PARAMETER_NAMES,
    CalibrationError,
    Reference,
    calibrate,
    check_sensor_scale,
    far_from_prior,
    model_jacobian,
    model_mismatch,
    one_way,
    predict,
    sensor_scale,
)
from fourbar_ros.core.completion import inverse_branch

CFG = default_config()
DESIGN = (CFG.frame_length, CFG.rocker_ab_length, CFG.coupler_length, CFG.rocker_cd_length)
TRUTH = np.array([0.1803, 0.0598, 0.1021, 0.0602, -math.radians(0.7), 0.004])  # m x4, rad x2
COUNT = 2.0 * math.pi / (4096 * 500)  # one encoder count at the joint, rad


def branch_for(link: AntennaLinkage, driven: Driven) -> Branch:
    return inverse_branch(link, 0.0, driven, Branch.UPPER)


def readings(truth: np.ndarray, driven: Driven, n: int, noise: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """(measured q, sensor theta): the true sweep over the tilt range, the encoder's zero off and counted."""
    rng = np.random.default_rng(seed)
    link = AntennaLinkage(*truth[:3], rocker_cd=truth[3])
    theta = CFG.theta_min + (CFG.theta_max - CFG.theta_min) * rng.random(n)
    g, d = link.rocker_angles(theta)
    q_true = np.asarray(g if driven is Driven.GAMMA else d)
    q_measured = np.round((q_true - truth[4]) / COUNT) * COUNT
    return q_measured, theta + truth[5] + rng.normal(0.0, noise, n)


def noiseless(truth: np.ndarray, q_measured: np.ndarray, driven: Driven, branch: Branch) -> np.ndarray:
    """The sensor's noiseless reading at the measured joint: the true linkage at q_measured + the true offset."""
    return predict(truth, q_measured, driven, branch)


@pytest.mark.parametrize('driven', list(Driven))
def test_jacobian_matches_central_differences(driven: Driven) -> None:
    branch = branch_for(CFG.linkage, driven)
    g, d = CFG.linkage.rocker_angles(np.linspace(CFG.theta_min, CFG.theta_max, 9))
    q = np.asarray(g if driven is Driven.GAMMA else d)
    p = TRUTH.copy()
    pred, jac = model_jacobian(p, q, driven, branch)
    assert np.array_equal(pred, predict(p, q, driven, branch))
    for i, name in enumerate(PARAMETER_NAMES):
        h = 1e-6 * (p[i] if i < 4 else 1.0)
        up, down = p.copy(), p.copy()
        up[i] += h
        down[i] -= h
        fd = (predict(up, q, driven, branch) - predict(down, q, driven, branch)) / (2.0 * h)
        # central differences: truncation ~h^2 |theta'''|, rounding ~eps / h
        assert np.allclose(jac[:, i], fd, rtol=1e-6, atol=1e-8), name


@pytest.mark.parametrize('seed', range(5))
def test_fit_recovers_the_truth_within_four_sd(seed: int) -> None:
    driven = Driven.GAMMA
    branch = CFG.measured_branch
    q, y = readings(TRUTH, driven, 20000, 1e-3, seed)  # 400 s of a 50 Hz sensor
    fit = calibrate(q, y, DESIGN, driven, branch)
    for p, truth in zip(fit.parameters, TRUTH, strict=True):
        assert abs(p.value - truth) <= 4.0 * p.sd, (p.name, p.value, truth, p.sd)
    grid = np.linspace(q.min(), q.max(), 501)
    error = predict(fit.values, grid, driven, branch) - noiseless(TRUTH, grid, driven, branch)
    before = predict(np.array([*DESIGN, 0.0, 0.0]), grid, driven, branch) - noiseless(TRUTH, grid, driven, branch)
    assert np.max(np.abs(error)) < 1e-4
    assert np.max(np.abs(before)) > 5e-3  # the offsets alone are 0.7 deg of joint and 0.23 deg of sensor
    assert fit.sigma == pytest.approx(1e-3, rel=0.1)


def test_fit_driving_delta_with_an_imu_like_noise() -> None:
    driven = Driven.DELTA
    branch = branch_for(CFG.linkage, driven)
    q, y = readings(TRUTH, driven, 30000, 2e-3, 11)
    fit = calibrate(q, y, DESIGN, driven, branch)
    grid = np.linspace(q.min(), q.max(), 501)
    assert np.max(np.abs(predict(fit.values, grid, driven, branch) - noiseless(TRUTH, grid, driven, branch))) < 1e-4
    for p, truth in zip(fit.parameters, TRUTH, strict=True):
        assert abs(p.value - truth) <= 4.0 * p.sd, p.name


def test_the_report_says_what_the_data_determined() -> None:
    """Over -6..+7 deg the data fix about three combinations; the lengths' sds stay near the prior's (scale cannot
    come from angles), the offsets' collapse from the weak prior."""
    q, y = readings(TRUTH, Driven.GAMMA, 3000, 1e-3, 3)
    fit = calibrate(q, y, DESIGN, Driven.GAMMA, CFG.measured_branch)
    assert fit.determined_directions == 3
    assert list(fit.singular_values) == sorted(fit.singular_values, reverse=True)
    assert fit.singular_values[-1] < 1e-6 * fit.singular_values[0]  # the scale: no information at all
    by_data = {p.name: p.determined_by_data for p in fit.parameters}
    assert by_data == {'frame_length': False, 'rocker_ab_length': False, 'coupler_length': False,
                       'rocker_cd_length': False, 'driven_joint_offset': True, 'sensor_offset': True}
    for p in fit.parameters:
        assert p.determined_by_data == (p.sd < calibration.DETERMINED_RATIO * p.prior_sd)
        assert 0.0 < p.sd <= p.prior_sd
    # posterior sds from the covariance, which is symmetric positive definite
    assert np.allclose(fit.covariance, fit.covariance.T)
    assert np.all(np.linalg.eigvalsh(fit.covariance) > 0.0)
    assert [p.sd for p in fit.parameters] == pytest.approx(list(np.sqrt(np.diag(fit.covariance))))


def test_a_tighter_prior_moves_the_lengths_less() -> None:
    q, y = readings(TRUTH, Driven.GAMMA, 2000, 1e-3, 5)
    loose = calibrate(q, y, DESIGN, Driven.GAMMA, CFG.measured_branch, length_sd=5e-4)
    tight = calibrate(q, y, DESIGN, Driven.GAMMA, CFG.measured_branch, length_sd=1e-6)
    assert np.max(np.abs(tight.values[:4] - DESIGN)) < np.max(np.abs(loose.values[:4] - DESIGN))
    assert np.max(np.abs(tight.values[:4] - DESIGN)) < 1e-5


def test_non_convergence_is_one_line() -> None:
    q, y = readings(TRUTH, Driven.GAMMA, 500, 1e-3, 1)
    with pytest.raises(CalibrationError, match=r'^the fit did not converge in 1 iterations') as info:
        calibrate(q, y, DESIGN, Driven.GAMMA, CFG.measured_branch, max_iterations=1)
    assert '\n' not in str(info.value)


def test_a_joint_the_given_geometry_cannot_take_is_refused() -> None:
    q, y = readings(TRUTH, Driven.GAMMA, 100, 1e-3, 1)
    q[7] = 3.0
    with pytest.raises(CalibrationError, match=r"1 of 100 measured joint angles are out of the given geometry's"):
        calibrate(q, y, DESIGN, Driven.GAMMA, CFG.measured_branch)
    q[7] = q[6]
    with pytest.raises(CalibrationError, match=r"^1 of 2 reference joint angles are out of the given geometry's "
                       r"reach \(first q=3\.0 rad\)"):
        calibrate(q, y, DESIGN, Driven.GAMMA, CFG.measured_branch,
                  references=[Reference(float(q[0]), 0.0, 1e-3), Reference(3.0, 0.0, 1e-3)])


def test_too_few_readings() -> None:
    with pytest.raises(CalibrationError, match='the fit needs more than 6'):
        calibrate(np.zeros(6), np.zeros(6), DESIGN, Driven.GAMMA, CFG.measured_branch)


def test_model_mismatch_for_one_reading_and_for_arrays() -> None:
    link = AntennaLinkage(*TRUTH[:3], rocker_cd=TRUTH[3])
    branch = CFG.measured_branch
    q, _ = readings(TRUTH, Driven.GAMMA, 50, 0.0, 2)
    exact = noiseless(TRUTH, q, Driven.GAMMA, branch)
    offsets = {'driven_joint_offset': float(TRUTH[4]), 'sensor_offset': float(TRUTH[5])}
    mismatch = model_mismatch(link, q, exact + 1e-3, Driven.GAMMA, branch, **offsets)
    assert isinstance(mismatch, np.ndarray)
    assert np.allclose(mismatch, 1e-3, rtol=0, atol=1e-15)
    one = model_mismatch(link, float(q[0]), float(exact[0]), Driven.GAMMA, branch, **offsets)
    assert isinstance(one, float)
    assert abs(one) < 1e-15
    # without the offsets, the mismatch is what the calibration removes
    assert abs(model_mismatch(link, float(q[0]), float(exact[0]), Driven.GAMMA, branch)) > 1e-3


# ---------------------------------------------------------------- the absolute angle, robustness, sanity

ANTENNA_TRUTH = np.array([*TRUTH[:5], 0.0])  # the true antenna angle at the measured joint: no sensor offset


def sweep_readings(n: int = 6000, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(measured q, sensor theta) of a slow sweep down and up over the tilt range (time order), 1 mrad noise."""
    rng = np.random.default_rng(seed)
    theta = 0.5 * (CFG.theta_min + CFG.theta_max) + 0.5 * (CFG.theta_max - CFG.theta_min) * np.cos(
        np.linspace(0.0, 4.0 * math.pi, n))
    link = AntennaLinkage(*TRUTH[:3], rocker_cd=TRUTH[3])
    q_true = np.asarray(link.rocker_angles(theta)[0])
    q = np.round((q_true - TRUTH[4]) / COUNT) * COUNT
    return q, theta + TRUTH[5] + rng.normal(0.0, 1e-3, n)


def absolute_error_in_sd(fit: calibration.Calibration, q: np.ndarray) -> tuple[float, float]:
    """(largest |node's angle - truth| / sd, largest |node's angle - truth| (rad)) over the swept joint range."""
    grid = np.linspace(q.min(), q.max(), 41)
    theta, sd = fit.angle(grid)
    error = np.abs(theta - predict(ANTENNA_TRUTH, grid, Driven.GAMMA, CFG.measured_branch))
    return float(np.max(error / sd)), float(np.max(error))


@pytest.mark.parametrize('seed', range(4))
def test_the_absolute_angle_is_within_four_sd_and_the_map_is_far_tighter(seed: int) -> None:
    q, y = sweep_readings(seed=seed)
    fit = calibrate(q, y, DESIGN, Driven.GAMMA, CFG.measured_branch)
    in_sd, _ = absolute_error_in_sd(fit, q)
    assert in_sd <= 4.0  # a Gaussian error passes 4 sd once in 16000
    grid = np.linspace(q.min(), q.max(), 41)
    reading, reading_sd = fit.angle(grid, with_sensor=True)
    assert np.all(np.abs(reading - predict(TRUTH, grid, Driven.GAMMA, CFG.measured_branch)) <= 4.0 * reading_sd)
    # the sensor map is fixed to hundredths of a mrad, the absolute angle only to mrad: the offsets trade
    assert np.max(reading_sd) < 1e-4 and np.min(fit.angle(grid)[1]) > 1e-3


def test_variance_sources_add_up_to_the_variance() -> None:
    q, y = sweep_readings()
    fit = calibrate(q, y, DESIGN, Driven.GAMMA, CFG.measured_branch, references=[Reference(float(q[100]), 0.0, 1e-3)])
    for joint in (float(q.min()), float(np.median(q))):
        parts = fit.variance_sources(joint)
        assert len(parts) == 1 + 6 + 1 and min(parts.values()) >= 0.0
        assert sum(parts.values()) == pytest.approx(float(fit.angle(joint)[1][0]) ** 2, rel=1e-9)


def test_a_reference_pins_the_absolute_angle() -> None:
    q, y = sweep_readings()
    joint = float(np.median(q))
    theta = float(predict(ANTENNA_TRUTH, np.array([joint]), Driven.GAMMA, CFG.measured_branch)[0])
    fit = calibrate(q, y, DESIGN, Driven.GAMMA, CFG.measured_branch, references=[Reference(joint, theta, 5e-5)])
    in_sd, error = absolute_error_in_sd(fit, q)
    assert error < 2e-4 and in_sd <= 4.0
    assert float(np.max(fit.angle(np.linspace(q.min(), q.max(), 41))[1])) < 2e-4


def test_a_datasheet_prior_on_the_sensor_offset_sets_the_absolute_angle() -> None:
    q, y = sweep_readings()
    fit = calibrate(q, y, DESIGN, Driven.GAMMA, CFG.measured_branch, sensor_offset=TRUTH[5] + 1e-4,
                    sensor_offset_sd=2e-4)
    in_sd, _ = absolute_error_in_sd(fit, q)
    assert in_sd <= 4.0
    joint = float(q.min())
    parts = fit.variance_sources(joint)
    assert max(parts, key=lambda k: parts[k]).startswith('the prior of sensor_offset')
    assert float(fit.angle(joint)[1][0]) < 2.5e-4  # the prior's 0.2 mrad, and the map's hundredths


def test_spikes_are_set_aside_and_do_not_inflate_the_noise() -> None:
    """Three +0.4 rad spikes and one +0.2 rad glitch among 6000: set aside, the noise is the sensor's; a plain
    least-squares fit (loss 'linear') keeps them and reports a noise nine times the sensor's."""
    q, y = sweep_readings()
    y[[700, 2500, 4100]] += 0.4
    y[3333] += 0.2
    fit = calibrate(q, y, DESIGN, Driven.GAMMA, CFG.measured_branch)
    assert fit.set_aside == 4 and not fit.kept[[700, 2500, 3333, 4100]].any()
    assert fit.sigma == pytest.approx(1e-3, rel=0.05)  # 6000 readings: the sd's own sd is 0.9%
    assert absolute_error_in_sd(fit, q)[0] <= 4.0
    plain = calibrate(q, y, DESIGN, Driven.GAMMA, CFG.measured_branch, loss='linear')
    assert plain.set_aside == 0 and plain.sigma > 5e-3


def test_a_trial_step_never_leaves_a_valid_linkage() -> None:
    """Readings in degrees pull the fit far from any linkage: every trial outside LENGTH_BOUND or that cannot
    assemble is refused, so the fit ends inside the bound (or says it did not converge), never on an invalid
    length."""
    q, y = sweep_readings(n=2000)
    try:
        fit = calibrate(q, np.degrees(y), DESIGN, Driven.GAMMA, CFG.measured_branch)
    except CalibrationError as exc:
        assert '\n' not in str(exc)
    else:
        assert np.all(np.abs(fit.values[:4] - DESIGN) <= LENGTH_BOUND * np.array(DESIGN))


@pytest.mark.parametrize(('scale', 'cause'), [(-1.0, 'its sign is flipped'), (math.degrees(1.0), 'reports degrees'),
                                              (3.0, 'the sensor or the parameter file is wrong')])
def test_the_sensor_scale_is_checked_before_the_fit(scale: float, cause: str) -> None:
    q, y = sweep_readings(n=2000)
    y[[5, 50]] = 0.4  # spikes do not move the robust scale
    good = sensor_scale(q, y, CFG.linkage, Driven.GAMMA, CFG.measured_branch)
    assert good == pytest.approx(1.0, abs=0.05)  # the design's lengths against the truth's: a few %
    check_sensor_scale(good)
    bad = sensor_scale(q, scale * y, CFG.linkage, Driven.GAMMA, CFG.measured_branch)
    assert bad == pytest.approx(scale * good, rel=1e-9)
    with pytest.raises(CalibrationError, match=cause) as info:
        check_sensor_scale(bad)
    assert str(info.value).startswith(f'the sensor moves {bad:.3g} times as far as the model')


def test_a_parameter_far_from_its_prior_is_named() -> None:
    q, y = sweep_readings(n=2000)
    fit = calibrate(q, y + 0.5, DESIGN, Driven.GAMMA, CFG.measured_branch)  # the sensor mounted 0.5 rad off
    far = far_from_prior(fit)
    assert len(far) == 1 and far[0].startswith('sensor_offset 0.50')
    assert far_from_prior(calibrate(q, y, DESIGN, Driven.GAMMA, CFG.measured_branch)) == []


def test_one_way_sweeps() -> None:
    down_up = np.cos(np.linspace(0.0, 2.0 * math.pi, 1000))
    assert one_way(down_up) == pytest.approx(1.0)
    assert one_way(down_up[:500]) < 0.01 < BOTH_WAYS_FRACTION  # down only: the counts' jitter at most
    assert one_way(np.cos(np.linspace(0.0, 1.3 * math.pi, 1000))) == pytest.approx((1.0 - math.cos(0.3 * math.pi))
                                                                                   / 2.0, rel=1e-3)


def test_correlated_noise_widens_the_sds_white_noise_does_not() -> None:
    """AR(1) noise of lag-1 correlation 0.9 holds (1 - 0.9) / (1 + 0.9) of the readings' information: the map's sds
    are sqrt(19) = 4.4 times a white noise's; white noise's correlation is not significant and leaves them."""
    q, white = sweep_readings(seed=5)
    rng = np.random.default_rng(5)
    noise = rng.normal(0.0, 1e-3, q.size)
    for i in range(1, q.size):
        noise[i] = 0.9 * noise[i - 1] + math.sqrt(1.0 - 0.81) * noise[i]
    correlated = predict(TRUTH, q, Driven.GAMMA, CFG.measured_branch) + noise  # the encoder's counts aside
    plain = calibrate(q, white, DESIGN, Driven.GAMMA, CFG.measured_branch)
    filtered = calibrate(q, correlated, DESIGN, Driven.GAMMA, CFG.measured_branch)
    assert plain.independent == 1.0 and abs(plain.correlation) < 2.0 / math.sqrt(q.size)
    assert filtered.correlation == pytest.approx(0.9, abs=0.03)  # the estimate's sd: 0.006
    grid = np.linspace(q.min(), q.max(), 41)
    ratio = filtered.angle(grid, with_sensor=True)[1] / plain.angle(grid, with_sensor=True)[1]
    assert np.all((ratio > 3.5) & (ratio < 5.5))  # sqrt(19) = 4.36, the noise sds alike within a few %
    in_sd = np.abs(filtered.angle(grid, with_sensor=True)[0] - predict(TRUTH, grid, Driven.GAMMA, CFG.measured_branch))
    assert np.all(in_sd <= 4.0 * filtered.angle(grid, with_sensor=True)[1])
