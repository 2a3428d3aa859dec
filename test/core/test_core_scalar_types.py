"""Every entry point of the core takes any real scalar: Python int and float, numpy floating and integer scalars,
0-d arrays of each. Each gives bit for bit what the Python float of the same value gives (its value, its type, or
its error), at the ends of its reach and one ulp either side too; out of reach is UnreachableError for every type.
The measured rocker's reach is exactly what from_rocker takes. No ROS."""

from __future__ import annotations

import math
import struct
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from support.linkages import TURNANTENNA, links

from fourbar_ros import AntennaLinkage, Branch, Driven, FourBar, Reach, UnreachableError
from fourbar_ros.core import loads
from fourbar_ros.core.completion import complete, coupler_joint_position, inverse_branch
from fourbar_ros.core.lookup import RockerTable
from fourbar_ros.core.numeric import real

GAPPED = links(1, 7)[6]  #: a geometry whose theta and gamma reaches both have a gap
assert GAPPED.reach().theta_gap > 0.0 and GAPPED.rocker_reach(Driven.GAMMA).theta_gap > 0.0
CRANK = FourBar(0.1, 0.09, 0.05, 0.06)  #: a crank that stops short of pi
TABLE = RockerTable.build(TURNANTENNA, -0.5, 0.5, tolerance=1e-6)


@dataclass(frozen=True)
class Load:
    """A LoadSpec with an antenna weight (so the gravity path runs)."""

    linkage: AntennaLinkage = TURNANTENNA
    driven: Driven = Driven.GAMMA
    branch: Branch = Branch.UPPER
    load_torque: float = 3.5
    antenna_mass: float = 1.7
    gravity: float = 9.80665
    com_offset_along: float = 0.01
    com_offset_normal: float = 0.02
    reducer_ratio: float = 500.0
    reducer_efficiency: float = 0.7


LOAD = Load()


def _integral(x: float) -> float:
    return float(round(x)) if math.isfinite(x) else 0.0


#: (name, typed value from a float): the type of the input; an integer type gets the integer nearest the value.
TYPES: list[tuple[str, Callable[[float], object]]] = [
    ('float', float),
    ('int', lambda x: int(_integral(x))),
    ('np.float64', np.float64),
    ('np.float32', np.float32),
    ('np.float16', np.float16),
    ('np.int64', lambda x: np.int64(_integral(x))),
    ('np.int8', lambda x: np.int8(max(-128.0, min(127.0, _integral(x))))),
    ('np.uint16', lambda x: np.uint16(max(0.0, min(65535.0, _integral(x))))),
]
TYPES += [(f'0-d {name}', lambda x, c=conv: np.array(c(x))) for name, conv in list(TYPES)[:6]]


def _with_nonfinite(name: str) -> bool:
    return 'int' not in name  # integers have no NaN or inf


def outcome(call: Callable[[object], object], x: object) -> object:
    """What call(x) gives, exactly: each output's type and bits, or the exception's type."""
    try:
        return _bits(call(x))
    except Exception as exc:  # the exception's type is the outcome
        return type(exc)


def _bits(r: object) -> object:
    if isinstance(r, tuple):
        return tuple(_bits(v) for v in r)
    if r is None:
        return None
    if isinstance(r, (bool, np.bool_)):
        return type(r), bool(r)
    assert type(r) in (float, np.float64), f'a scalar in gave {type(r).__name__} out'
    return type(r), struct.pack('<d', float(r))


def ends(reach: tuple[float, float]) -> list[float]:
    """Both ends of a reach (gap, max) on both sides of zero, and one ulp either side of each."""
    gap, top = reach
    out: list[float] = []
    for e in {gap, top}:
        for v in (e, -e):
            out += [v, math.nextafter(v, math.inf), math.nextafter(v, -math.inf)]
    return out


