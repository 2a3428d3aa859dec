"""K1 or K2 zero within the solve's rounding: the degenerate family where t4 - t2 is the same at every pair
(K1 = K2 = 0 exactly, an infinitely long crank and rocker) is refused whatever sign rounding gives the solved
constants, and the error bound that decides it (``rounding_bound``) holds against an exact solve."""

from __future__ import annotations

import math

import mpmath
import numpy as np
import pytest
from hypothesis import assume, given
from hypothesis import strategies as st

from fourbar_ros.commands import main as cli_main
from fourbar_ros.core.synthesis import (
    DegenerateDesignError,
    UnbuildableDesignError,
    relative_system,
    rounding_bound,
    synthesize,
)


@pytest.mark.parametrize('pairs', [
    ('0.5,1.0', '0.7,1.2', '0.9,1.4'),  # K1 came out +1.6e-15 and the design was accepted (a 6e14 m crank)
    ('0.1,1.1', '0.4,1.4', '0.9,1.9'),  # K1 came out -5.8e-16: refused only as "negative"
])
def test_constant_difference_pairs_are_refused_as_zero_constants(
        pairs: tuple[str, ...], capsys: pytest.CaptureFixture[str]) -> None:
    assert cli_main(['design', '--pairs', *pairs]) == 2
    err = capsys.readouterr().err
    assert err.startswith('fourbar design: error: unbuildable: K1 = ') and 'is zero within rounding' in err, err
    assert err.count('\n') == 1


#: Angles typed with two decimals, as a user types them (rad): 0.01 .. 3.00.
_TWO_DECIMALS = st.integers(min_value=1, max_value=300)


@given(st.lists(_TWO_DECIMALS, min_size=3, max_size=3, unique=True), st.integers(min_value=-200, max_value=200))
def test_typed_pairs_with_one_difference_are_never_accepted(t2_hundredths: list[int], diff: int) -> None:
    """t4 = t2 + c exactly in the decimals typed: the exact constants are K1 = K2 = 0, so every such request is
    refused (as zero constants, or as degenerate when the cosines repeat), never designed."""
    pairs = [(float(f'{k / 100:.2f}'), float(f'{(k + diff) / 100:.2f}')) for k in t2_hundredths]
    with pytest.raises((UnbuildableDesignError, DegenerateDesignError)) as info:
        synthesize(pairs)
    if isinstance(info.value, UnbuildableDesignError):
        assert 'zero within rounding' in str(info.value)


def _exact_k1_k2(pairs: list[tuple[float, float]]) -> tuple[mpmath.mpf, mpmath.mpf]:
    """K1, K2 of the three float pairs taken as exact, solved with 60 digits (textbook rows)."""
    with mpmath.workdps(60):
        a = mpmath.matrix([[mpmath.cos(t4), -mpmath.cos(t2), 1] for t2, t4 in pairs])
        b = mpmath.matrix([mpmath.cos(mpmath.mpf(t2) - mpmath.mpf(t4)) for t2, t4 in pairs])
        k = mpmath.lu_solve(a, b)
        return k[0], k[1]


@given(st.lists(st.floats(min_value=-3.0, max_value=3.0), min_size=3, max_size=3),
       st.floats(min_value=-2.5, max_value=2.5),
       st.lists(st.floats(min_value=-1e-3, max_value=1e-3), min_size=3, max_size=3),
       st.integers(min_value=0, max_value=12))
def test_rounding_bound_holds_over_nearly_collinear_pairs(t2s: list[float], diff: float, wobble: list[float],
                                                          decades: int) -> None:
    """t4 - t2 nearly the same at every pair (offsets down to 1e-15 rad): the solved K1 and K2 are within
    ``rounding_bound`` of the exact solution of the same float inputs, so a constant accepted (|K| above the
    bound) has the exact constant's sign and is off by less than itself."""
    scale = 10.0 ** -decades
    pairs = [(t2, t2 + diff + w * scale) for t2, w in zip(t2s, wobble, strict=True)]
    arr = np.array(pairs)
    m, rhs, col_scale = relative_system(arr)
    assume(bool(np.all(col_scale > 0.0)))
    singular = np.linalg.svd(m, compute_uv=False)
    assume(singular[-1] > 1e-6 * singular[0])  # the condition limit refuses the rest before this bound matters
    y = np.linalg.solve(m, rhs)
    k1, k2 = float(y[0] / col_scale[0]), float(y[1] / col_scale[1])
    bound = rounding_bound(arr, m, y, m @ y - rhs, col_scale)
    exact = _exact_k1_k2(pairs)
    for got, want, err in zip((k1, k2), exact, bound, strict=True):
        assert abs(got - want) <= err, (got, float(want), err)
        if abs(got) > err:
            assert math.copysign(1.0, got) == mpmath.sign(want)


def test_bound_stays_far_below_a_real_design() -> None:
    """A real linkage (Turnantenna's, K1 = K2 = 3) is not near the bound: the refusal costs no real design."""
    pairs = [(math.radians(a), math.radians(b)) for a, b in (
        (40.921022829819, 123.621192784333), (49.458398126495, 130.541601873505),
        (57.328038082382, 140.609886452344))]
    arr = np.array(pairs)
    m, rhs, col_scale = relative_system(arr)
    y = np.linalg.solve(m, rhs)
    bound = rounding_bound(arr, m, y, m @ y - rhs, col_scale)
    d = synthesize(pairs)
    # cond 512: the first-order bound is about cond * eps * (angles + constants) ~ 1e-12 of K = 3.
    assert max(bound) < 1e-10 * min(d.k1, d.k2)
