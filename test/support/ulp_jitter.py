"""Make this CPU look like another: transcendental results of numpy and of the math module moved by one ulp.

numpy's SIMD transcendentals (arctan2, sin, cos, ... on AVX2/AVX-512) are not correctly rounded and may differ
from libm (Python's math module) and from another CPU's numpy by an ulp or two; another platform's libm may differ
from this one's too. A test that holds only on the CPU it was written on compares two float paths bit for bit
somewhere, or lets a comparison one ulp from its threshold decide something. With the jitter on, every result of
the wrapped numpy ufuncs and math functions moves by one ulp, up or down, on a deterministic share of the elements
(by default every element): which ones and which way is a hash of the input bits, of the seed and, for numpy, of
the element's position in the call (numpy dispatches by layout: a strided or overlapping array may take libm's loop
where a contiguous one takes the SIMD loop, so the same value can round differently in another place), or every
moved result goes up, or every one down (``direction``). The same call always gives the same output; numpy calls
with out= are moved in place. Left alone, as every real implementation returns them exactly: special values (a
zero or non-finite input or result, a result at the function's extreme such as cos x = -1, where the function is
flat) and the leading-term regimes (for |x| < 2**-26: cos x = 1, exp x = 1, sin x = x and the like; arctan2(y, x)
and hypot(x, y) when one input is below 2**-26 times the other). math.sqrt and np.sqrt are correctly rounded by
IEEE 754 everywhere, so they are not moved.

Turn it on for a pytest run with ``--ulp-jitter`` or ``FOURBAR_ULP_JITTER=1``; ``--ulp-jitter-share`` (default 1:
every element), ``--ulp-jitter-seed`` (an integer: another choice of directions and elements) and
``--ulp-jitter-direction`` (hash, up or down), or the same names as FOURBAR_ULP_JITTER_* variables. The package
looks numpy's functions up as ``np.<name>`` at call time (test_ulp_jitter checks it); module-level aliases of math
functions in loaded fourbar_ros modules (the core's scalar fast paths bind ``_sin = math.sin``) are replaced too.
"""

from __future__ import annotations

import contextlib
import math
import sys
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np

#: The wrapped ufuncs and the closed range of each one's results (a moved value stays inside it, as a real
#: implementation's does: |sin| never exceeds 1, arctan2 never leaves [-pi, pi]).
UFUNCS: dict[str, tuple[float, float]] = {
    'sin': (-1.0, 1.0),
    'cos': (-1.0, 1.0),
    'tan': (-math.inf, math.inf),
    'arcsin': (-math.pi / 2, math.pi / 2),
    'arccos': (0.0, math.pi),
    'arctan': (-math.pi / 2, math.pi / 2),
    'arctan2': (-math.pi, math.pi),
    'hypot': (0.0, math.inf),
    'exp': (0.0, math.inf),
    'expm1': (-1.0, math.inf),
    'log': (-math.inf, math.inf),
    'log1p': (-math.inf, math.inf),
    'log2': (-math.inf, math.inf),
    'log10': (-math.inf, math.inf),
    'tanh': (-1.0, 1.0),
}

#: The math module's counterparts, with the same result ranges.
MATH_FUNCS: dict[str, tuple[float, float]] = {
    'sin': UFUNCS['sin'], 'cos': UFUNCS['cos'], 'tan': UFUNCS['tan'], 'asin': UFUNCS['arcsin'],
    'acos': UFUNCS['arccos'], 'atan': UFUNCS['arctan'], 'atan2': UFUNCS['arctan2'], 'hypot': UFUNCS['hypot'],
    'exp': UFUNCS['exp'], 'expm1': UFUNCS['expm1'], 'log': UFUNCS['log'], 'log1p': UFUNCS['log1p'],
    'log2': UFUNCS['log2'], 'log10': UFUNCS['log10'], 'tanh': UFUNCS['tanh'],
}
_MATH_NUMPY = {'asin': 'arcsin', 'acos': 'arccos', 'atan': 'arctan', 'atan2': 'arctan2'}

DEFAULT_SHARE = 1.0
#: hash: each moved result up or down by a hash; up, down: every moved result that way.
DIRECTIONS = ('hash', 'up', 'down')

_M1 = np.uint64(0x9E3779B97F4A7C15)
_M2 = np.uint64(0xC2B2AE3D27D4EB4F)
_M3 = np.uint64(0xBF58476D1CE4E5B9)
_S29 = np.uint64(29)
_S32 = np.uint64(32)