def inside(reach: tuple[float, float]) -> st.SearchStrategy[float]:
    """Values inside the reach, its exact ends and one ulp either side of them."""
    gap, top = reach
    mags = st.floats(gap, top)
    return st.one_of(st.sampled_from(ends(reach)), mags, mags.map(lambda v: -v))


def beyond(reach: tuple[float, float]) -> st.SearchStrategy[float]:
    """Values clearly out of reach (well past an end, or in the gap), NaN and inf."""
    gap, top = reach
    parts = [st.sampled_from([math.nan, math.inf, -math.inf])]
    if top < math.pi:
        past = st.floats(top + 1e-6 * (1.0 + top), math.pi)
        parts += [past, past.map(lambda v: -v)]
    if gap > 1e-6:
        hole = st.floats(0.0, gap * (1.0 - 1e-6))
        parts += [hole, hole.map(lambda v: -v)]
    return st.one_of(parts)


def _quiet(residual: Callable[[object, float], object], t2: object) -> object:
    with np.errstate(invalid='ignore'):  # cos(inf): NaN, as for arrays
        return residual(t2, 0.4)


G, D = Driven.GAMMA, Driven.DELTA
U, L = Branch.UPPER, Branch.LOWER
R = TURNANTENNA.reach()
TR = (R.theta_gap, R.theta_max)
GR = (GAPPED.reach().theta_gap, GAPPED.reach().theta_max)
RG = TURNANTENNA.rocker_reach(G)
RD = TURNANTENNA.rocker_reach(D)
GRG = GAPPED.rocker_reach(G)


def _r(reach: Reach) -> tuple[float, float]:
    return reach.theta_gap, reach.theta_max


_P = TURNANTENNA.rocker_angles(0.1)  # a solved pose, for the *_at entry points with theta typed
_g, _d = float(_P.gamma), float(_P.delta)

#: (name, call, reach, refuses out of reach with UnreachableError)
ENTRIES: list[tuple[str, Callable[[object], object], tuple[float, float], bool]] = [
    ('reachable', TURNANTENNA.reachable, TR, False),
    ('reachable gapped', GAPPED.reachable, GR, False),
    ('rocker_angles', TURNANTENNA.rocker_angles, TR, True),
    ('rocker_angles lower gapped', lambda x: GAPPED.rocker_angles(x, L), GR, True),
    ('rocker_rates', TURNANTENNA.rocker_rates, TR, True),
    ('rocker_second_derivatives', TURNANTENNA.rocker_second_derivatives, TR, True),
    ('rocker_velocities', lambda x: TURNANTENNA.rocker_velocities(x, 0.3), TR, True),
    ('rocker_velocities rate', lambda x: TURNANTENNA.rocker_velocities(0.1, x), TR, False),
    ('mechanical_advantage', lambda x: TURNANTENNA.mechanical_advantage(x, D), TR, True),
    ('input_torque', lambda x: TURNANTENNA.input_torque(x, 3.5), TR, True),
    ('input_torque delta', lambda x: TURNANTENNA.input_torque(x, 3.5, D), TR, True),
    ('input_torque load', lambda x: TURNANTENNA.input_torque(0.1, x), TR, False),
    ('transmission_angle', TURNANTENNA.transmission_angle, TR, True),
    ('state', lambda x: TURNANTENNA.state(x, 3.5), TR, True),
    ('state gapped', lambda x: GAPPED.state(x, 1.0, D), GR, True),
    ('rates_at', lambda x: TURNANTENNA.rates_at(x, _g, _d), TR, False),
    ('torque_at', lambda x: TURNANTENNA.torque_at(0.1, x, _d, 2.0), TR, False),
    ('transmission_angle_at', lambda x: TURNANTENNA.transmission_angle_at(0.1, _g, x), TR, False),
    ('second_derivatives_at', lambda x: TURNANTENNA.second_derivatives_at(x, _g, _d), TR, False),
    ('from_rocker gamma', TURNANTENNA.from_rocker, _r(RG), True),
    ('from_rocker delta lower', lambda x: TURNANTENNA.from_rocker(x, D, L), _r(RD), True),
    ('from_rocker gapped', GAPPED.from_rocker, _r(GRG), True),
    ('complete', lambda x: complete(TURNANTENNA, x, G, U, 0.2, 0.004), _r(RG), True),
    ('complete delta', lambda x: complete(TURNANTENNA, x, D, U, -0.1, 0.003), _r(RD), True),
    ('complete rate', lambda x: complete(TURNANTENNA, 0.3, G, U, x, 0.004), _r(RG), False),
    ('complete effort', lambda x: complete(TURNANTENNA, 0.3, G, U, 0.2, x), _r(RG), False),
    ('coupler_joint_position', lambda x: coupler_joint_position(x, 0.25), TR, False),
    ('inverse_branch', lambda x: inverse_branch(TURNANTENNA, x, G, U), TR, True),
    ('Reach.contains', R.contains, TR, False),
    ('FourBar.angles', CRANK.angles, (CRANK.crank_gap, CRANK.crank_max), True),
    ('FourBar.velocity_ratio', CRANK.velocity_ratio, (CRANK.crank_gap, CRANK.crank_max), True),
    ('FourBar.mechanical_advantage', lambda x: CRANK.mechanical_advantage(x, L),
     (CRANK.crank_gap, CRANK.crank_max), True),
    ('FourBar.freudenstein_residual', lambda x: _quiet(CRANK.freudenstein_residual, x), TR, False),
    ('RockerTable.rocker_angles', TABLE.rocker_angles, (0.0, 0.5), True),
    ('loads.solve', lambda x: loads.solve(LOAD, x), TR, True),
    ('loads.pose', lambda x: loads.pose(LOAD, x), TR, True),
    ('loads.com_height_rate', lambda x: loads.com_height_rate(LOAD, x, _g, 1.1), TR, False),
    ('loads.motor_torque', lambda x: loads.motor_torque(LOAD, x), TR, False),
]
assert CRANK.crank_max < math.pi


