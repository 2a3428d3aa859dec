"""benchmarks.completion_peers on a tiny input: its reference agrees with the theta-input reference, and its error
figures are plausible (the exact completion within a few ulps of its condition, the cubic fit visibly off, the
differenced rates of the iterative solver worse than the exact ones); the report renders."""

from __future__ import annotations

import math

import mpmath
import numpy as np
import pytest
from support.ulp_bounds import CHAIN_ULPS

from benchmarks import completion_peers as cp
from benchmarks.cases import COMMON_GEOMETRIES, TURNANTENNA
from benchmarks.reference import Geometry, ReferenceUnreachableError, rates_mp, rocker_angles_mp
from benchmarks.reference_driven import driven_pose_mp, working_range
from benchmarks.report import completion_markdown


def wrapped(x: mpmath.mpf) -> float:
    """x modulo 2 pi, in [-pi, pi] (rad)."""
    with mpmath.workdps(60):
        return float(x - 2 * mpmath.pi * mpmath.nint(x / (2 * mpmath.pi)))


@pytest.mark.parametrize('geo', COMMON_GEOMETRIES, ids=lambda g: g.name)
def test_driven_reference_inverts_the_theta_reference(geo: Geometry) -> None:
    r = working_range(geo)
    assert abs(float(driven_pose_mp(geo, r.q0, r.branch).theta)) < 1e-12  # the working pose is on this branch
    for q in np.linspace(r.lo, r.hi, 9)[1:-1].tolist():
        p = driven_pose_mp(geo, q, r.branch)
        theta = float(p.theta)
        theta_branch = 1 if mpmath.sin(q + p.delta) >= 0 else -1  # upper theta branch: gamma + delta in [0, pi]
        gamma, delta = rocker_angles_mp(geo, theta, theta_branch)
        dg, dd = rates_mp(geo, theta, theta_branch)
        # theta rounded to a float moves the rockers by their rates times that rounding (half an ulp of theta).
        assert abs(wrapped(gamma - q)) <= abs(dg) * math.ulp(theta) + 1e-40
        assert abs(wrapped(delta - p.delta)) <= abs(dd) * math.ulp(theta) + 1e-40
        # dq/dtheta from the driven reference is d gamma/d theta of the theta reference.
        assert float(p.dq_dtheta) == pytest.approx(dg, rel=1e-9)


@pytest.mark.parametrize('geo', COMMON_GEOMETRIES, ids=lambda g: g.name)
def test_working_range_ends_are_the_reach_limits(geo: Geometry) -> None:
    r = working_range(geo)
    assert r.limited
    assert r.lo < r.mid_lo < r.q0 < r.mid_hi < r.hi
    for end, outward in ((r.lo, -math.inf), (r.hi, math.inf)):
        assert abs(float(driven_pose_mp(geo, end, r.branch).dq_dtheta)) < 1e-6  # a dead point of the driven rocker
        with pytest.raises(ReferenceUnreachableError):
            driven_pose_mp(geo, math.nextafter(end, outward), r.branch)


def test_errors_are_plausible_on_a_tiny_stream() -> None:
    out = cp.geometry_errors(TURNANTENNA, max_mid=8)
    assert out['mid_messages'] == 8
    m = out['methods']
    assert set(m['exact']) == {'mid', 'limit_1e-06', 'limit_1e-12'}
    for where, row in m['exact'].items():
        # The exact completion: each output within CHAIN_ULPS of its condition-weighted scale
        # (test/support/ulp_bounds.py).
        assert row['position_ulps'] <= CHAIN_ULPS, where
        assert row['rate_ulps'] <= CHAIN_ULPS, where
        for other in ('cubic', 'gauss-newton'):  # rates by derivative of a fit or by differences: far worse
            assert m[other][where]['theta_dot_rel'] > 1e3 * row['theta_dot_rel'], (other, where)
            assert m[other][where]['load_torque_rel'] > 1e3 * row['load_torque_rel'], (other, where)
    # A cubic over the whole range (two square-root branch points at its ends) is visibly off even mid-range.
    assert m['cubic']['mid']['theta_rad'] > 1e-4
    assert m['cubic']['mid']['other_rad'] > 1e-4
    # Warm-started Newton to a 1e-5 rad step converges far below that mid-range, and no better than the limit's
    # square-root conditioning allows near it (its error there exceeds the exact one by orders of magnitude).
    assert m['gauss-newton']['mid']['theta_rad'] < cp.TOLERANCE
    assert m['gauss-newton']['limit_1e-12']['theta_rad'] > 1e3 * m['exact']['limit_1e-12']['theta_rad']
    assert out['solver_stats']['gauss-newton']['not_converged'] == 0


def test_cost_and_report_render_on_a_tiny_run() -> None:
    cost = cp.costs(n_scalar=20, n_vector=64, repeats=1)
    assert cost['methods']['exact']['scalar_ratio_to_exact'] == 1.0
    assert cost['methods']['cubic']['vector_messages'] == 64
    assert 'vector_seconds' not in cost['methods']['gauss-newton']  # sequential: no vectorized path
    data = {'driven': 'gamma', 'stream': {'q_rate_rad_s': cp.Q_RATE, 'rate_hz': cp.RATE_HZ, 'step_rad': cp.STEP,
                                          'effort_n_m': cp.EFFORT, 'approach_messages': cp.APPROACH},
            'tolerance_rad': cp.TOLERANCE, 'fit_points': cp.FIT_POINTS, 'publishes': cp.PUBLISHES,
            'geometries': {TURNANTENNA.name: cp.geometry_errors(TURNANTENNA, max_mid=4)}, 'cost': cost}
    text = completion_markdown(data)
    assert '| exact | positions, rates, load torque | mid-range |' in text
    assert '| cubic | positions only | 1e-12 rad from the limit |' in text
    assert 'publish positions only' in text
    assert completion_markdown(None).startswith('Not measured')
    assert 'boom' in completion_markdown({'error': 'boom'})
