"""fourbar_ros.core.lookup.RockerTable: its documented error bound holds against the 50-digit reference, in Python and
in the C it emits; bad intervals and out-of-table angles are refused."""

from __future__ import annotations

import math
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from benchmarks.cases import COMMON_GEOMETRIES, TURNANTENNA
from benchmarks.methods import linkage
from benchmarks.reference import Geometry, angle_error, reference_arrays
from fourbar_ros.core.antenna import AntennaLinkage, Branch
from fourbar_ros.core.errors import UnreachableError
from fourbar_ros.core.lookup import RockerTable

TILT = (math.radians(-6.0), math.radians(7.0))


def errors_against_reference(geo: Geometry, theta: np.ndarray, gam: np.ndarray, dlt: np.ndarray,
                             branch: int = 1) -> float:
    ref = reference_arrays(geo, theta, branch)
    return float(max(angle_error(gam, ref.gamma_hi, ref.gamma_lo).max(),
                     angle_error(dlt, ref.delta_hi, ref.delta_lo).max()))


@pytest.mark.parametrize('tolerance', [1e-4, 1e-6, 1e-9])
def test_table_meets_its_tolerance_against_the_reference(tolerance: float) -> None:
    table = RockerTable.build(linkage(TURNANTENNA), *TILT, tolerance=tolerance)
    theta = np.random.default_rng(1).uniform(*TILT, 1500)
    gam, dlt = table.rocker_angles(theta)
    err = errors_against_reference(TURNANTENNA, theta, np.asarray(gam), np.asarray(dlt))
    assert err <= tolerance
    assert err <= 2.0 * table.max_error + 1e-15  # the measured maximum is representative
    # The scalar path is the same table.
    gam_a, dlt_a = np.asarray(gam), np.asarray(dlt)
    for k, t in enumerate(theta[:50].tolist()):
        g, d = table.rocker_angles(t)
        assert isinstance(g, float)
        assert g == pytest.approx(float(gam_a[k]), abs=1e-15)
        assert d == pytest.approx(float(dlt_a[k]), abs=1e-15)


def test_small_table_suffices_for_turnantenna_tilt_range() -> None:
    table = RockerTable.build(linkage(TURNANTENNA), *TILT, tolerance=1e-6)
    assert table.points <= 17
    assert table.max_error <= 0.5e-6
    assert table.max_error_float32 <= 1e-6


def test_lower_branch_and_a_long_coupler() -> None:
    geo = COMMON_GEOMETRIES[1]
    link = linkage(geo)
    lo, hi = -0.8, 0.8
    table = RockerTable.build(link, lo, hi, tolerance=1e-7, branch=Branch.LOWER)
    theta = np.random.default_rng(2).uniform(lo, hi, 800)
    gam, dlt = table.rocker_angles(theta)
    assert errors_against_reference(geo, theta, np.asarray(gam), np.asarray(dlt), branch=-1) <= 1e-7


def test_bad_intervals_are_refused() -> None:
    link = linkage(TURNANTENNA)
    top = link.reach().theta_max
    with pytest.raises(ValueError, match='leaves the reach'):
        RockerTable.build(link, 0.0, top + 0.01)
    with pytest.raises(ValueError, match='non-empty'):
        RockerTable.build(link, 0.1, 0.1)
    with pytest.raises(ValueError, match='finite'):
        RockerTable.build(link, math.nan, 0.1)
    with pytest.raises(ValueError, match='reach limit'):  # unbounded slope at the limit: no table converges
        RockerTable.build(link, 0.0, top, tolerance=1e-12, max_points=4097)


def test_out_of_table_angles_raise_or_mask() -> None:
    table = RockerTable.build(linkage(TURNANTENNA), *TILT)
    with pytest.raises(UnreachableError, match='outside the table'):
        table.rocker_angles(0.2)
    with pytest.raises(UnreachableError):
        table.rocker_angles(math.nan)
    with pytest.raises(UnreachableError, match='2 of 3'):
        table.rocker_angles(np.array([0.0, 0.2, math.nan]))
    g = np.asarray(table.rocker_angles(np.array([0.0, 0.2, math.nan]), on_invalid='nan').gamma)
    assert math.isfinite(g[0]) and math.isnan(g[1]) and math.isnan(g[2])
    assert table.rocker_angles(TILT[1]).gamma == pytest.approx(float(linkage(TURNANTENNA).rocker_angles(TILT[1])[0]))


@pytest.mark.skipif(shutil.which('cc') is None, reason='no C compiler')
def test_emitted_c_meets_the_float32_bound(tmp_path: Path) -> None:
    link = AntennaLinkage(frame=0.180, rocker_ab=0.060, coupler=0.102)
    table = RockerTable.build(link, *TILT, tolerance=1e-6)
    theta = np.random.default_rng(3).uniform(*TILT, 400)
    src = tmp_path / 'table.c'
    src.write_text(table.to_c('tilt') + '''
#include <stdio.h>
#include <stdlib.h>
int main(void) {
  double t; float out[2];
  while (scanf("%lf", &t) == 1) { tilt_eval((float)t, out); printf("%.9e %.9e\\n", out[0], out[1]); }
  return 0;
}
''', encoding='utf-8')
    exe = tmp_path / 'table'
    subprocess.run(['cc', '-std=c99', '-O2', '-o', str(exe), str(src)], check=True, timeout=60)
    run = subprocess.run([str(exe)], input='\n'.join(repr(t) for t in theta.tolist()), capture_output=True,
                         text=True, check=True, timeout=60)
    out = np.array([[float(v) for v in line.split()] for line in run.stdout.splitlines()])
    assert out.shape == (theta.size, 2)
    err = errors_against_reference(TURNANTENNA, theta, out[:, 0], out[:, 1])
    assert err <= 1e-6
    assert err <= 2.0 * table.max_error_float32
    with pytest.raises(ValueError):
        table.to_c('not an identifier')