def assert_every_type_as_its_float(call: Callable[[object], object], x: float) -> None:
    for name, conv in TYPES:
        if not math.isfinite(x) and not _with_nonfinite(name):
            continue
        typed = conv(x)
        want = outcome(call, float(typed))
        assert outcome(call, typed) == want, (name, x, typed, want)


IDS = [e[0] for e in ENTRIES]


def assert_refused_by_every_type(call: Callable[[object], object], reach: tuple[float, float], x: float) -> None:
    for type_name, conv in TYPES:
        if math.isfinite(x) or _with_nonfinite(type_name):
            typed = conv(x)
            if math.isfinite(float(typed)) and _r_contains(reach, float(typed)):
                continue  # a narrow type rounded it back inside
            with pytest.raises(UnreachableError):
                call(typed)


@pytest.mark.parametrize(('name', 'call', 'reach', 'refuses'), ENTRIES, ids=IDS)
def test_at_the_ends_of_the_reach_and_one_ulp_either_side(name: str, call: Callable[[object], object],
                                                          reach: tuple[float, float], refuses: bool) -> None:
    for x in ends(reach):
        assert_every_type_as_its_float(call, x)


@pytest.mark.parametrize(('name', 'call', 'reach', 'refuses'), ENTRIES, ids=IDS)
@settings(max_examples=10, deadline=None)
@given(data=st.data())
def test_every_real_scalar_type_gives_its_floats_result(name: str, call: Callable[[object], object],
                                                        reach: tuple[float, float], refuses: bool,
                                                        data: st.DataObject) -> None:
    assert_every_type_as_its_float(call, data.draw(inside(reach), label='inside'))
    x = data.draw(beyond(reach), label='beyond')
    assert_every_type_as_its_float(call, x)
    if refuses:
        assert_refused_by_every_type(call, reach, x)


