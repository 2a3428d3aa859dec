"""Make this CPU's numpy look like another's: transcendental ufunc results moved by one ulp on a fixed share.

numpy's SIMD transcendentals (arctan2, sin, cos, ... on AVX2/AVX-512) are not correctly rounded and may differ
from libm (Python's math module) and from another CPU's numpy by an ulp or two. A test that holds only on the
CPU it was written on compares two float paths bit for bit somewhere. With the jitter on, every result of the
wrapped ufuncs moves by one ulp (up or down) on a deterministic share of the elements, chosen by a hash of the
input bits and of the element's position in the call (numpy dispatches by layout: a strided or overlapping array
may take libm's loop where a contiguous one takes the SIMD loop, so the same value can round differently in
another place). The same call always gives the same output; calls with out= are moved in place. Left alone, as
every real implementation returns them exactly: special values (a zero or non-finite input or result, a result
at the function's extreme such as cos x = -1, where the function is flat) and the leading-term regimes (for
|x| < 2**-26: cos x = 1, exp x = 1, sin x = x and the like; arctan2(y, x) and hypot(x, y) when one input is
below 2**-26 times the other). math.* (the scalar paths) is untouched.

Turn it on for a pytest run with ``--ulp-jitter`` or ``FOURBAR_ULP_JITTER=1``. The share of elements moved is
``--ulp-jitter-share`` or ``FOURBAR_ULP_JITTER_SHARE`` (default 0.25); ``--ulp-jitter-seed`` or
``FOURBAR_ULP_JITTER_SEED`` (an integer) picks another set. The package looks numpy's functions up as
``np.<name>`` at call time, so replacing numpy's module attributes reaches it; code binding a ufunc to another
name at import time would escape (test_ulp_jitter checks that the package has no such binding).
"""

from __future__ import annotations

import contextlib
import math
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

DEFAULT_SHARE = 0.25

_M1 = np.uint64(0x9E3779B97F4A7C15)
_M2 = np.uint64(0xC2B2AE3D27D4EB4F)
_M3 = np.uint64(0xBF58476D1CE4E5B9)
_S29 = np.uint64(29)
_S32 = np.uint64(32)


#: Unary ufuncs whose result is its leading term, exactly rounded, for |x| < TINY (cos x = 1, sin x = x, ...).
LEADING_TERM = {'sin', 'cos', 'tan', 'arcsin', 'arccos', 'arctan', 'exp', 'expm1', 'log1p', 'tanh'}
TINY = 2.0**-26


def selection(inputs: tuple[Any, ...], share: float, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(moved, up): which elements move and in which direction, from a hash of the inputs' float64 bits and of
    each element's flat position in the broadcast result (arrays of that shape, 0-d for scalars)."""
    arrays = [np.asarray(x, dtype=np.float64) for x in inputs]
    shape = np.broadcast_shapes(*(a.shape for a in arrays))
    n = math.prod(shape)
    key = np.arange(n, dtype=np.uint64)  # 1-d throughout: 0-d numpy arithmetic would return (warning) scalars
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
    up = (key >> np.uint64(40)) & np.uint64(1) == np.uint64(1)
    return moved.reshape(shape), up.reshape(shape)


class JitteredUfunc:
    """A numpy ufunc whose float results move by one ulp on a hashed share of the elements."""

    def __init__(self, ufunc: np.ufunc, share: float, bounds: tuple[float, float], seed: int = 0) -> None:
        self.ufunc = ufunc
        self.share = share
        self.seed = seed
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
            moved, up = selection(inputs, self.share, self.seed)
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


@contextlib.contextmanager
def jittered(share: float = DEFAULT_SHARE, seed: int = 0, names: tuple[str, ...] = tuple(UFUNCS)) -> Iterator[None]:
    """Within the block, numpy's transcendental ufuncs (as np.<name>) are the jittered ones."""
    undo = install(share, seed, names)
    try:
        yield
    finally:
        undo()


def install(share: float = DEFAULT_SHARE, seed: int = 0, names: tuple[str, ...] = tuple(UFUNCS)) -> Callable[[], None]:
    """Replace np.<name> by its jittered wrapper; return the function that restores the originals."""
    originals = {name: getattr(np, name) for name in names}
    for name, func in originals.items():
        base = func.ufunc if isinstance(func, JitteredUfunc) else func
        setattr(np, name, JitteredUfunc(base, share, UFUNCS[name], seed))

    def undo() -> None:
        for name, func in originals.items():
            setattr(np, name, func)

    return undo
