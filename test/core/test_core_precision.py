"""Accuracy against an independent 60-digit evaluation (mpmath), including the numerically hard cases.

The bound every case must meet is BOUND ulps of the answer's condition: the error of a correctly rounded
input carried through the problem, eps * (|gamma| + 1 + |theta * d gamma/d theta|). It is not fitted to the
implementation: the annex formula as written (atan and acos) fails it near the reach limit, and so does any
formulation that cancels (see test_annex_formula_fails_the_same_bound).
"""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from mpmath import mpf
from support.ulp_bounds import second_derivative_scales

from benchmarks.reference import (
    Geometry,
    rates_numeric_mp,
    reach_float,
    reach_mp,
    rocker_angles_mp,
    second_derivatives_numeric_mp,
)
from benchmarks.reference import angle_error_mp as angle_error
from fourbar_ros import AntennaLinkage, Branch, InvalidGeometryError, SingularPositionError

BOUND = 8.0  # ulps of the condition-weighted magnitude
EPS = math.ulp(1.0)
#: The package solves an angle out of reach by no more than rounding as the limit pose; so does the reference.
LIMIT_SLACK = 1e-12


def antenna_angles(frame: float, ab: float, coupler: float, cd: float, theta: float,
                   branch: int = 1) -> tuple[mpf, mpf]:
    """The 60-digit reference (gamma, delta) of benchmarks.reference, solving the limit as above."""
    return rocker_angles_mp(Geometry('link', frame, ab, coupler, cd), theta, branch, limit_slack=LIMIT_SLACK)


def antenna_rates(frame: float, ab: float, coupler: float, cd: float, theta: float) -> tuple[mpf, mpf]:
    """The reference rates by numerical differentiation of the 60-digit angles."""
    return rates_numeric_mp(Geometry('link', frame, ab, coupler, cd), theta, limit_slack=LIMIT_SLACK)


def theta_limit(frame: float, ab: float, coupler: float, cd: float) -> mpf:
    """The outer reach limit theta_max at 60 digits (the rockers in line: |AD'| = AB + CD)."""
    return reach_mp(Geometry('link', frame, ab, coupler, cd))[1]


def condition(link: AntennaLinkage, theta: float, gamma: float, delta: float) -> tuple[float, float]:
    """Condition-weighted magnitudes of gamma and delta (radians): |q| + 1 + |theta dq/dtheta|.

    At the reach limit itself the rates are unbounded; there the weight is 1/sqrt(eps), the size of the
    rounding of a float that lies on the limit carried through the square root.
    """
    try:
        r = link.rates_at(theta, gamma, delta)
    except SingularPositionError:
        return (1.0 / math.sqrt(EPS),) * 2
    return (abs(gamma) + 1.0 + abs(theta * r.dgamma_dtheta), abs(delta) + 1.0 + abs(theta * r.ddelta_dtheta))


def check(link: AntennaLinkage, theta: float, branch: Branch = Branch.UPPER) -> float:
    """Assert the bound for one pose; return the worst error in units of its bound's eps."""
    g, d = link.rocker_angles(theta, branch)
    g_ref, d_ref = antenna_angles(link.frame, link.rocker_ab, link.coupler, float(link.rocker_cd or 0), theta,
                                  int(branch))
    cg, cd = condition(link, theta, g, d)
    eg, ed = angle_error(g, g_ref), angle_error(d, d_ref)
    assert eg <= BOUND * EPS * cg, (link, theta, eg, cg)
    assert ed <= BOUND * EPS * cd, (link, theta, ed, cd)
    # The array path is held to the same standard.
    ga, da = link.rocker_angles(np.array([theta]), branch)
    assert angle_error(float(ga[0]), g_ref) <= BOUND * EPS * cg
    assert angle_error(float(da[0]), d_ref) <= BOUND * EPS * cd
    return max(eg / (EPS * cg), ed / (EPS * cd))


def geometry(link: AntennaLinkage) -> Geometry:
    return Geometry('link', link.frame, link.rocker_ab, link.coupler, float(link.rocker_cd or 0))


#: check_second claims its bound where the angles' error bound is below this share of |sin(gamma + delta)|.
LINEAR = 1.0


