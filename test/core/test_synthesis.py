"""Freudenstein synthesis: recovery of known linkages, degenerate and unbuildable requests, least squares,
branch reporting, and the `fourbar design` command.

Pairs are generated with the core's position solver (FourBar.angles); every claim about the designed linkage is
also checked independently of that solver where it can be (loop closure from the lengths and angles, the branch
from the side of B->O4 that C lies on, the Freudenstein residual from the textbook formula).
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from support.cli_support import fourbar
from support.reference_table import FLOAT_ROWS

from fourbar_ros.commands import main as cli_main
from fourbar_ros.core.errors import InvalidGeometryError, SingularPositionError
from fourbar_ros.core.general import FourBar
from fourbar_ros.core.synthesis import (
    DegenerateDesignError,
    DesignError,
    UnbuildableDesignError,
    freudenstein_system,
    lengths_from_constants,
    synthesize,
)

EPS = float(np.finfo(float).eps)

# (ground, crank, coupler, rocker): one of each Grashof class, plus a long-coupler and a tiny-rocker case.
LINKAGES = {
    'crank-rocker': (1.0, 0.3, 0.9, 0.7),
    'double-crank': (0.4, 1.0, 0.9, 0.8),
    'double-rocker': (1.0, 0.8, 0.3, 0.9),
    'triple-rocker': (1.0, 0.8, 0.6, 0.7),
    'long coupler': (0.5, 0.4, 3.0, 2.8),
    'metres scale': (180.0, 60.0, 102.0, 60.0),
}


def pairs_of(fb: FourBar, t2s: list[float], branches: list[int]) -> list[tuple[float, float]]:
    return [(t2, float(fb.angles(t2, b).t4)) for t2, b in zip(t2s, branches, strict=True)]


def spread_angles(fb: FourBar, n: int) -> list[float]:
    """n crank angles spread over the crank's closing interval (positive side), away from its ends."""
    lo, hi = fb.crank_gap, fb.crank_max
    return [lo + (hi - lo) * (i + 1) / (n + 1) for i in range(n)]


def rel_err(design_lengths: tuple[float, float, float], true: tuple[float, float, float]) -> float:
    return max(abs(a - b) / b for a, b in zip(design_lengths, true, strict=True))


def side_of_b_o4(fb_lengths: tuple[float, float, float, float], t2: float, t4: float) -> float:
    """Cross product (O4 - B) x (C - B) from the lengths and the requested angles: > 0 when C is left of B->O4."""
    l1, l2, _, l4 = fb_lengths
    bx, by = l2 * math.cos(t2), l2 * math.sin(t2)
    cx, cy = l1 + l4 * math.cos(t4), l4 * math.sin(t4)
    return (l1 - bx) * (cy - by) - (0.0 - by) * (cx - bx)


# ---------------------------------------------------------------- recovery of known linkages


@pytest.mark.parametrize('name', sorted(LINKAGES))
@pytest.mark.parametrize('branch', [1, -1])
def test_three_positions_recover_known_linkage(name: str, branch: int) -> None:
    lengths = LINKAGES[name]
    fb = FourBar(*lengths)
    pairs = pairs_of(fb, spread_angles(fb, 3), [branch] * 3)
    d = synthesize(pairs, ground=lengths[0])
    assert rel_err((d.crank, d.coupler, d.rocker), lengths[1:]) <= 1e-12
    for got, want in zip((d.k1, d.k2, d.k3), fb.freudenstein_constants(), strict=True):
        assert abs(got - want) <= 1e-12 * abs(want)
    assert d.branch == branch and not d.mixed_branches
    assert d.max_t4_error is not None and d.max_t4_error <= 1e-12
    assert d.residual <= 1e-14
    assert not d.crank_flipped and not d.rocker_flipped
    assert d.grashof_type == name or name in ('long coupler', 'metres scale')
    # Independent of the position solver: the designed lengths close the loop at every requested pair, and the
    # reported branch is the side of B->O4 that C lies on.
    for p in d.pairs:
        bx, by = d.crank * math.cos(p.t2), d.crank * math.sin(p.t2)
        cx, cy = d.ground + d.rocker * math.cos(p.t4), d.rocker * math.sin(p.t4)
        assert abs(math.hypot(cx - bx, cy - by) - d.coupler) <= 1e-12 * d.coupler
        assert math.copysign(1, side_of_b_o4((d.ground, d.crank, d.coupler, d.rocker), p.t2, p.t4)) == p.branch


