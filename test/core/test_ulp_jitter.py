"""The one-ulp wrapper that stands in for another CPU's numpy (ulp_jitter) and the comparison helper (ulp_bounds)."""

from __future__ import annotations

import ast
import math
import sys
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from support import ulp_jitter
from support.paths import REPO
from support.ulp_bounds import EPS, assert_close_ulps

from fourbar_ros import AntennaLinkage


@pytest.fixture
def plain_numpy() -> Iterator[None]:
    """Undo a session-wide --ulp-jitter (and --ulp-jitter-math) for this test, so 'unmoved' is the library's own
    result: numpy's ufuncs, the math module's functions and the package's aliases of them."""
    places: list[tuple[Any, str, Any]] = [(np, n, getattr(np, n)) for n in ulp_jitter.UFUNCS]
    places += [(math, n, getattr(math, n)) for n in ulp_jitter.MATH_FUNCS]
    places += [(m, a, v) for name, m in list(sys.modules.items()) if name.startswith('fourbar_ros') and m is not None
               for a, v in list(vars(m).items()) if isinstance(v, ulp_jitter.JitteredMath)]
    for module, name, func in places:
        if isinstance(func, ulp_jitter.JitteredUfunc):
            setattr(module, name, func.ufunc)
        elif isinstance(func, ulp_jitter.JitteredMath):
            setattr(module, name, func.func)
    yield
    for module, name, func in places:
        setattr(module, name, func)


@pytest.mark.parametrize('share', [0.06, 0.25, 1.0])
@pytest.mark.parametrize('name', ['sin', 'cos', 'arctan2', 'arctan', 'exp', 'log', 'hypot'])
def test_moves_the_share_asked_by_one_ulp(plain_numpy: None, name: str, share: float) -> None:
    x = np.linspace(0.01, 3.0, 20001)
    args = (x, x[::-1]) if name in ('arctan2', 'hypot') else (x,)
    plain = getattr(np, name)(*args)
    with ulp_jitter.jittered(share):
        moved = getattr(np, name)(*args)
        again = getattr(np, name)(*args)
    changed = moved != plain
    assert abs(changed.mean() - share) < 0.02  # 20001 draws: the binomial spread is below 0.004
    ulps = np.abs(moved - plain) / np.spacing(np.abs(plain))
    assert np.all(ulps[changed] == 1.0)
    assert 0.4 < np.mean(moved[changed] > plain[changed]) < 0.6  # up and down alike
    assert np.array_equal(moved, again)  # deterministic
    assert isinstance(getattr(np, name), np.ufunc)  # restored on leaving the block


def test_out_argument_is_moved_in_place_and_inputs_read_first(plain_numpy: None) -> None:
    x = np.linspace(-1.0, 1.0, 4001)
    plain = np.cos(x)
    with ulp_jitter.jittered(0.5):
        fresh = np.cos(x)
        buf = x.copy()
        res = np.cos(buf, out=buf)  # out= aliases the input, as the core's solve does
    assert res is buf
    assert np.array_equal(buf, fresh) and np.mean(buf != plain) > 0.4


def test_leaves_math_scalars_and_exact_values_alone(plain_numpy: None) -> None:
    x = np.linspace(0.01, 3.0, 201)
    libm = [(math.sin(v), math.cos(v), math.atan2(v, 0.7)) for v in x]
    with ulp_jitter.jittered(1.0):
        assert [(math.sin(v), math.cos(v), math.atan2(v, 0.7)) for v in x] == libm  # the scalar path: untouched
        assert np.sin(0.0) == 0.0 and np.cos(0.0) == 1.0 and np.arctan2(0.0, 1.0) == 0.0
        assert np.all(np.abs(np.cos(np.linspace(-0.1, 0.1, 101))) <= 1.0)  # never past the function's range
        tiny = np.geomspace(1e-300, 1e-8, 101)  # leading-term regime: cos x = 1, sin x = x in every libm
        assert np.all(np.cos(tiny) == 1.0) and np.array_equal(np.sin(tiny), tiny)
        assert np.array_equal(np.arctan2(tiny, 1.0), tiny) and np.all(np.hypot(1.0, tiny) == 1.0)
        flat = np.full(64, math.pi)  # cos(pi) = -1 and sin(pi/2) = 1 at every position: flat extremes are exact
        assert np.all(np.cos(flat) == -1.0) and np.all(np.sin(flat / 2) == 1.0)
        assert abs(float(np.arctan2(1e-300, -1.0))) <= math.pi
        assert math.isnan(np.sin(np.nan)) and np.exp(-np.inf) == 0.0
        assert np.sin.nin == 1 and np.arctan2.nout == 1  # the ufunc's attributes are still there
        s = np.sin(0.3)
        assert isinstance(s, np.float64) and abs(s - math.sin(0.3)) == math.ulp(math.sin(0.3))  # scalars too
    assert isinstance(np.sin, np.ufunc)


