"""The general four-bar (lecture notes): Freudenstein's equation, both branches, velocity ratio, statics."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from support.ulp_bounds import CHAIN_ULPS, angle_scale, assert_close_ulps, sine_ratio_scale

from fourbar_ros import (
    AntennaLinkage,
    DeadPointError,
    FourBar,
    InvalidGeometryError,
    SingularPositionError,
    UnreachableError,
)
from fourbar_ros.core.transforms import fourbar_joint_positions, rot, trans

CRANK_ROCKER = FourBar(ground=4.0, crank=1.0, coupler=3.5, rocker=3.0)


def crank_angles(fb: FourBar, n: int = 361) -> np.ndarray:
    if fb.crank_max == math.pi and fb.crank_gap == 0.0:
        return np.linspace(-math.pi, math.pi, n)
    lo = fb.crank_gap + 1e-3 * (fb.crank_max - fb.crank_gap)
    hi = fb.crank_max - 1e-3 * (fb.crank_max - fb.crank_gap)
    return np.concatenate([np.linspace(lo, hi, n // 2), -np.linspace(lo, hi, n // 2)])


def test_freudenstein_constants_standard_form() -> None:
    k1, k2, k3 = CRANK_ROCKER.freudenstein_constants()
    assert k1 == 4.0 and k2 == 4.0 / 3.0
    assert k3 == pytest.approx((16 + 1 - 12.25 + 9) / (2 * 1 * 3.0), rel=1e-15)


@pytest.mark.parametrize('branch', [1, -1])
def test_poses_satisfy_freudenstein_and_close_the_loop(branch: int) -> None:
    assert CRANK_ROCKER.is_grashof() and CRANK_ROCKER.crank_max == math.pi  # a full-turn crank
    t2 = crank_angles(CRANK_ROCKER)
    t3, t4 = CRANK_ROCKER.angles(t2, branch)
    assert np.max(np.abs(CRANK_ROCKER.freudenstein_residual(t2, t4))) < 1e-14
    pos = fourbar_joint_positions(4.0, 1.0, 3.5, 3.0, t2, t3, t4)
    assert np.max(pos.residual) < 1e-14
    # Branch +1 has C to the left of the diagonal B -> O4, -1 to the right.
    bd, bc = pos.d - pos.b, pos.c - pos.b
    cross = bd[:, 0] * bc[:, 1] - bd[:, 1] * bc[:, 0]
    assert np.all(np.sign(cross) == branch)


def angle_scales(fb: FourBar, t2: np.ndarray, t3: np.ndarray, t4: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Condition-weighted magnitudes (rad) of t3 and t4: 1 + |q| + |t2 dq/dt2| (ulp_bounds.angle_scale).

    dt4/dt2 is the velocity ratio; dt3/dt2 = l2 sin(t4 - t2) / (l3 sin(t3 - t4)) from differentiating the loop.
    """
    with np.errstate(divide='ignore', invalid='ignore'):
        dt3 = fb.crank * np.sin(t4 - t2) / (fb.coupler * np.sin(t3 - t4))
    return angle_scale(t3, t2, dt3), angle_scale(t4, t2, fb.velocity_ratio(t2))


def test_scalar_and_array_paths_agree() -> None:
    t2 = crank_angles(CRANK_ROCKER, 41)
    t3, t4 = CRANK_ROCKER.angles(t2)
    scalar = [CRANK_ROCKER.angles(float(t)) for t in t2]
    s3, s4 = angle_scales(CRANK_ROCKER, t2, t3, t4)
    # numpy vs math transcendentals (1-2 ulp each, a handful in the chain): CHAIN_ULPS ulps of the
    # condition-weighted magnitude.
    assert_close_ulps(t3, [a.t3 for a in scalar], CHAIN_ULPS, s3, 't3 array vs scalar')
    assert_close_ulps(t4, [a.t4 for a in scalar], CHAIN_ULPS, s4, 't4 array vs scalar')


def test_velocity_ratio_matches_notes_form_and_finite_differences() -> None:
    k1, k2, _ = CRANK_ROCKER.freudenstein_constants()
    for t2 in crank_angles(CRANK_ROCKER, 73):
        _, t4 = CRANK_ROCKER.angles(float(t2))
        vr = CRANK_ROCKER.velocity_ratio(float(t2))
        # The notes' form, differentiated from Freudenstein's equation with the correct constants:
        # dt2/dt4 = (K1 sin t4 + sin(t2 - t4)) / (K2 sin t2 + sin(t2 - t4)).
        notes = (k1 * math.sin(t4) + math.sin(t2 - t4)) / (k2 * math.sin(t2) + math.sin(t2 - t4))
        assert vr * notes == pytest.approx(1.0, rel=1e-10)
        h = 1e-6
        fd = (CRANK_ROCKER.angles(float(t2) + h).t4 - CRANK_ROCKER.angles(float(t2) - h).t4) / (2 * h)
        assert vr == pytest.approx(fd, rel=1e-7, abs=1e-9)
        assert CRANK_ROCKER.mechanical_advantage(float(t2)) * vr == pytest.approx(1.0, rel=1e-13)