def test_turnantenna_linkage_from_the_reference_table() -> None:
    """The antenna linkage is a four-bar with ground AD, crank AB (t2 = gamma) and rocker DC (t4 = pi - delta).
    The three rows of the 60-digit reference table (test/data/turnantenna_reference.csv, -6, 0, +7 deg) must give
    back Turnantenna's 60 / 102 / 60 mm, to within what double precision allows: each angle is good to a few ulps
    of pi (the float of the table's degrees, radians(), pi - delta), and the lengths to sensitivity times that."""
    pairs = [(math.radians(r.gamma_deg), math.pi - math.radians(r.delta_deg)) for r in FLOAT_ROWS]
    d = synthesize(pairs, ground=0.180)
    bound = d.sensitivity * 4 * EPS * math.pi
    assert 1e-14 < bound < 1e-12
    assert rel_err((d.crank, d.coupler, d.rocker), (0.060, 0.102, 0.060)) <= bound
    assert d.k1 == pytest.approx(3.0, rel=bound) and d.k2 == pytest.approx(3.0, rel=bound)
    assert d.k3 == pytest.approx((0.18**2 + 0.06**2 - 0.102**2 + 0.06**2) / (2 * 0.06 * 0.06), rel=2 * bound)
    assert d.branch == 1 and d.grashof_type == 'triple-rocker'


def test_ground_sets_the_scale_only() -> None:
    fb = FourBar(*LINKAGES['crank-rocker'])
    pairs = pairs_of(fb, [0.4, 1.2, 2.1], [1, 1, 1])
    unit = synthesize(pairs)
    big = synthesize(pairs, ground=0.18)
    assert (unit.k1, unit.k2, unit.k3) == (big.k1, big.k2, big.k3)
    assert big.crank == pytest.approx(0.18 * unit.crank, rel=1e-15)
    assert big.coupler == pytest.approx(0.18 * unit.coupler, rel=1e-15)
    assert big.rocker == pytest.approx(0.18 * unit.rocker, rel=1e-15)


def test_solved_form_keeps_digits_the_textbook_matrix_loses() -> None:
    """Crank angles near 0 (cos t2 flat) with a long crank swinging a tiny rocker far: the problem itself is
    well-conditioned (problem_condition about 117), but solving the textbook matrix (condition number 7.7e4)
    loses the rocker's digits; the solved form keeps them. (Found by a random search over 10 000 linkages.)

    How many digits the textbook route loses depends on how cos rounds (one ulp more or less on another CPU), so
    both routes are run on the pairs and on each pair set with one angle moved by one ulp (13 sets): the solved
    form meets 1e-12 on every set, the textbook route misses it on some."""
    lengths = (9.278414375761113, 9.479454340062729, 0.3801119772901776, 0.20165612748593023)
    fb = FourBar(*lengths)
    pairs = pairs_of(fb, [-0.03662915289417647, 0.0097128838956452, 0.015248535337307292], [-1, -1, -1])
    assert problem_condition(lengths, pairs) < 200
    l1 = lengths[0]
    variants = [pairs]
    for i in range(len(pairs)):
        for j in range(2):
            for toward in (-math.inf, math.inf):
                moved = [list(p) for p in pairs]
                moved[i][j] = math.nextafter(moved[i][j], toward)
                variants.append([(t2, t4) for t2, t4 in moved])
    naive_errors = []
    for v in variants:
        a, b = freudenstein_system(v)
        k = np.linalg.solve(a, b)
        naive = (l1 / k[0],
                 math.sqrt(l1 * l1 + (l1 / k[0]) ** 2 + (l1 / k[1]) ** 2 - 2 * l1 * l1 / k[0] / k[1] * k[2]),
                 l1 / k[1])
        naive_errors.append(rel_err(naive, lengths[1:]))
        d = synthesize(v, ground=l1)
        assert rel_err((d.crank, d.coupler, d.rocker), lengths[1:]) <= 1e-12  # the solved form meets it ...
        assert d.condition_number == pytest.approx(float(np.linalg.cond(a)), rel=1e-12)
    assert max(naive_errors) > 1e-12  # ... the textbook route misses it