def check_second(link: AntennaLinkage, theta: float, branch: Branch = Branch.UPPER) -> float:
    """Assert the bound for the second derivatives at one pose (scalar and array paths, each from its own angles);
    return the worst error in units of its bound's eps (0 where both paths' pose is the limit's own,
    sin(gamma + delta) == 0, which each path must report).

    The reference differentiates the 60-digit angles numerically (benchmarks.reference). The bound is BOUND ulps
    of ulp_bounds.second_derivative_scales: the angles' condition-weighted magnitudes carried through the
    closed form, plus its terms' rounding.
    """
    ref = second_derivatives_numeric_mp(geometry(link), theta, int(branch), limit_slack=LIMIT_SLACK)
    g, d = link.rocker_angles(theta, branch)
    ga, da = link.rocker_angles(np.array([theta]), branch)
    worst = 0.0
    for path, (gp, dp) in (('scalar', (g, d)), ('array', (float(ga[0]), float(da[0])))):
        if math.sin(gp + dp) == 0.0:  # the limit itself: unbounded, reported (the reference is huge but finite)
            if path == 'scalar':
                with pytest.raises(SingularPositionError, match='reach limit'):
                    link.rocker_second_derivatives(theta, branch)
            else:
                assert np.isnan(link.rocker_second_derivatives(np.array([theta]), branch)).all()
            continue
        got = (link.rocker_second_derivatives(theta, branch) if path == 'scalar' else
               [float(v[0]) for v in link.rocker_second_derivatives(np.array([theta]), branch)])
        cg, cd = condition(link, theta, gp, dp)
        if BOUND * EPS * (cg + cd) >= LINEAR * abs(math.sin(gp + dp)):
            # The angles' own error bound reaches sin X itself: q'' ~ 1/sin^3 X is then not linear in it, and no
            # bound of this form holds (another CPU's rounding moved q'' by 34 times the bound here). Only the
            # last floats before the reach limit: the value is finite, with no correct digit claimed.
            assert all(math.isfinite(v) for v in got), (link, theta, path, got)
            continue
        scales = second_derivative_scales(link.rocker_ab, float(link.rocker_cd or 0), link.coupler, theta, gp, dp,
                                          cg, cd)
        for name, value, want, scale in zip(('d2gamma', 'd2delta'), got, ref, scales, strict=True):
            err = float(abs(mpf(value) - want)) / (EPS * float(scale))
            assert err <= BOUND, (link, theta, branch, path, name, value, float(want), err)
            worst = max(worst, err)
    return worst


def random_links(seed: int, n: int, low: float = 0.05, high: float = 2.0) -> list[AntennaLinkage]:
    rng = np.random.default_rng(seed)
    links: list[AntennaLinkage] = []
    while len(links) < n:
        frame, ab, coupler, cd = (float(v) for v in rng.uniform(low, high, 4))
        try:
            links.append(AntennaLinkage(frame, ab, coupler, cd))
        except InvalidGeometryError:
            continue
    return links


def random_poses(link_seed: int, n_links: int, angle_seed: int, per_link: int
                 ) -> Iterator[tuple[AntennaLinkage, float, Branch]]:
    """``random_links(link_seed, n_links)``, each at ``per_link`` angles of random sign and magnitude inside its reach
    (drawn from ``angle_seed``), on both branches."""
    rng = np.random.default_rng(angle_seed)
    for link in random_links(link_seed, n_links):
        r = link.reach()
        for _ in range(per_link):
            mag = rng.uniform(r.theta_gap, r.theta_max) * 0.999 + r.theta_gap * 0.001
            theta = float(mag * rng.choice([-1.0, 1.0]))
            for branch in Branch:
                yield link, theta, branch


def test_random_geometries_both_branches() -> None:
    for link, theta, branch in random_poses(1, 60, 11, 4):
        check(link, theta, branch)


@pytest.mark.parametrize('digits', range(1, 16))
def test_toward_the_reach_limit(digits: int) -> None:
    # theta at relative distance 10^-digits inside the exact (60-digit) limit, rounded to the nearest float.
    links = [AntennaLinkage(0.180, 0.060, 0.102), *random_links(digits, 6)]
    for link in links:
        limit = theta_limit(link.frame, link.rocker_ab, link.coupler, float(link.rocker_cd or 0))
        theta = float(limit * (1 - mpf(10) ** -digits))
        if link.reach().theta_gap and theta < link.reach().theta_gap:
            continue
        check(link, theta)
        check(link, -theta)


def test_exact_limit_floats_all_solve() -> None:
    # The float nearest the exact limit, the package's own limit, and neighbours inside: solved, accurate.
    for link in [AntennaLinkage(0.180, 0.060, 0.102), *random_links(99, 40)]:
        limit = theta_limit(link.frame, link.rocker_ab, link.coupler, float(link.rocker_cd or 0))
        for start in {float(limit), link.reach().theta_max}:
            t = start
            for _ in range(3):
                if link.reach().contains(t):
                    check(link, t)
                t = math.nextafter(t, 0.0)