#: Unary ufuncs whose result is its leading term, exactly rounded, for |x| < TINY (cos x = 1, sin x = x, ...).
LEADING_TERM = {'sin', 'cos', 'tan', 'arcsin', 'arccos', 'arctan', 'exp', 'expm1', 'log1p', 'tanh'}
TINY = 2.0**-26


def selection(inputs: tuple[Any, ...], share: float, seed: int = 0, direction: str = 'hash',
              positional: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """(moved, up): which elements move and in which direction, from a hash of the inputs' float64 bits, the seed
    and (``positional``) each element's flat position in the broadcast result (arrays of that shape, 0-d for
    scalars); ``direction`` up or down overrides the hashed direction."""
    arrays = [np.asarray(x, dtype=np.float64) for x in inputs]
    shape = np.broadcast_shapes(*(a.shape for a in arrays))
    n = math.prod(shape)
    # 1-d throughout: 0-d numpy arithmetic would return (warning) scalars
    key = np.arange(n, dtype=np.uint64) if positional else np.zeros(n, dtype=np.uint64)
    key += np.uint64(seed * 0x632BE59BD9B4E019 % 2**64)
    special = np.zeros(n, dtype=bool)
    with np.errstate(over='ignore'):
        for i, a in enumerate(arrays):
            f = np.ascontiguousarray(np.broadcast_to(a, shape)).reshape(n)
            special |= (f == 0.0) | ~np.isfinite(f)
            key ^= f.view(np.uint64) * (_M1 if i == 0 else _M2)
            key ^= key >> _S29
            key *= _M3
        key ^= key >> _S32
    threshold = np.uint64(min(int(share * 2.0**31), 2**31))
    moved = ((key & np.uint64(0x7FFFFFFF)) < threshold) & ~special
    if direction == 'hash':
        up = (key >> np.uint64(40)) & np.uint64(1) == np.uint64(1)
    else:
        up = np.full(n, direction == 'up')
    return moved.reshape(shape), up.reshape(shape)


class JitteredUfunc:
    """A numpy ufunc whose float results move by one ulp on a hashed share of the elements."""

    def __init__(self, ufunc: np.ufunc, share: float, bounds: tuple[float, float], seed: int = 0,
                 direction: str = 'hash') -> None:
        self.ufunc = ufunc
        self.share = share
        self.seed = seed
        self.direction = direction
        self.low, self.high = bounds
        self.__name__ = ufunc.__name__
        self.__doc__ = ufunc.__doc__

    def _leading_term(self, inputs: tuple[Any, ...], shape: tuple[int, ...]) -> np.ndarray:
        """Where the result is its leading term, which every implementation returns exactly rounded."""
        a = [np.abs(np.broadcast_to(np.asarray(x, dtype=np.float64), shape)) for x in inputs]
        with np.errstate(invalid='ignore', over='ignore'):
            if self.__name__ in LEADING_TERM:
                return a[0] < TINY
            if self.__name__ in ('arctan2', 'hypot'):
                return (a[0] < TINY * a[1]) | (a[1] < TINY * a[0])
        return np.zeros(shape, dtype=bool)

    def __getattr__(self, name: str) -> Any:  # nin, nout, reduce, outer, ...: the real ufunc's
        return getattr(self.ufunc, name)

    def __repr__(self) -> str:
        return f'<ulp-jittered {self.ufunc!r}>'

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        inputs = args[:self.ufunc.nin]
        if len(inputs) < self.ufunc.nin or any(np.iscomplexobj(x) for x in inputs):
            return self.ufunc(*args, **kwargs)
        # Chosen before the call: with out= aliasing an input, the input bits are gone afterwards.
        try:
            moved, up = selection(inputs, self.share, self.seed, self.direction)
            moved &= ~self._leading_term(inputs, moved.shape)
        except (TypeError, ValueError):  # object arrays and the like: not ours to move
            return self.ufunc(*args, **kwargs)
        where = kwargs.get('where', True)
        if where is not True:
            moved &= np.broadcast_to(np.asarray(where, dtype=bool), moved.shape)
        result = self.ufunc(*args, **kwargs)
        if isinstance(result, tuple) or np.asarray(result).dtype.kind != 'f':
            return result
        res = np.asarray(result)
        if res.shape != moved.shape:  # broadcast against out= of a larger shape
            moved = np.broadcast_to(moved, res.shape)
            up = np.broadcast_to(up, res.shape)
        # A result at the function's extreme (cos = -1, |sin| = 1, ...) is where the function is flat: exact.
        moved = moved & np.isfinite(res) & (res != 0.0) & (res != self.low) & (res != self.high)
        if not moved.any():
            return result
        toward = np.where(up, np.inf, -np.inf).astype(res.dtype)
        shifted = np.clip(np.nextafter(res, toward), self.low, self.high).astype(res.dtype)
        if isinstance(result, np.ndarray):
            np.copyto(result, shifted, where=moved)
            return result
        return res.dtype.type(shifted)


class JitteredMath:
    """A math-module function whose result moves by one ulp as a JitteredUfunc's does (no position: a scalar)."""

    def __init__(self, func: Callable[..., float], name: str, share: float, seed: int = 0,
                 direction: str = 'hash') -> None:
        self.func = func
        self.name = name
        self.__name__ = name
        self.nin = 2 if name in ('atan2', 'hypot') else 1
        self.share, self.seed, self.direction = share, seed, direction
        self.low, self.high = MATH_FUNCS[name]
        self._leading = _MATH_NUMPY.get(name, name)

    def __repr__(self) -> str:
        return f'<ulp-jittered math.{self.name}>'

    def __call__(self, *args: float) -> float:
        result = self.func(*args)
        if len(args) != self.nin or not isinstance(result, float) or not math.isfinite(result) or result == 0.0 \
                or result in (self.low, self.high):
            return result
        try:
            xs = tuple(float(a) for a in args)
        except (TypeError, ValueError, OverflowError):
            return result
        if any(x == 0.0 or not math.isfinite(x) for x in xs):
            return result
        if self._leading in LEADING_TERM and abs(xs[0]) < TINY:
            return result
        if self.nin == 2 and (abs(xs[0]) < TINY * abs(xs[1]) or abs(xs[1]) < TINY * abs(xs[0])):
            return result
        moved, up = selection(xs, self.share, self.seed, self.direction, positional=False)
        if not bool(moved):
            return result
        return min(max(math.nextafter(result, math.inf if bool(up) else -math.inf), self.low), self.high)


@contextlib.contextmanager
def jittered(share: float = DEFAULT_SHARE, seed: int = 0, names: tuple[str, ...] = tuple(UFUNCS),
             direction: str = 'hash', math_names: tuple[str, ...] = ()) -> Iterator[None]:
    """Within the block, numpy's transcendental ufuncs (as np.<name>) and the math functions ``math_names`` are
    the jittered ones."""
    undo = install(share, seed, names, direction, math_names)
    try:
        yield
    finally:
        undo()


def install(share: float = DEFAULT_SHARE, seed: int = 0, names: tuple[str, ...] = tuple(UFUNCS),
            direction: str = 'hash', math_names: tuple[str, ...] = tuple(MATH_FUNCS)) -> Callable[[], None]:
    """Replace np.<name> and math.<name> (and the loaded fourbar_ros modules' aliases of math functions) by their
    jittered wrappers; return the function that restores the originals."""
    if direction not in DIRECTIONS:
        raise ValueError(f'direction {direction!r}: one of {DIRECTIONS}')
    originals = {name: getattr(np, name) for name in names}
    for name, func in originals.items():
        base = func.ufunc if isinstance(func, JitteredUfunc) else func
        setattr(np, name, JitteredUfunc(base, share, UFUNCS[name], seed, direction))
    math_originals = {name: getattr(math, name) for name in math_names}
    wrappers: dict[int, JitteredMath] = {}
    for name, func in math_originals.items():
        base = func.func if isinstance(func, JitteredMath) else func
        wrappers[id(base)] = JitteredMath(base, name, share, seed, direction)
        setattr(math, name, wrappers[id(base)])
    aliases: list[tuple[Any, str, Any]] = []
    for module_name, module in list(sys.modules.items()):
        if module is None or not module_name.startswith('fourbar_ros'):
            continue
        for attr, value in list(vars(module).items()):
            if id(value) in wrappers and not attr.startswith('__'):
                aliases.append((module, attr, value))
                setattr(module, attr, wrappers[id(value)])

    def undo() -> None:
        for name, func in originals.items():
            setattr(np, name, func)
        for name, func in math_originals.items():
            setattr(math, name, func)
        for module, attr, value in aliases:
            setattr(module, attr, value)

    return undo