def problem_condition(lengths: tuple[float, float, float, float], pairs: list[tuple[float, float]]) -> float:
    """First-order condition number of synthesis itself: the largest relative change of a length per unit
    absolute change (in units of max(1, |angle|)) of the six input angles, summed over the angles (worst case).

    From Freudenstein's equations A K = b: dK = -A^-1 e_i (d residual_i), residual_i' = (K2 sin t2 + sin(t2 - t4))
    dt2 + (-K1 sin t4 - sin(t2 - t4)) dt4; then l2 = l1/K1, l4 = l1/K2 and
    l3^2 = l1^2 + l2^2 + l4^2 - 2 l2 l4 K3 to first order.
    """
    l1, l2, l3, l4 = lengths
    k1, k2, k3 = l1 / l2, l1 / l4, (l1 * l1 + l2 * l2 - l3 * l3 + l4 * l4) / (2.0 * l2 * l4)
    a, _ = freudenstein_system(pairs)
    try:
        ainv = np.linalg.inv(a)
    except np.linalg.LinAlgError:  # exactly singular: the pairs do not determine the constants
        return math.inf
    cols = []
    for i, (t2, t4) in enumerate(pairs):
        d2 = (k2 * math.sin(t2) + math.sin(t2 - t4)) * max(1.0, abs(t2))
        d4 = (-k1 * math.sin(t4) - math.sin(t2 - t4)) * max(1.0, abs(t4))
        cols += [-ainv[:, i] * d2, -ainv[:, i] * d4]
    dk1, dk2, dk3 = np.array(cols).T
    dl2, dl4 = -l2 * dk1 / k1, -l4 * dk2 / k2
    dl3 = (l2 * dl2 + l4 * dl4 - k3 * (l4 * dl2 + l2 * dl4) - l2 * l4 * dk3) / l3
    return float(max(np.abs(dl2 / l2).sum(), np.abs(dl3 / l3).sum(), np.abs(dl4 / l4).sum()))


lengths_st = st.floats(math.log(0.1), math.log(10.0)).map(math.exp)


@st.composite
def linkages_with_pairs(draw: st.DrawFn) -> tuple[tuple[float, float, float, float], list[tuple[float, float]]]:
    """A random four-bar and three positions of it, generated with the position solver (filters: see comments).

    Ground, crank and rocker are 0.1..10 (log-uniform); the coupler is the B-C distance of a random pose, so the
    linkage assembles by construction. The three crank angles lie anywhere in the crank's closing interval
    (either sign), all on one random branch.
    """
    l1, l2, l4 = draw(lengths_st), draw(lengths_st), draw(lengths_st)
    a, b = draw(st.floats(-math.pi, math.pi)), draw(st.floats(-math.pi, math.pi))
    l3 = math.hypot(l2 * math.cos(a) - l1 - l4 * math.cos(b), l2 * math.sin(a) - l4 * math.sin(b))
    assume(l3 > 0.0)  # B on C: no coupler, not a four-bar
    try:
        fb = FourBar(l1, l2, l3, l4)
    except InvalidGeometryError:  # a collinear pose that is the linkage's only one (e.g. l2 = l1 + l3 + l4):
        assume(False)             # whether the rounded l3 still closes the loop is up to rounding
    branch = draw(st.sampled_from([1, -1]))
    t2s = [math.copysign(fb.crank_gap + draw(st.floats(0.0, 1.0)) * (fb.crank_max - fb.crank_gap),
                         draw(st.sampled_from([1.0, -1.0]))) for _ in range(3)]
    try:
        pairs = pairs_of(fb, t2s, [branch] * 3)
    except SingularPositionError:  # a change point (ground = crank at t2 = 0): the rocker angle is undetermined
        assume(False)
    return (l1, l2, l3, l4), pairs


#: Largest error / (problem_condition * eps) found by an exploratory hypothesis search that maximised it with
#: target() over 3000 draws of this generator (kappa up to 3e3; not part of the suite): 34. The bounds below leave
#: a factor of about 3 over it; test_hypothesis_error_tracks_condition re-checks the 100 kappa eps bound each run.
KAPPA_FOR_1E12 = 90.0