@pytest.mark.parametrize('k', [1, 3, 6, 9, 12, 15])
def test_frame_close_to_coupler(k: int) -> None:
    # H -> h approaches the parallelogram's change point at theta = 0.
    for sign in (1.0, -1.0):
        frame = 0.180
        coupler = frame * (1 + sign * 10.0**-k)
        link = AntennaLinkage(frame, 0.060, coupler)
        for theta in (1e-3, -1e-3, 1e-8, 0.1, -0.3, 1e-15):
            if link.reach().contains(theta):
                check(link, theta)


@pytest.mark.parametrize('exponent', range(-6, 7))
def test_scales(exponent: int) -> None:
    # Lengths from micrometres to thousands of kilometres: the angles depend only on ratios.
    s = 10.0**exponent
    base = AntennaLinkage(0.180, 0.060, 0.102)
    link = AntennaLinkage(0.180 * s, 0.060 * s, 0.102 * s)
    t = np.radians(np.linspace(-30, 30, 61))
    check(link, 0.3)
    g0, d0 = base.rocker_angles(t)
    g1, d1 = link.rocker_angles(t)
    assert np.max(np.abs(g1 - g0)) < 1e-14 and np.max(np.abs(d1 - d0)) < 1e-14
    assert link.input_torque(0.05, 3.5) == pytest.approx(base.input_torque(0.05, 3.5), rel=1e-14)


def test_subnormal_and_tiny_angles() -> None:
    link = AntennaLinkage(0.180, 0.060, 0.102)
    for theta in (5e-324, -5e-324, 1e-310, 1e-200, 1e-20):
        check(link, theta)


def test_full_turn_rhombus_near_theta_pi() -> None:
    # Angles the property test below draws: AB + CD = H + h, so the over-stretch factor vanishes at theta = pi;
    # formed as far0 - 4 H h sin^2(theta/2) it cancels (17-70 ulps of the condition); dyad forms it from pi past
    # |theta| = pi/2.
    link = AntennaLinkage(1.0, 1.0, 1.0, 1.0)
    for theta in (3.1354567304382504, 3.129320807286708):
        check(link, theta)


def test_large_and_wrapped_angles() -> None:
    link = AntennaLinkage(0.3, 0.4, 0.1, 0.35)  # AB + CD >= H + h: the coupler turns all the way round
    assert link.reach().theta_max == math.pi
    for theta in (3.0, math.pi, -math.pi, 10.0, 1e3, -1e6, 1e10):
        check(link, theta)


def test_rates_against_numerical_differentiation() -> None:
    for link in [AntennaLinkage(0.180, 0.060, 0.102), *random_links(5, 8)]:
        r = link.reach()
        for frac in (-0.7, -0.2, 0.1, 0.6):
            theta = frac * r.theta_max if not r.theta_gap else math.copysign(
                r.theta_gap + abs(frac) * (r.theta_max - r.theta_gap), frac)
            ours = link.rocker_rates(theta)
            ref = antenna_rates(link.frame, link.rocker_ab, link.coupler, float(link.rocker_cd or 0), theta)
            for got, want in zip(ours, ref, strict=True):
                assert abs(got - float(want)) <= 1e-13 * (1 + abs(float(want))), (link, theta)


@settings(max_examples=150, deadline=None)
@given(st.floats(0.01, 10.0), st.floats(0.01, 10.0), st.floats(0.01, 10.0), st.floats(0.01, 10.0),
       st.floats(-0.999, 0.999))
def test_property_any_geometry_any_reachable_angle(frame: float, ab: float, coupler: float, cd: float,
                                                  frac: float) -> None:
    try:
        link = AntennaLinkage(frame, ab, coupler, cd)
    except InvalidGeometryError:
        return  # never assembles: covered by the geometry tests
    r = link.reach()
    # A geometry that assembles in a single pose has no interval to sample (the limit tests cover poses at it),
    # and the parallelogram's change point is undetermined by definition (test_core_antenna covers the error).
    assume(r.theta_max - r.theta_gap > 1e-9)
    theta = math.copysign(r.theta_gap + abs(frac) * (r.theta_max - r.theta_gap), frac)
    # Within ~1e-154 rad of that change point the squared diagonal underflows and the solver reports the change
    # point too (documented in AntennaLinkage.rocker_angles).
    assume(not (frame == coupler and ab == cd and abs(theta) < 1e-150))
    check(link, theta)