def test_reaches_the_core(plain_numpy: None) -> None:
    link = AntennaLinkage(0.180, 0.060, 0.102)
    t = np.linspace(-0.6, 0.6, 1001)
    plain = link.rocker_angles(t).gamma
    with ulp_jitter.jittered(1.0):
        moved = link.rocker_angles(t).gamma
    assert np.mean(moved != plain) > 0.5
    assert_close_ulps(moved, plain, 8, 1.0 + np.abs(plain) + np.abs(t * 1.6))


def test_package_looks_ufuncs_up_at_call_time() -> None:
    """A module-level alias (from numpy import sin, _atan2 = np.arctan2) would escape the wrapper."""
    escapes = []
    for path in sorted([*(REPO / 'fourbar_ros').rglob('*.py'), *(REPO / 'benchmarks').rglob('*.py')]):
        tree = ast.parse(path.read_text(), str(path))
        called = {id(n.func) for n in ast.walk(tree) if isinstance(n, ast.Call)}
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.module and node.module.split('.')[0] == 'numpy':
                escapes += [f'{path.name}:{node.lineno} from numpy import {a.name}' for a in node.names
                            if a.name in ulp_jitter.UFUNCS or a.name == '*']
            if (isinstance(node, ast.Attribute) and node.attr in ulp_jitter.UFUNCS
                    and isinstance(node.value, ast.Name) and node.value.id in ('np', 'numpy')
                    and id(node) not in called):
                escapes.append(f'{path.name}:{node.lineno} np.{node.attr} bound without a call')
    assert escapes == []


def test_assert_close_ulps_passes_and_fails() -> None:
    a = np.array([1.0, 2.0, np.nan, np.inf])
    assert_close_ulps(a, a, 0)
    assert_close_ulps(a + np.array([EPS, 2 * EPS, 0, 0]), a, 1.0)  # 1 ulp of |expected| each
    with pytest.raises(AssertionError, match='1 of 4 elements differ by more than 1 ulps'):
        assert_close_ulps(a + np.array([0, 8 * EPS, 0, 0]), a, 1.0)
    assert_close_ulps(1e-17, 0.0, 1.0, scale=1.0)  # absolute via scale
    with pytest.raises(AssertionError, match='NaN at different elements'):
        assert_close_ulps([np.nan, 1.0], [1.0, 1.0], 4)
    with pytest.raises(AssertionError, match='infinities differ'):
        assert_close_ulps([np.inf], [-np.inf], 4)


@pytest.mark.parametrize('direction', ['up', 'down'])
def test_a_direction_moves_every_element_that_way(plain_numpy: None, direction: str) -> None:
    x = np.linspace(0.01, 3.0, 2001)
    plain = np.sin(x)
    with ulp_jitter.jittered(1.0, direction=direction):
        moved = np.sin(x)
    changed = moved != plain
    assert changed.mean() > 0.99  # every element but the flat extreme, if sampled
    assert np.all((moved[changed] > plain[changed]) == (direction == 'up'))


def test_math_functions_and_the_packages_aliases_of_them_move_too(plain_numpy: None) -> None:
    from fourbar_ros.core import dyad

    x = [0.1 + 0.01 * k for k in range(300)]
    plain = [(math.sin(v), math.atan2(v, 0.7), dyad._sin(v)) for v in x]
    with ulp_jitter.jittered(1.0, seed=3, math_names=tuple(ulp_jitter.MATH_FUNCS)):
        moved = [(math.sin(v), math.atan2(v, 0.7), dyad._sin(v)) for v in x]
        again = [(math.sin(v), math.atan2(v, 0.7), dyad._sin(v)) for v in x]
        assert math.sin(0.0) == 0.0 and math.cos(1e-300) == 1.0 and math.atan2(1e-300, 1.0) == 1e-300
    assert moved == again  # deterministic
    for (s0, a0, _), (s1, a1, d1) in zip(plain, moved, strict=True):
        assert abs(s1 - s0) == math.ulp(s0) and abs(a1 - a0) == math.ulp(a0) and d1 == s1
    assert [(math.sin(v), math.atan2(v, 0.7), dyad._sin(v)) for v in x] == plain  # restored