@settings(max_examples=300, deadline=None, derandomize=True)
@given(linkages_with_pairs())
def test_hypothesis_three_positions_recover_lengths(
        case: tuple[tuple[float, float, float, float], list[tuple[float, float]]]) -> None:
    """Random linkages and positions: lengths recovered to 1e-12 relative.

    Filtered, besides the generator's own two cases (no coupler; a change point): draws whose problem condition
    number kappa (problem_condition) exceeds KAPPA_FOR_1E12. Rounding the six angles to double precision alone
    moves the lengths by up to kappa * eps, and synthesis errs by up to 34 kappa eps, so 1e-12 is a promise only
    for kappa <= 1e-12 / (34 * 3 * eps) = 90 -- these near-degenerate draws (positions almost coinciding in
    (cos t2, cos t4), near a toggle, extreme length ratios) are covered by test_hypothesis_error_tracks_condition.
    """
    lengths, pairs = case
    l1, l2, l3, l4 = lengths
    assume(problem_condition(lengths, pairs) <= KAPPA_FOR_1E12)
    d = synthesize(pairs, ground=l1)
    assert rel_err((d.crank, d.coupler, d.rocker), (l2, l3, l4)) <= 1e-12
    branch = 1 if max((side_of_b_o4(lengths, t2, t4) for t2, t4 in pairs), key=abs) > 0 else -1
    for p in d.pairs:
        # Away from a toggle (C on the line B-O4, sin psi = 0, where t4 moves like the square root of a length
        # change and either branch is right to rounding) and from a change point (B on O4, where any t4 fits),
        # the linkage passes the pair on the generated branch.
        diag = math.hypot(l1 - l2 * math.cos(p.t2), l2 * math.sin(p.t2))
        if diag < 1e-6 * max(lengths):
            continue
        sin_psi = side_of_b_o4(lengths, p.t2, p.t4) / (l3 * diag)
        if abs(sin_psi) >= 1e-3:
            assert p.branch == branch
            bound = t4_bound(lengths, p.t2, p.t4)
            assert p.t4_error is not None and p.t4_error <= bound, (p, bound)


def t4_bound(lengths: tuple[float, float, float, float], t2: float, t4: float) -> float:
    """How far (rad) the designed linkage's rocker angle may be from the pair's at crank angle t2: Freudenstein's
    F = K1 cos t4 - K2 cos t2 + K3 - cos(t2 - t4) moves by dF when the K's do, and t4 by dF / |dF/dt4|. Lengths
    recovered to 1e-12 relative move K1 = l1/l2 and K2 = l1/l4 by 2e-12 of themselves and K3 by 2e-12 of
    (l1^2 + l2^2 + l3^2 + l4^2) / (2 l2 l4) + 2e-12 |K3|; the pair's own t4 and F's evaluation round by a few eps of
    F's terms (64 eps). Near a change point or a toggle |dF/dt4| is small and the bound grows with 1/|dF/dt4|."""
    l1, l2, l3, l4 = lengths
    k1, k2, k3 = l1 / l2, l1 / l4, (l1 * l1 + l2 * l2 - l3 * l3 + l4 * l4) / (2 * l2 * l4)
    dk3 = 2e-12 * ((l1 * l1 + l2 * l2 + l3 * l3 + l4 * l4) / (2 * l2 * l4) + abs(k3))
    terms = abs(k1 * math.cos(t4)) + abs(k2 * math.cos(t2)) + abs(k3) + 1.0
    df = 2e-12 * (abs(k1 * math.cos(t4)) + abs(k2 * math.cos(t2))) + dk3 + 64 * EPS * terms
    slope = abs(k1 * math.sin(t4) + math.sin(t2 - t4))
    return df / slope if slope > 0.0 else math.inf


@settings(max_examples=300, deadline=None, derandomize=True)
@given(linkages_with_pairs())
def test_hypothesis_error_tracks_condition(
        case: tuple[tuple[float, float, float, float], list[tuple[float, float]]]) -> None:
    """Without the conditioning filter: whenever synthesis accepts the request, the length error stays within
    100 kappa eps; otherwise it refuses it as degenerate (condition number in the message) or as unbuildable
    because rounding hides the sign of K1 or K2."""
    lengths, pairs = case
    l1, l2, l3, l4 = lengths
    try:
        d = synthesize(pairs, ground=l1)
    except DegenerateDesignError as exc:
        assert 'condition number' in str(exc)
        return
    except UnbuildableDesignError as exc:
        assert 'zero within rounding' in str(exc)
        return
    kappa = problem_condition(lengths, pairs)
    assert rel_err((d.crank, d.coupler, d.rocker), (l2, l3, l4)) <= 100.0 * kappa * EPS


