r"""Peer libraries solving the same antenna positions (theta given, upper branch), as a user of each would.

- ``pylinkage`` (requirements/bench.txt): its position primitive for a revolute dyad,
  ``pylinkage.geometry.circle_intersect`` (what its RRR dyads and simulation loop call). Given theta, B is an
  intersection of the circle (A, AB) with the circle (D - h (cos t, -sin t), CD); we pick the upper one (left of
  A -> D') and read gamma, delta with atan2. Scalar only: pylinkage has no array API for one dyad.
- ``mechanism`` (requirements/bench.txt): a Mechanism of four Vectors with the loop equation
  AB(g) + BC(-t) - DC(pi - d) - AD = 0 solved by its scipy fsolve. Scalar: ``calculate()`` per angle, cold-started
  from the mid-interval pose (as Newton here is); vector: ``iterate()`` over the array (warm-starts each angle from
  the previous one). Angles are read from the Vectors as a user of mechanism reads them.

Both import lazily so the rest of the benchmark runs without them (the report then says they were missing).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import numpy.typing as npt

from benchmarks.methods import Method, NotApplicableError, Solver, linkage
from benchmarks.reference import Geometry

FloatArray = npt.NDArray[np.float64]


def peer_versions() -> dict[str, str | None]:
    """Installed versions of the peers (None when missing)."""
    from importlib.metadata import PackageNotFoundError, version

    out: dict[str, str | None] = {}
    for name in ('pylinkage', 'mechanism'):
        try:
            out[name] = version(name)
        except PackageNotFoundError:
            out[name] = None
    return out


def pylinkage_solver(g: Geometry, _interval: tuple[float, float]) -> Solver:
    try:
        from pylinkage.geometry import circle_intersect
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise NotApplicableError(f'pylinkage is not installed: {exc}') from None
    H, a, h, b = g.frame, g.rocker_ab, g.coupler, g.rocker_cd
    sin, cos, atan2 = math.sin, math.cos, math.atan2

    def scalar(theta: float) -> tuple[float, float]:
        px, py = H - h * cos(theta), h * sin(theta)
        n, x1, y1, x2, y2 = circle_intersect(0.0, 0.0, a, px, py, b)
        if n == 0:
            raise ValueError(f'pylinkage: no intersection at theta={theta!r}')
        if n == 2 and px * y1 - py * x1 < px * y2 - py * x2:  # keep the point left of A -> D'
            x1, y1 = x2, y2
        return atan2(y1, x1), atan2(y1 - py, px - x1)

    return Solver(scalar, None)


def _mechanism(g: Geometry, interval: tuple[float, float]) -> Solver:
    try:
        from mechanism import Joint, Mechanism, Vector
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise NotApplicableError(f'mechanism is not installed: {exc}') from None
    g0, d0 = (float(v) for v in linkage(g).rocker_angles(0.5 * (interval[0] + interval[1])))
    guess = np.array([g0, math.pi - d0])

    def build(pos: float | FloatArray) -> tuple[Any, Any, Any]:
        """A fresh Mechanism at ``pos`` (its Vectors hold the solution), and its Vectors AB and DC."""
        a_, b_, c_, d_ = Joint('A'), Joint('B'), Joint('C'), Joint('D')
        ab = Vector((a_, b_), r=g.rocker_ab)
        bc = Vector((b_, c_), r=g.coupler)
        dc = Vector((d_, c_), r=g.rocker_cd)
        ad = Vector((a_, d_), r=g.frame, theta=0.0, style='ground')

        def loops(x: FloatArray, t: float) -> FloatArray:
            return np.asarray(ab(x[0]) + bc(-t) - dc(x[1]) - ad())

        return Mechanism(vectors=(ab, bc, dc, ad), origin=a_, loops=loops, pos=pos, guess=(guess,)), ab, dc

    single, ab, dc = build(0.0)

    def scalar(theta: float) -> tuple[float, float]:
        single.pos = theta
        single.calculate()
        single.clear_joints()
        return float(ab.pos.theta), math.pi - float(dc.pos.theta)

    def vector(theta: FloatArray) -> tuple[FloatArray, FloatArray]:
        mech, v_ab, v_dc = build(theta)
        mech.iterate()
        return np.asarray(v_ab.pos.thetas, dtype=np.float64), math.pi - np.asarray(v_dc.pos.thetas)

    return Solver(scalar, vector)


def peer_methods() -> list[Method]:
    """The peers as benchmark methods (build raises NotApplicableError when the package is missing)."""
    return [
        Method('pylinkage', 'peer', 'float64', 'pylinkage.geometry.circle_intersect + atan2', pylinkage_solver),
        Method('mechanism', 'peer', 'float64', 'mechanism.Mechanism (scipy fsolve on the loop equation)',
               _mechanism),
    ]
