"""The benchmark's 50-digit reference: known values, loop closure, precision, reach, condition numbers."""

from __future__ import annotations

import math

import mpmath
import numpy as np
import pytest
from support.reference_table import FIRST_ORDER_ROWS

from benchmarks.cases import COMMON_GEOMETRIES, TURNANTENNA, sweep_angles, sweep_interval
from benchmarks.reference import (
    Geometry,
    ReferenceSingularError,
    ReferenceUnreachableError,
    angle_error,
    condition,
    loop_residual_mp,
    rates_mp,
    reach_float,
    reference_arrays,
    rocker_angles_mp,
)

# The 60-digit reference table (test/data/turnantenna_reference.csv): degrees; rates dimensionless.
REFERENCE_TABLE = FIRST_ORDER_ROWS

RANDOM = np.random.default_rng(12345)


def random_geometry(i: int) -> Geometry:
    """A random geometry that assembles (rockers long enough to span |H - h|)."""
    H, h = RANDOM.uniform(0.05, 2.0, 2)
    a = RANDOM.uniform(0.5, 2.0) * abs(H - h) + 0.01
    b = RANDOM.uniform(0.5, 1.5) * a
    return Geometry(f'random{i}', float(H), float(a), float(h), float(b))


@pytest.mark.parametrize(('deg', 'gamma', 'delta', 'dg', 'dd'), REFERENCE_TABLE)
def test_reference_reproduces_the_reference_table(deg: float, gamma: float, delta: float, dg: float, dd: float) -> None:
    theta = math.radians(deg)
    g, d = rocker_angles_mp(TURNANTENNA, theta)
    assert math.degrees(float(g)) == pytest.approx(gamma, abs=1e-11)
    assert math.degrees(float(d)) == pytest.approx(delta, abs=1e-11)
    rg, rd = rates_mp(TURNANTENNA, theta)
    assert rg == pytest.approx(dg, abs=1e-11)
    assert rd == pytest.approx(dd, abs=1e-11)


@pytest.mark.parametrize('branch', [1, -1])
def test_reference_closes_the_loop_on_random_geometries(branch: int) -> None:
    checked = 0
    for i in range(12):
        geo = random_geometry(i)
        for theta in RANDOM.uniform(-math.pi, math.pi, 8).tolist():
            try:
                g, d = rocker_angles_mp(geo, theta, branch)
            except ReferenceUnreachableError:
                continue
            r1, r2 = loop_residual_mp(geo, theta, g, d)
            assert abs(r1) < mpmath.mpf(10) ** -50 * (geo.frame + geo.coupler)
            assert abs(r2) < mpmath.mpf(10) ** -50 * (geo.frame + geo.coupler)
            # Branch: upper means B left of A -> D' (gamma + delta in [0, pi] modulo 2 pi), lower the mirror.
            s = float(mpmath.sin(g + d))
            assert s * branch >= -1e-40
            checked += 1
    assert checked > 20


def test_reference_agrees_with_twice_the_precision() -> None:
    geo = COMMON_GEOMETRIES[1]
    _, top = reach_float(geo)
    for theta in (0.3, -0.2, top, math.nextafter(top, 0.0), 1e15 + 0.25, 5e-324):
        try:
            lo = rocker_angles_mp(geo, theta, dps=60)
        except ReferenceUnreachableError:
            with pytest.raises(ReferenceUnreachableError):
                rocker_angles_mp(geo, theta, dps=120)
            continue
        hi = rocker_angles_mp(geo, theta, dps=120)
        for x, y in zip(lo, hi, strict=True):
            assert abs(x - y) < mpmath.mpf(10) ** -50


def test_reach_float_is_the_last_reachable_float() -> None:
    for geo in COMMON_GEOMETRIES[:3]:
        _, top = reach_float(geo)
        rocker_angles_mp(geo, top)
        rocker_angles_mp(geo, -top)
        with pytest.raises(ReferenceUnreachableError):
            rocker_angles_mp(geo, math.nextafter(top, math.inf))
    # Turnantenna reaches |theta| <= 39.33 deg (the rockers in line: |AD'| = 2 l).
    assert math.degrees(reach_float(TURNANTENNA)[1]) == pytest.approx(39.328, abs=1e-3)