@pytest.mark.parametrize(('name', 'n', 'noise'), [('crank-rocker', 3, 0.0), ('double-rocker', 3, 0.0),
                                                   ('crank-rocker', 6, 0.0), ('crank-rocker', 6, 0.02)])
def test_reported_sensitivity_matches_finite_differences(name: str, n: int, noise: float) -> None:
    """Design.sensitivity against central differences of the whole synthesis (each angle moved by +-1e-6)."""
    fb = FourBar(*LINKAGES[name])
    rng = np.random.default_rng(3)
    pairs = [(t2, t4 + noise * float(rng.standard_normal()))
             for t2, t4 in pairs_of(fb, spread_angles(fb, n), [1] * n)]
    d = synthesize(pairs)
    base = np.array([d.crank, d.coupler, d.rocker])
    h = 1e-6
    total = np.zeros(3)
    for i in range(n):
        for j in range(2):
            plus = [list(p) for p in pairs]
            minus = [list(p) for p in pairs]
            plus[i][j] += h
            minus[i][j] -= h
            dp, dm = synthesize(plus), synthesize(minus)
            deriv = np.array([dp.crank - dm.crank, dp.coupler - dm.coupler, dp.rocker - dm.rocker]) / (2 * h)
            total += np.abs(deriv) / base
    assert d.sensitivity == pytest.approx(float(total.max()), rel=1e-5)


# ---------------------------------------------------------------- degenerate requests


@pytest.mark.parametrize(('pairs', 'kind'), [
    ([(0.1, 0.2), (0.1, 0.2), (0.5, 0.9)], 'singular'),  # a repeated pair
    ([(0.4, 1.0), (-0.4, -1.0), (1.2, 1.5)], 'singular'),  # mirror images give the same equation
    ([(0.1, 0.7), (0.6, 0.7), (1.3, 0.7)], 'singular'),  # t4 never changes
    ([(0.3, 0.2), (0.3, 0.8), (0.3, 1.5)], 'singular'),  # t2 never changes
    ([(0.1, 0.2), (0.1 + 1e-9, 0.2), (0.5, 0.9)], 'badly conditioned'),
])
def test_degenerate_positions_are_refused_with_the_condition_number(pairs: list[tuple[float, float]],
                                                                   kind: str) -> None:
    with pytest.raises(DegenerateDesignError) as info:
        synthesize(pairs)
    msg = str(info.value)
    assert kind in msg and 'condition number' in msg and '\n' not in msg


def test_condition_limit_is_enforced_at_the_reported_number() -> None:
    fb = FourBar(*LINKAGES['crank-rocker'])
    pairs = pairs_of(fb, [0.5, 0.52, 0.56], [1, 1, 1])
    d = synthesize(pairs)
    with pytest.raises(DegenerateDesignError, match='badly conditioned'):
        synthesize(pairs, max_condition=0.99 * d.condition_number)
    assert synthesize(pairs, max_condition=1.01 * d.condition_number).condition_number == d.condition_number


@pytest.mark.parametrize(('pairs', 'match'), [
    ([(0.1, 0.2), (0.5, 0.9)], 'at least 3'),
    ([(0.1, 0.2), (0.5, float('nan')), (1.0, 1.0)], 'pair 2 is not finite'),
    ([(0.1, 0.2, 0.3), (0.5, 0.9, 1.0), (1.0, 1.0, 1.0)], 'exactly two angles'),
])
def test_bad_pairs(pairs: list[tuple[float, ...]], match: str) -> None:
    with pytest.raises(DesignError, match=match):
        synthesize(pairs)


@pytest.mark.parametrize('ground', [0.0, -1.0, float('inf'), float('nan')])
def test_bad_ground(ground: float) -> None:
    fb = FourBar(*LINKAGES['crank-rocker'])
    with pytest.raises(DesignError, match='ground length must be finite and > 0'):
        synthesize(pairs_of(fb, [0.4, 1.2, 2.1], [1, 1, 1]), ground=ground)


# ---------------------------------------------------------------- unbuildable requests and flipped links


