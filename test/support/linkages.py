"""Linkages the core tests share: Turnantenna's, and random valid geometries drawn from a seed."""

from __future__ import annotations

import numpy as np

from fourbar_ros import AntennaLinkage, InvalidGeometryError

TURNANTENNA = AntennaLinkage(frame=0.180, rocker_ab=0.060, coupler=0.102)


def links(seed: int, n: int) -> list[AntennaLinkage]:
    """Turnantenna, then random geometries (lengths 0.05..2 m, rocker CD free) until there are ``n``."""
    rng = np.random.default_rng(seed)
    out: list[AntennaLinkage] = [TURNANTENNA]
    while len(out) < n:
        try:
            out.append(AntennaLinkage(*(float(v) for v in rng.uniform(0.05, 2.0, 3)), float(rng.uniform(0.05, 2.0))))
        except InvalidGeometryError:
            continue
    return out
