"""The 60-digit reference values for Turnantenna (test/data/turnantenna_reference.csv), without needing mpmath.

Each row: theta in degrees, gamma and delta in degrees, d gamma/d theta and d delta/d theta (dimensionless),
d2 gamma/d theta2 and d2 delta/d theta2 (rad/rad^2), upper branch, for frame 0.180 m, rockers 0.060 m, coupler
0.102 m. ``ROWS`` holds them as exact decimal strings, ``FLOAT_ROWS`` as the nearest floats.
"""

from __future__ import annotations

import csv
from typing import NamedTuple

from support.paths import TEST_DATA

PATH = TEST_DATA / 'turnantenna_reference.csv'

#: Turnantenna's lengths in metres: frame H = AD, rockers l = AB = CD, coupler h = BC.
FRAME, ROCKER, COUPLER = 0.180, 0.060, 0.102


class Row(NamedTuple):
    """One reference pose: theta, gamma, delta in degrees; the rocker rates dimensionless; their derivatives in
    rad/rad^2."""

    theta_deg: float
    gamma_deg: float
    delta_deg: float
    dgamma_dtheta: float
    ddelta_dtheta: float
    d2gamma_dtheta2: float
    d2delta_dtheta2: float


def _read() -> list[list[str]]:
    with PATH.open(newline='') as f:
        lines = [line for line in f if not line.startswith('#')]
    rows = list(csv.reader(lines))
    assert rows[0] == list(Row._fields), rows[0]
    return rows[1:]


#: The rows as the decimal strings of the file (60 significant digits).
ROWS: list[tuple[str, ...]] = [tuple(r) for r in _read()]
#: The rows as floats (each the float nearest the 60-digit value).
FLOAT_ROWS: list[Row] = [Row(*(float(v) for v in r)) for r in ROWS]
#: The first five columns of FLOAT_ROWS (pose and rates), for tests that need no second derivatives.
FIRST_ORDER_ROWS: list[tuple[float, ...]] = [tuple(r[:5]) for r in FLOAT_ROWS]