@pytest.mark.parametrize(('crank_flip', 'rocker_flip'), [(True, False), (False, True), (True, True)])
def test_negative_constants_are_unbuildable_unless_a_flip_is_allowed(crank_flip: bool, rocker_flip: bool) -> None:
    """Requesting t2 + pi (t4 + pi) for a real linkage's positions makes K1 (K2) negative: the same linkage with
    its crank (rocker) pointing the other way."""
    lengths = LINKAGES['crank-rocker']
    fb = FourBar(*lengths)
    real = pairs_of(fb, [0.4, 1.2, 2.1], [1, 1, 1])
    pairs = [(t2 + math.pi * crank_flip, t4 + math.pi * rocker_flip) for t2, t4 in real]
    with pytest.raises(UnbuildableDesignError) as info:
        synthesize(pairs)
    assert ('K1 = -' if crank_flip else 'K2 = -') in str(info.value) and '\n' not in str(info.value)
    d = synthesize(pairs, allow_flip=True)
    assert (d.crank_flipped, d.rocker_flipped) == (crank_flip, rocker_flip)
    assert (d.k1 < 0) == crank_flip and (d.k2 < 0) == rocker_flip
    assert rel_err((d.crank, d.coupler, d.rocker), lengths[1:]) <= 1e-12
    assert d.branch == 1 and d.max_t4_error is not None and d.max_t4_error <= 1e-12


def test_zero_constant_is_unbuildable() -> None:
    """Pairs solving -K2 cos t2 + K3 = cos(t2 - t4) with K1 = 0: an infinitely long crank."""
    pairs = [(t2, t2 - math.acos(0.5 - math.cos(t2))) for t2 in (0.3, 1.1, 2.0)]
    with pytest.raises(UnbuildableDesignError, match=r'K1 = .* is zero within rounding'):
        synthesize(pairs)


@pytest.mark.parametrize(('k', 'match'), [
    ((0.0, 1.0, 1.0), 'K1 = 0 gives an infinitely long crank'),
    ((1.0, 0.0, 1.0), 'K2 = 0 gives an infinitely long rocker'),
    ((1.0, 1.0, 2.0), 'coupler length squared'),  # l3^2 = 1 + 1 + 1 - 2 * 2 < 0
    ((1.0, 1.0, 1.5), 'coupler length squared'),  # exactly 0
])
def test_lengths_from_constants_refuses(k: tuple[float, float, float], match: str) -> None:
    with pytest.raises(UnbuildableDesignError, match=match):
        lengths_from_constants(*k)


def test_lengths_from_constants_matches_the_definition() -> None:
    fb = FourBar(*LINKAGES['double-rocker'])
    crank, coupler, rocker, f1, f2 = lengths_from_constants(*fb.freudenstein_constants(), ground=1.0)
    assert rel_err((crank, coupler, rocker), LINKAGES['double-rocker'][1:]) <= 1e-14
    assert not f1 and not f2


# ---------------------------------------------------------------- branches


def test_pairs_on_different_branches_are_reported() -> None:
    lengths = LINKAGES['crank-rocker']
    fb = FourBar(*lengths)
    branches = [1, -1, 1]
    d = synthesize(pairs_of(fb, [0.5, 1.3, 2.2], branches))
    assert [p.branch for p in d.pairs] == branches
    assert d.mixed_branches and d.branch is None
    assert rel_err((d.crank, d.coupler, d.rocker), lengths[1:]) <= 1e-12
    for p in d.pairs:  # independent of the solver: which side of B->O4 is C on
        assert math.copysign(1, side_of_b_o4(lengths, p.t2, p.t4)) == p.branch


@pytest.mark.parametrize(('name', 'edge'), [('double-rocker', 'gap'), ('double-rocker', 'max'),
                                            ('triple-rocker', 'max'), ('metres scale', 'max')])
