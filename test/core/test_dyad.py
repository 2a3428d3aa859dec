"""The shared dyad solve: one closure for both linkages, one Branch, the inverse solve's errors, pickling.

(The core's import structure is checked with the whole package's in test_layers.py.)"""

from __future__ import annotations

import math
import pickle

import numpy as np
import pytest

from fourbar_ros import (
    AntennaLinkage,
    Branch,
    Driven,
    FourBar,
    SingularPositionError,
    UnreachableError,
)
from fourbar_ros.core.dyad import closure_array, closure_for, dyad_constants

TURNANTENNA = AntennaLinkage(frame=0.180, rocker_ab=0.060, coupler=0.102)


def test_antenna_and_general_solve_through_the_same_closure() -> None:
    # FourBar (t2) and the antenna (theta) are the same dyad with x = -t2 and x = theta: with the antenna's
    # lengths as (ground, crank, coupler, rocker) = (frame, coupler, AB, CD), t3 is gamma(-t2) exactly (same
    # operations on the same floats) and t4 = pi - delta(-t2) up to the one rounding of that subtraction.
    fb = FourBar(0.180, 0.102, 0.060, 0.060)
    for t in (-0.3, -0.05, 0.0, 0.2, 0.6):
        g, d = TURNANTENNA.rocker_angles(t)
        t3, t4 = fb.angles(-t)
        assert t3 == g
        assert abs(t4 - (math.pi - d)) <= math.ulp(math.pi)
    k = dyad_constants(0.180, 0.102, 0.060, 0.060, unit=0.180)
    x = np.linspace(-0.6, 0.6, 9)
    p, q = closure_array(k, x, Branch.LOWER, 'raise')
    solve = closure_for(k)
    for i, xi in enumerate(x.tolist()):
        sp, sq = solve(xi, Branch.LOWER)
        # numpy's SIMD sin/cos/atan2 may differ from libm by 1-2 ulp; the angles are O(1) and well conditioned
        # here (far from the reach limit), so a few ulps of pi bound the difference.
        assert abs(sp - p[i]) <= 8 * math.ulp(math.pi) and abs(sq - q[i]) <= 8 * math.ulp(math.pi)


def test_fourbar_takes_branch_or_plus_minus_one_only() -> None:
    fb = FourBar(4.0, 1.0, 3.5, 3.0)
    assert fb.angles(0.7, Branch.LOWER) == fb.angles(0.7, -1)  # type: ignore[arg-type]
    assert fb.angles(0.7) == fb.angles(0.7, 1)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match='not a valid Branch'):
        fb.angles(0.7, 0)  # type: ignore[arg-type]


def test_inverse_errors_name_the_rocker_and_its_range() -> None:
    with pytest.raises(UnreachableError) as exc:
        TURNANTENNA.from_rocker(3.0, Driven.GAMMA)
    msg = str(exc.value)
    assert '\n' not in msg and msg.startswith('q=3.0 rad: the gamma rocker cannot take this angle; it takes |q| <=')
    with pytest.raises(UnreachableError, match=r'^2 of 3 delta angles cannot be taken, the first q=nan'):
        TURNANTENNA.from_rocker(np.array([math.nan, 0.9, 3.0]), Driven.DELTA)
    with pytest.raises(UnreachableError):
        TURNANTENNA.from_rocker(math.inf)
    # A rocker as long as the frame puts its end on the other pivot at q = 0: undetermined, not a NaN.
    square = AntennaLinkage(frame=0.1, rocker_ab=0.1, coupler=0.1, rocker_cd=0.1)
    with pytest.raises(SingularPositionError, match='change point of the gamma rocker'):
        square.from_rocker(0.0)
    with pytest.raises(SingularPositionError, match='change point of the gamma rocker'):
        square.from_rocker(np.array([0.3, 0.0]))


def test_linkages_pickle_by_their_lengths() -> None:
    link = AntennaLinkage(0.180, 0.060, 0.102, 0.065)
    link.from_rocker(0.9)  # fills the per-rocker cache, which is not pickled
    back = pickle.loads(pickle.dumps(link))
    assert back == link and back.rocker_cd == 0.065
    assert back.rocker_angles(0.1) == link.rocker_angles(0.1)
    assert back.from_rocker(0.9) == link.from_rocker(0.9)
    fb = FourBar(4.0, 1.0, 3.5, 3.0)
    assert pickle.loads(pickle.dumps(fb)).angles(0.4) == fb.angles(0.4)
