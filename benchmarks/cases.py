"""The common sweep: the geometries and angles every method is measured on.

All four geometries have equal rockers (the annex formula's scope). The angles are seeded uniform samples plus
both ends of the central 99% of each geometry's reachable interval, [-0.99 theta_max, 0.99 theta_max]
(theta_max from :func:`benchmarks.reference.reach_float`, computed independently of the core).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from benchmarks.reference import Geometry, reach_float

FloatArray = npt.NDArray[np.float64]

TURNANTENNA = Geometry('turnantenna', frame=0.180, rocker_ab=0.060, coupler=0.102, rocker_cd=0.060)

COMMON_GEOMETRIES: tuple[Geometry, ...] = (
    TURNANTENNA,
    Geometry('coupler-longer-than-frame', frame=0.100, rocker_ab=0.060, coupler=0.150, rocker_cd=0.060),
    Geometry('wide-frame', frame=0.300, rocker_ab=0.100, coupler=0.120, rocker_cd=0.100),
    Geometry('full-turn', frame=0.180, rocker_ab=0.200, coupler=0.102, rocker_cd=0.200),
)

FRACTION = 0.99
SEED = 20260501


def sweep_interval(g: Geometry) -> tuple[float, float]:
    """The central 99% of the reachable interval, radians (all common geometries have theta_gap = 0)."""
    gap, top = reach_float(g)
    if gap != 0.0:
        raise ValueError(f'{g.name}: the common sweep expects a geometry without a reach gap')
    return -FRACTION * top, FRACTION * top


def sweep_angles(g: Geometry, n: int, seed: int = SEED) -> FloatArray:
    """n angles (radians): both interval ends and n - 2 seeded uniform samples between them."""
    lo, hi = sweep_interval(g)
    rng = np.random.default_rng(seed)
    inner = rng.uniform(lo, hi, n - 2)
    return np.concatenate(([lo, hi], inner))