@pytest.mark.parametrize('branch', [1, -1])
def test_pair_at_a_toggle_is_reported_on_both_branches(name: str, edge: str, branch: int) -> None:
    """At the crank's limit the coupler and rocker are in line (C on the line B-O4): both branches meet. The
    designed lengths differ from the true ones by rounding, which moves t4 there like a square root (~1e-8 rad),
    so this is reported as a toggle (branch 0), not as whichever branch rounding favours."""
    lengths = LINKAGES[name]
    fb = FourBar(*lengths)
    limit = fb.crank_gap if edge == 'gap' else fb.crank_max
    assert 0.0 < limit < math.pi  # a real limit of the crank, not full rotation
    others = [fb.crank_gap + (fb.crank_max - fb.crank_gap) * f for f in (0.3, 0.6)]
    d = synthesize(pairs_of(fb, [*others, limit], [branch] * 3), ground=lengths[0])
    # Really a toggle: C on the line B-O4 to within the square-root effect of the rounded limit angle.
    assert abs(side_of_b_o4(lengths, limit, d.pairs[2].t4)) <= 1e-7 * max(lengths) ** 2
    assert [p.branch for p in d.pairs] == [branch, branch, 0]
    assert d.branch == branch and not d.mixed_branches
    assert d.pairs[2].t4_error is not None and d.pairs[2].t4_error <= 1e-6


# ---------------------------------------------------------------- least squares


@pytest.mark.parametrize('n', [4, 5, 12])
def test_least_squares_with_exact_data_has_zero_residual(n: int) -> None:
    lengths = LINKAGES['double-rocker']
    fb = FourBar(*lengths)
    d = synthesize(pairs_of(fb, spread_angles(fb, n), [1] * n))
    assert d.residual <= 1e-14
    assert rel_err((d.crank, d.coupler, d.rocker), lengths[1:]) <= 1e-12
    assert d.branch == 1 and d.max_t4_error is not None and d.max_t4_error <= 1e-12


def test_least_squares_with_perturbed_data_reports_its_residual() -> None:
    lengths = LINKAGES['crank-rocker']
    fb = FourBar(*lengths)
    exact = pairs_of(fb, spread_angles(fb, 8), [1] * 8)
    noise = np.random.default_rng(7).normal(0.0, 2e-3, len(exact))
    pairs = [(t2, t4 + float(e)) for (t2, t4), e in zip(exact, noise, strict=True)]
    d = synthesize(pairs)
    # The residual is the textbook one, recomputed here from the reported constants.
    a, b = freudenstein_system(pairs)
    r = a @ np.array([d.k1, d.k2, d.k3]) - b
    assert d.residual == pytest.approx(float(np.linalg.norm(r)), rel=1e-9, abs=1e-15)
    assert [p.equation_residual for p in d.pairs] == pytest.approx(list(r), rel=1e-8, abs=1e-14)
    assert d.residual > 1e-4  # the noise shows
    # It is the least-squares solution: the residual is orthogonal to the columns, and any change of K grows it.
    assert np.abs(a.T @ r).max() <= 1e-12
    for dk in np.eye(3) * 1e-6:
        assert np.linalg.norm(a @ (np.array([d.k1, d.k2, d.k3]) + dk) - b) > d.residual
    # The lengths move by about the size of the noise, not more.
    assert rel_err((d.crank, d.coupler, d.rocker), lengths[1:]) < 0.05
    errors = [p.t4_error for p in d.pairs]
    assert all(e is not None and 0.0 < e < 0.02 for e in errors)


# ---------------------------------------------------------------- the command line