def _r_contains(reach: tuple[float, float], v: float) -> bool:
    return Reach(*reach).contains(v)


def test_the_integers_of_every_width() -> None:
    for conv in (np.int8, np.int16, np.int32, np.int64, np.uint8, np.uint32, np.uint64, int):
        assert outcome(TURNANTENNA.from_rocker, conv(1)) == outcome(TURNANTENNA.from_rocker, 1.0)
        assert outcome(TURNANTENNA.rocker_angles, conv(0)) == outcome(TURNANTENNA.rocker_angles, 0.0)
        with pytest.raises(UnreachableError):
            TURNANTENNA.rocker_angles(conv(1))
        with pytest.raises(UnreachableError):
            TURNANTENNA.from_rocker(np.array(conv(2)))


def test_bools_and_complex_are_not_real_numbers_and_arrays_pass_unchanged() -> None:
    for bad in (True, np.bool_(False), np.array(True), 1j, np.complex128(0.1), np.array(0.1 + 0j)):
        with pytest.raises(TypeError):
            TURNANTENNA.rocker_angles(bad)
    a = np.array([0.1, 0.2])
    assert real(a) is a and real(0.5) == 0.5 and type(real(np.float32(0.5))) is float
    assert type(real(np.array(0.5, dtype=object))) is float


def test_reachable_is_the_solvers_test() -> None:
    for link in (TURNANTENNA, GAPPED):
        r = link.reach()
        for t in [*ends((r.theta_gap, r.theta_max)), 0.1, math.nan, math.inf]:
            try:
                link.rocker_angles(t)
                solved = True
            except UnreachableError:
                solved = False
            assert link.reachable(t) is solved
            with np.errstate(invalid='ignore'):
                solved_a = bool(np.isfinite(link.rocker_angles(np.array([t]), on_invalid='nan').gamma[0]))
            assert bool(link.reachable(np.array([t]))[0]) == solved_a


@pytest.mark.parametrize('driven', list(Driven))
def test_complete_on_float32_computes_in_float64(driven: Driven) -> None:
    r = TURNANTENNA.rocker_reach(driven)
    for q in np.linspace(-0.99, 0.99, 23) * r.theta_max:
        q32, rate32, effort32 = np.float32(q), np.float32(0.37), np.float32(0.0061)
        got = complete(TURNANTENNA, q32, driven, Branch.UPPER, rate32, effort32)
        want = complete(TURNANTENNA, float(q32), driven, Branch.UPPER, float(rate32), float(effort32))
        assert _bits(got) == _bits(want)
        assert all(type(v) is float for v in got)


@pytest.mark.parametrize('link', [TURNANTENNA, GAPPED, *links(11, 40)[1:]])
@pytest.mark.parametrize('driven', list(Driven))
def test_from_rocker_takes_exactly_its_rocker_reach(link: AntennaLinkage, driven: Driven) -> None:
    r = link.rocker_reach(driven)
    edges = [(r.theta_max, math.inf)] if r.theta_max < math.pi else []
    if r.theta_gap > 0.0:
        edges.append((r.theta_gap, 0.0))
    for edge, away in edges:
        for sign in (1.0, -1.0):
            q, out = sign * edge, math.nextafter(sign * edge, sign * away)
            assert r.contains(q) and not r.contains(out)
            link.from_rocker(q, driven)  # solves: no UnreachableError at the reported end
            with pytest.raises(UnreachableError):
                link.from_rocker(out, driven)
            with pytest.raises(UnreachableError):
                link.from_rocker(np.array([q, out]), driven)
            both = link.from_rocker(np.array([q, out, q + 2 * math.pi]), driven, on_invalid='nan')
            assert np.isfinite(both.theta[0]) and np.isnan(both.theta[1]) and np.isnan(both.other[1])
            assert r.contains(q + 2 * math.pi) == bool(np.isfinite(both.theta[2]))
