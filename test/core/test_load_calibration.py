"""The load model fitted to the measured effort (fourbar_ros.core.load_calibration): the exact Jacobian against
central differences, the truth recovered within 4 sd over seeds, readings at rest left out, too few refused."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fourbar_ros.config.antenna_config import default_config
from fourbar_ros.core.antenna import Driven
from fourbar_ros.core.calibration import CalibrationError
from fourbar_ros.core.completion import inverse_branch
from fourbar_ros.core.load_calibration import LOAD_NAMES, calibrate_load, effort_model, load_pose

CFG = default_config()
LINK = CFG.linkage
G = 9.80665
TRUTH = np.array([2.0, 0.03, 0.02, 0.05, 0.7])  # kg, m, m, N m, efficiency


def sweep(driven: Driven, seconds: float = 240.0) -> tuple[np.ndarray, np.ndarray]:
    """(q rad, q_dot rad/s) of a cosine sweep over the tilt range, one cycle a minute, at 100 Hz."""
    t = np.arange(0.0, seconds, 0.01)
    mid, half = 0.5 * (CFG.theta_max + CFG.theta_min), 0.5 * (CFG.theta_max - CFG.theta_min)
    w = 2.0 * math.pi / 60.0
    theta, theta_rate = mid + half * np.cos(w * t), -half * w * np.sin(w * t)
    g, d = LINK.rocker_angles(theta)
    rates = LINK.rates_at(theta, g, d)
    if driven is Driven.GAMMA:
        return np.asarray(g), theta_rate * np.asarray(rates.dgamma_dtheta)
    return np.asarray(d), theta_rate * np.asarray(rates.ddelta_dtheta)


@pytest.mark.parametrize('driven', list(Driven))
def test_jacobian_matches_central_differences(driven: Driven) -> None:
    q, q_rate = sweep(driven, 60.0)
    pose = load_pose(LINK, q[::50], q_rate[::50], driven, inverse_branch(LINK, 0.0, driven, CFG.branch))
    _, jac = effort_model(TRUTH, pose, G)
    for i, name in enumerate(LOAD_NAMES):
        h = 1e-6
        up, down = TRUTH.copy(), TRUTH.copy()
        up[i] += h
        down[i] -= h
        fd = (effort_model(up, pose, G)[0] - effort_model(down, pose, G)[0]) / (2.0 * h)
        assert np.allclose(jac[:, i], fd, rtol=1e-6, atol=1e-9), name


@pytest.mark.parametrize('seed', range(3))
def test_fit_recovers_the_load_within_four_sd(seed: int) -> None:
    driven = Driven.GAMMA
    branch = CFG.measured_branch
    q, q_rate = sweep(driven)
    effort = effort_model(TRUTH, load_pose(LINK, q, q_rate, driven, branch), G)[0]
    noisy = effort + np.random.default_rng(seed).normal(0.0, 0.02, effort.size)
    fit, used = calibrate_load(LINK, q, q_rate, noisy, driven, branch, G)
    assert 0.8 * q.size < int(np.count_nonzero(used)) < q.size  # the turnarounds (at rest) left out
    for p, truth in zip(fit.parameters, TRUTH, strict=True):
        assert abs(p.value - truth) <= 4.0 * p.sd, (p.name, p.value, truth, p.sd)
        assert p.determined_by_data, p.name
    assert fit.sigma == pytest.approx(0.02, rel=0.05)


def test_a_joint_at_rest_cannot_fit_the_load() -> None:
    q, _ = sweep(Driven.GAMMA, 10.0)
    with pytest.raises(CalibrationError, match=r'^0 readings of a moving joint with an effort: too few'):
        calibrate_load(LINK, q, np.zeros(q.size), np.ones(q.size), Driven.GAMMA, CFG.measured_branch, G)