def design_cli(*args: str, capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    code = cli_main(['design', *args])
    out = capsys.readouterr()
    return code, out.out, out.err


def pair_args(pairs: list[tuple[float, float]], deg: bool = False) -> list[str]:
    f = math.degrees if deg else (lambda x: x)
    return [f'{f(t2)!r},{f(t4)!r}' for t2, t4 in pairs]


def test_cli_json_keys_and_values(capsys: pytest.CaptureFixture[str]) -> None:
    fb = FourBar(*LINKAGES['crank-rocker'])
    pairs = pairs_of(fb, [0.5, 1.3, 2.2], [1, 1, 1])
    code, out, err = design_cli('--pairs', *pair_args(pairs), '--ground', '0.25', '--json', capsys=capsys)
    assert code == 0, err
    v = json.loads(out)
    assert {'K1', 'K2', 'K3', 'ground', 'crank', 'coupler', 'rocker', 'branch', 'residual',
            'condition_number', 'pairs'} <= set(v)
    d = synthesize(pairs, ground=0.25)
    assert (v['K1'], v['K2'], v['K3'], v['crank'], v['coupler'], v['rocker']) == (
        d.k1, d.k2, d.k3, d.crank, d.coupler, d.rocker)
    assert v['ground'] == 0.25 and v['branch'] == 1
    assert v['rocker'] == pytest.approx(0.25 * 0.7, rel=1e-12)


def test_cli_degrees_match_radians(capsys: pytest.CaptureFixture[str]) -> None:
    fb = FourBar(*LINKAGES['double-rocker'])
    pairs = pairs_of(fb, spread_angles(fb, 4), [-1] * 4)
    _, rad, _ = design_cli('--pairs', *pair_args(pairs), '--json', capsys=capsys)
    _, deg, _ = design_cli('--deg', '--pairs', *pair_args(pairs, deg=True), '--json', capsys=capsys)
    a, b = json.loads(rad), json.loads(deg)
    for key in ('K1', 'K2', 'K3', 'crank', 'coupler', 'rocker'):
        assert b[key] == pytest.approx(a[key], rel=1e-12)
    assert a['branch'] == b['branch'] == -1


def test_cli_text_reports_mixed_branches(capsys: pytest.CaptureFixture[str]) -> None:
    fb = FourBar(*LINKAGES['crank-rocker'])
    code, out, _ = design_cli('--pairs', *pair_args(pairs_of(fb, [0.5, 1.3, 2.2], [1, -1, 1])), capsys=capsys)
    assert code == 0
    assert 'MIXED' in out and 'K1 =' in out and 'condition number' in out


@pytest.mark.parametrize(('args', 'match'), [
    (['--pairs', '0.1,0.2', '0.1,0.2', '0.5,0.9'], 'singular (condition number'),
    (['--pairs', '0.1,0.2', '0.5,0.9'], 'need at least 3 pairs'),
    (['--pairs', '0.1,0.2', '0.5', '0.9,1.0'], "pair '0.5' must be two angles"),
    (['--pairs', '0.1,0.2', '0.5,x', '0.9,1.0'], 'must be two numbers'),
    (['--pairs', '0.1,0.2', '0.5,inf', '0.9,1.0'], 'must be finite'),
    (['--pairs', '0.3,0.2', '0.5,0.9', '0.9,1.0', '--ground', '-1'], 'ground length must be finite and > 0'),
])
def test_cli_bad_requests_exit_2_with_one_line(args: list[str], match: str,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = design_cli(*args, capsys=capsys)
    assert code == 2 and out == ''
    assert err.startswith('fourbar design: error: ') and err.count('\n') == 1 and match in err


def test_cli_unbuildable_and_allow_flip(capsys: pytest.CaptureFixture[str]) -> None:
    fb = FourBar(*LINKAGES['crank-rocker'])
    pairs = [(t2 + math.pi, t4) for t2, t4 in pairs_of(fb, [0.4, 1.2, 2.1], [1, 1, 1])]
    code, _, err = design_cli('--pairs', *pair_args(pairs), capsys=capsys)
    assert code == 2 and 'unbuildable: K1 = -' in err and err.count('\n') == 1
    code, out, _ = design_cli('--pairs', *pair_args(pairs), '--allow-flip', '--json', capsys=capsys)
    assert code == 0 and json.loads(out)['crank_flipped'] is True


def test_cli_negative_first_angle_via_pair_option(capsys: pytest.CaptureFixture[str]) -> None:
    fb = FourBar(*LINKAGES['double-crank'])
    pairs = pairs_of(fb, [-1.0, 0.5, 2.0], [1, 1, 1])
    code, out, err = design_cli('--pair=' + pair_args(pairs[:1])[0], '--pairs', *pair_args(pairs[1:]), '--json',
                                capsys=capsys)
    assert code == 0, err
    assert json.loads(out)['crank'] == pytest.approx(1.0 / 0.4, rel=1e-12)  # ground 1: crank l2 / l1


def test_main_exit_status() -> None:
    ok = fourbar('design', '--deg', '--pairs', '30,92.35', '75,99.4', '125,120.3')
    assert ok.returncode == 0, ok.stderr
    assert 'branch: +1 (open) at every position' in ok.stdout
    bad = fourbar('design', '--pairs', '0.1,0.2', '0.1,0.2', '0.5,0.9')
    assert bad.returncode == 2 and bad.stderr.startswith('fourbar design: error: degenerate positions')