def test_parallelogram_change_point_is_singular() -> None:
    geo = Geometry('p', 0.1, 0.06, 0.1, 0.06)
    with pytest.raises(ReferenceSingularError):
        rocker_angles_mp(geo, 0.0)
    rocker_angles_mp(geo, 1e-12)  # an arbitrarily small angle is fine


def test_condition_matches_finite_differences() -> None:
    """kappa from the implicit-function formulas against central differences of the reference itself."""
    geo = TURNANTENNA
    theta = 0.3
    kg, kd = condition(geo, theta)
    eta = 1e-20
    total_g = mpmath.mpf(0)
    total_d = mpmath.mpf(0)
    with mpmath.workdps(60):
        for field in ('theta', 'frame', 'rocker_ab', 'rocker_cd', 'coupler'):
            vals = []
            for sign in (1, -1):
                # Perturb in mp, then evaluate with the perturbed value passed through an mpf-aware geometry.
                factor = 1 + sign * mpmath.mpf(eta)
                if field == 'theta':
                    g, d = _angles_mp(geo, mpmath.mpf(theta) * factor, {})
                else:
                    g, d = _angles_mp(geo, mpmath.mpf(theta), {field: mpmath.mpf(getattr(geo, field)) * factor})
                vals.append((g, d))
            total_g += abs(vals[0][0] - vals[1][0]) / (2 * eta)
            total_d += abs(vals[0][1] - vals[1][1]) / (2 * eta)
    assert float(total_g) == pytest.approx(kg, rel=1e-10)
    assert float(total_d) == pytest.approx(kd, rel=1e-10)


def _angles_mp(geo: Geometry, theta: mpmath.mpf, override: dict[str, mpmath.mpf]) -> tuple[mpmath.mpf, mpmath.mpf]:
    """Upper-branch angles with mpf (not float) inputs, by the same triangle construction, for the FD test."""
    H = override.get('frame', mpmath.mpf(geo.frame))
    a = override.get('rocker_ab', mpmath.mpf(geo.rocker_ab))
    b = override.get('rocker_cd', mpmath.mpf(geo.rocker_cd))
    h = override.get('coupler', mpmath.mpf(geo.coupler))
    px, py = H - h * mpmath.cos(theta), h * mpmath.sin(theta)
    s2 = px**2 + py**2
    root = mpmath.sqrt(((a + b) ** 2 - s2) * (s2 - (a - b) ** 2))
    phi = mpmath.atan2(py, px)
    return phi + mpmath.atan2(root, a * a - b * b + s2), mpmath.atan2(root, b * b - a * a + s2) - phi


def test_angle_error_resolves_below_one_ulp_and_wraps() -> None:
    hi = np.array([1.0, math.pi, -math.pi + 1e-15])
    lo = np.array([1e-20, 0.0, 0.0])
    err = angle_error(np.array([1.0, -math.pi, math.pi]), hi, lo)
    assert err[0] == pytest.approx(1e-20, rel=1e-6)
    assert err[1] < 1e-15  # pi and -pi are the same angle
    assert err[2] == pytest.approx(1e-15, abs=1e-15)
    assert np.isnan(angle_error(np.array([math.nan]), np.array([0.0]), np.array([0.0])))[0]


def test_reference_arrays_status_and_sweep_inside_reach() -> None:
    geo = TURNANTENNA
    lo, hi = sweep_interval(geo)
    th = np.concatenate((sweep_angles(geo, 5), [1.0, -1.0]))
    ref = reference_arrays(geo, th)
    assert ref.status.tolist() == [0, 0, 0, 0, 0, 1, 1]
    assert np.isnan(ref.gamma_hi[-1])
    assert lo == -hi and hi == pytest.approx(0.99 * reach_float(geo)[1])
