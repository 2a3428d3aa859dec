"""The calibration fit (fourbar_ros.core.calibration): the exact Jacobian against finite differences, the truth
recovered from synthetic readings (lengths off by tenths of a mm, both offsets, noise, encoder counts), the honest
report of what the data determine, and the live check's residual."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fourbar_ros.config.antenna_config import default_config
from fourbar_ros.core import calibration
from fourbar_ros.core.antenna import AntennaLinkage, Branch, Driven
from fourbar_ros.core.calibration import (
    PARAMETER_NAMES,
    CalibrationError,
    calibrate,
    model_jacobian,
    model_mismatch,
    predict,
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