def annex_formula(frame: float, rocker: float, coupler: float, theta: float) -> tuple[float, float]:
    """Annex A, A.13-A.15, as written (atan and acos)."""
    p = coupler * math.sin(theta) / (frame - coupler * math.cos(theta))
    q = (frame**2 + coupler**2 - 2 * frame * coupler * math.cos(theta)) / (2 * rocker**2) - 1
    return (2 * math.atan(p) + math.acos(q)) / 2, (math.acos(q) - 2 * math.atan(p)) / 2


def test_annex_formula_fails_the_same_bound() -> None:
    """The bound can fail: the annex's formula as written breaks it with a coupler longer than the frame
    (atan(P) lands on the wrong branch, off by pi) and raises at the float nearest the exact reach limit."""
    longer = AntennaLinkage(0.100, 0.040, 0.120)
    theta = 0.05
    g_ref, _ = antenna_angles(0.100, 0.040, 0.120, 0.040, theta)
    g, d = longer.rocker_angles(theta)
    cg, _ = condition(longer, theta, g, d)
    assert angle_error(g, g_ref) <= BOUND * EPS * cg
    g_annex, _ = annex_formula(0.100, 0.040, 0.120, theta)
    assert angle_error(g_annex, g_ref) > 1.0

    domain_errors = 0
    for sample in random_links(3, 200):
        try:
            link = AntennaLinkage(sample.frame, sample.rocker_ab, sample.coupler)  # the annex has equal rockers
        except InvalidGeometryError:
            continue
        limit = link.reach().theta_max
        try:
            annex_formula(link.frame, link.rocker_ab, link.coupler, limit)
        except ValueError:
            domain_errors += 1
        assert all(math.isfinite(v) for v in link.rocker_angles(limit))
    assert domain_errors > 0


# ---------------------------------------------------------------- second derivatives


def test_second_derivatives_random_geometries_both_branches() -> None:
    for link, theta, branch in random_poses(2, 30, 21, 3):
        check_second(link, theta, branch)


@pytest.mark.parametrize('digits', [1, 3, 6, 9, 12, 15])
def test_second_derivatives_toward_the_reach_limit(digits: int) -> None:
    # As test_toward_the_reach_limit: 10^-digits inside the exact outer limit, where they grow as 1/sin^3.
    for link in [AntennaLinkage(0.180, 0.060, 0.102), *random_links(100 + digits, 4)]:
        limit = reach_mp(geometry(link))[1]
        theta = float(limit * (1 - mpf(10) ** -digits))
        if theta < link.reach().theta_gap:
            continue
        for branch in Branch:
            check_second(link, theta, branch)
            check_second(link, -theta, branch)


@pytest.mark.parametrize('digits', [1, 3, 6, 9, 12])
def test_second_derivatives_toward_the_gap_limit(digits: int) -> None:
    # Rockers that differ by more than |frame - coupler| fold flat at theta_gap: gamma + delta -> pi, where the
    # closed form's terms AB g'^2 cos X and CD d'^2 would cancel (the more so the closer the rockers' lengths).
    for link in (AntennaLinkage(1.0, 0.5, 0.9, 0.3), AntennaLinkage(1.0, 0.5, 1.0 - 1e-6, 0.5 - 1e-3),
                 AntennaLinkage(0.4, 0.2, 0.45, 0.26)):
        gap = reach_mp(geometry(link))[0]
        assert gap > 0
        theta = float(gap * (1 + mpf(10) ** -digits))
        for branch in Branch:
            check_second(link, theta, branch)


def test_second_derivatives_at_the_limit_floats() -> None:
    # The last float inside the exact limit, the package's own limit float and their neighbours inside: either the
    # pose is the limit's own (reported) or the values meet the bound (which there allows no correct digit).
    seen_limit = 0
    for link in [AntennaLinkage(0.180, 0.060, 0.102), *random_links(7, 12)]:
        for start in {reach_float(geometry(link))[1], link.reach().theta_max}:
            t = start
            for _ in range(3):
                if link.reach().contains(t) and t <= reach_float(geometry(link))[1]:
                    check_second(link, t)
                    seen_limit += math.sin(sum(link.rocker_angles(t))) == 0.0  # the scalar (math module) path
                t = math.nextafter(t, 0.0)
    assert seen_limit > 0  # the limit's own pose is among them (sin(gamma + delta) rounds to 0 there)