def test_array_statics_match_scalar() -> None:
    fb = CRANK_ROCKER
    t2 = crank_angles(fb, 21)
    vr = fb.velocity_ratio(t2)
    ma = fb.mechanical_advantage(t2)
    t3, t4 = fb.angles(t2)
    s3, s4 = angle_scales(fb, t2, t3, t4)
    # vr = l2 sin(t2 - t3) / (l4 sin(t4 - t3)) and ma = 1/vr, with angles good to CHAIN_ULPS ulps of their scales
    # (t2 is exact): CHAIN_ULPS ulps of sine_ratio_scale, whose cotangents carry the amplification near a toggle.
    vr_scale = sine_ratio_scale(fb.crank / fb.rocker, t2 - t3, s3, t4 - t3, s3 + s4)
    ma_scale = sine_ratio_scale(fb.rocker / fb.crank, t4 - t3, s3 + s4, t2 - t3, s3)
    assert_close_ulps(vr, [fb.velocity_ratio(float(t)) for t in t2], CHAIN_ULPS, vr_scale, 'velocity ratio')
    assert_close_ulps(ma, [fb.mechanical_advantage(float(t)) for t in t2], CHAIN_ULPS, ma_scale, 'MA')


def test_antenna_is_the_four_bar_with_its_rocker_as_crank() -> None:
    link = AntennaLinkage(0.180, 0.060, 0.102)
    fb = FourBar(0.180, 0.060, 0.102, 0.060)
    theta = np.radians(np.linspace(-6, 7, 14))
    g, d = link.rocker_angles(theta)
    t3, t4 = fb.angles(g)
    assert np.allclose(-t3, theta, rtol=0, atol=1e-14)
    assert np.allclose(math.pi - t4, d, rtol=0, atol=1e-14)


def test_matrix_chain_matches_closed_form() -> None:
    # The notes' product R(a2) T(l2) R(a3) T(l3) applied to the origin.
    a2, a3, l2, l3 = 0.4, -1.1, 2.0, 1.5
    m = rot(a2) @ trans(l2) @ rot(a3) @ trans(l3)
    x = l2 * math.cos(a2) + l3 * math.cos(a2 + a3)
    y = l2 * math.sin(a2) + l3 * math.sin(a2 + a3)
    assert m[0, 2] == pytest.approx(x, abs=1e-15) and m[1, 2] == pytest.approx(y, abs=1e-15)
    assert m[0, 0] == pytest.approx(math.cos(a2 + a3), abs=1e-15)


@settings(max_examples=200, deadline=None)
@given(st.floats(0.05, 5.0), st.floats(0.05, 5.0), st.floats(0.05, 5.0), st.floats(0.05, 5.0),
       st.floats(0.0, 1.0), st.sampled_from([1, -1]))
def test_property_closure(l1: float, l2: float, l3: float, l4: float, frac: float, branch: int) -> None:
    try:
        fb = FourBar(l1, l2, l3, l4)
    except InvalidGeometryError:
        return
    assume(fb.crank_max > fb.crank_gap)  # a single-pose linkage has no interval to sample
    t2 = fb.crank_gap + frac * (fb.crank_max - fb.crank_gap)
    # The change point (covered below), and angles so close to it that the squared diagonal underflows.
    assume(not (l1 == l2 and abs(t2) < 1e-150))
    t3, t4 = fb.angles(t2, branch)
    pos = fourbar_joint_positions(l1, l2, l3, l4, t2, t3, t4)
    assert float(pos.residual) < 1e-14 * 16 * max(l1, l2, l3, l4)
    assert abs(fb.freudenstein_residual(t2, t4)) < 1e-12 * (1 + sum(map(abs, fb.freudenstein_constants())))


def test_toggle_and_change_point_are_reported() -> None:
    # Crank 1 in line with coupler 3 at t2 = pi reaching rocker... use a non-Grashof linkage's crank limit.
    fb = FourBar(ground=2.0, crank=1.5, coupler=1.0, rocker=1.2)
    assert not fb.is_grashof()
    t3, t4 = fb.angles(fb.crank_max)  # the exact limit closes (coupler and rocker in line)
    assert math.isfinite(t3) and math.isfinite(t4)
    with pytest.raises(DeadPointError, match='rocker is in line with the coupler'):
        fb.velocity_ratio(fb.crank_max)
    with pytest.raises(UnreachableError, match='cannot close the loop'):
        fb.angles(fb.crank_max + 1e-9)
    with pytest.raises(UnreachableError, match='not a finite angle'):
        fb.angles(math.nan)
    with pytest.raises(UnreachableError, match=r'crank angles cannot close the loop'):
        fb.angles(np.array([0.0, 3.0]))
    par = FourBar(1.0, 1.0, 0.5, 0.5)
    with pytest.raises(SingularPositionError, match='change point'):
        par.angles(0.0)


def test_invalid_four_bar() -> None:
    with pytest.raises(InvalidGeometryError, match='never assembles'):
        FourBar(10.0, 1.0, 1.0, 1.0)
    with pytest.raises(InvalidGeometryError, match=r'crank=0\.0 m must be finite and positive'):
        FourBar(1.0, 0.0, 1.0, 1.0)
