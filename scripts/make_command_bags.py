#!/usr/bin/env python3
"""Write the deterministic antenna command bags (std_msgs/msg/Float64, theta in rad).

    .venv/bin/python scripts/make_command_bags.py            # -> test/data/bags/, fourbar_ros/data/demo_sweep
    .venv/bin/python scripts/make_command_bags.py --out DIR  # all bags (and demo_sweep) under DIR

Five command streams, each in mcap and sqlite3 storage (``<kind>_<storage>``), plus the bundled
demo bag ``demo_sweep`` (the sweep, mcap). Topic ``/antenna_angle_cmd``: where the node's relative
subscription ``antenna_angle_cmd`` resolves in the root namespace, so ``ros2 bag play BAG`` reaches
a node started without a namespace. The tilt limits come from the parameter file (default
config/antenna.yaml), so the bags probe exactly the shipped limits.

Only +, -, *, / and ``random.random()`` (whose sequence Python guarantees for a seed) make the
values, so every platform writes the same bytes. The expected node outputs are not stored:
tests compute them from the core.
"""

from __future__ import annotations

import argparse
import math
import random
import shutil
import sys
from collections.abc import Callable
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
if str(REPO) not in sys.path:  # runnable without installing the package
    sys.path.insert(0, str(REPO))

from fourbar_ros.bags.storage import DEFAULT_STORAGE, Storage, write_command_bag  # noqa: E402
from fourbar_ros.config.antenna_config import AntennaConfig, load_config  # noqa: E402

#: First stamp of every bag: 2023-11-14T22:13:20Z, in ns since the epoch.
T0_NS = 1_700_000_000 * 1_000_000_000
DEG = math.pi / 180.0  # a product of constants only; multiplying by it is exact IEEE arithmetic
SEED = 20180501
DEFAULT_OUT = REPO / 'test' / 'data' / 'bags'
DEFAULT_DEMO = REPO / 'fourbar_ros' / 'data' / 'demo_sweep'
DEFAULT_PARAMS = REPO / 'config' / 'antenna.yaml'

Stream = tuple[list[int], list[float]]


def _clock(n: int, period_ns: int) -> list[int]:
    return [T0_NS + k * period_ns for k in range(n)]


def _lerp(a: float, b: float, k: int, n: int) -> float:
    """a + (b - a) k / n with both ends exact (k = 0 gives a, k = n gives b)."""
    if k == 0:
        return a
    if k == n:
        return b
    return a + (b - a) * k / n


def sweep(cfg: AntennaConfig) -> Stream:
    """Slow sweep theta_min -> theta_max -> theta_min at about 0.5 deg/s, 10 Hz (ends exact)."""
    n = max(2, round((cfg.theta_max - cfg.theta_min) / (0.05 * DEG)))
    up = [_lerp(cfg.theta_min, cfg.theta_max, k, n) for k in range(n + 1)]
    values = up + up[-2::-1]
    return _clock(len(values), 100_000_000), values


def steps(cfg: AntennaConfig) -> Stream:
    """Steps between held levels (each held 1 s at 10 Hz, so the node sees repeated commands)."""
    lo, hi = cfg.theta_min, cfg.theta_max
    levels = [0.0, 0.5 * hi, 0.5 * lo, hi, lo, 0.25 * hi, 0.0]
    values = [level for level in levels for _ in range(10)]
    return _clock(len(values), 100_000_000), values


def fast_ramp(cfg: AntennaConfig) -> Stream:
    """Ramps over the whole range in 0.2 s (about 65 deg/s for the shipped limits), 100 Hz, twice."""
    n = 20
    up = [_lerp(cfg.theta_min, cfg.theta_max, k, n) for k in range(n + 1)]
    down = up[-2::-1]
    values = up + down[1:] + up + down[1:]
    return _clock(len(values), 10_000_000), values


def jitter(cfg: AntennaConfig) -> Stream:
    """A noisy, jittered stream: a slow triangle wave plus noise, 50 Hz with +-8 ms timing jitter.

    Noise: sum of 12 uniforms minus 6 (about unit normal), scaled to 0.3 deg; values clipped into
    [theta_min, theta_max], so every command is valid. The stamps stay increasing.
    """
    rng = random.Random(SEED)
    lo, hi = cfg.theta_min, cfg.theta_max
    mid, half = 0.5 * (lo + hi), 0.4 * (hi - lo)
    n, period = 300, 20_000_000
    stamps: list[int] = []
    values: list[float] = []
    for k in range(n):
        phase = (k % 100) / 50.0  # 0..2: a 2 s triangle wave
        tri = phase if phase <= 1.0 else 2.0 - phase
        noise = (sum(rng.random() for _ in range(12)) - 6.0) * (0.3 * DEG)
        values.append(min(hi, max(lo, mid + half * (2.0 * tri - 1.0) + noise)))
        stamps.append(T0_NS + k * period + int((rng.random() - 0.5) * 16_000_000))
    return stamps, values


def bad_values(cfg: AntennaConfig) -> Stream:
    """Bad commands, each followed by a good one (so a node that drops the bad keeps serving).

    Bad: NaN, -NaN, +-inf, one ulp outside each limit, far outside the limits but reachable,
    beyond the linkage's reach, a full turn past a limit (reachable modulo 2 pi), huge finite.
    Good (inside or exactly at the limits): theta_min, theta_max, 0.0, -0.0, mid-range.
    The stream ends with a good command.
    """
    lo, hi = cfg.theta_min, cfg.theta_max
    reach = cfg.linkage.reach().theta_max
    bad = [math.nan, -math.nan, math.inf, -math.inf,
           math.nextafter(hi, math.inf), math.nextafter(lo, -math.inf),
           hi + 10.0 * DEG, lo - 10.0 * DEG,
           reach + 5.0 * DEG, -(reach + 5.0 * DEG),
           hi + 2.0 * math.pi, 1.0e308]
    good = [lo, hi, 0.0, -0.0, 0.5 * (lo + hi), 0.5 * hi]
    values: list[float] = [good[0]]
    for k, b in enumerate(bad):
        values += [b, good[(k + 1) % len(good)]]
    values += [hi, lo]  # exactly at the limits, back to back
    return _clock(len(values), 50_000_000), values


KINDS: dict[str, Callable[[AntennaConfig], Stream]] = {
    'sweep': sweep, 'steps': steps, 'fast_ramp': fast_ramp, 'jitter': jitter, 'bad_values': bad_values,
}


def _custom(kind: str, cfg: AntennaConfig, params: Path) -> dict[str, str]:
    doc = (KINDS[kind].__doc__ or '').strip().splitlines()[0]
    return {'fourbar.kind': kind, 'fourbar.description': doc,
            'fourbar.generator': 'scripts/make_command_bags.py',
            'fourbar.params': params.name,
            'fourbar.theta_min': repr(cfg.theta_min), 'fourbar.theta_max': repr(cfg.theta_max)}


def write_all(out: Path, demo: Path | None, params: Path, force: bool = False) -> list[Path]:
    """Write every bag under ``out`` (and the demo bag at ``demo``); return the bag paths."""
    cfg = load_config(params)
    targets: list[tuple[Path, str, Storage]] = [
        (out / f'{kind}_{storage}', kind, storage) for kind in KINDS for storage in Storage]
    if demo is not None:
        targets.append((demo, 'sweep', DEFAULT_STORAGE))
    for path, _, _ in targets:
        if path.exists():
            if not force:
                raise SystemExit(f'make_command_bags: error: {path} exists (use --force to replace)')
            shutil.rmtree(path)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    for path, kind, storage in targets:
        path.parent.mkdir(parents=True, exist_ok=True)
        stamps, values = KINDS[kind](cfg)
        written.append(write_command_bag(path, stamps, values, storage,
                                         custom_data=_custom(kind, cfg, params)))
    return written


def main(argv: list[str] | None = None) -> int:
    """Command line entry point."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--out', type=Path, help=f'directory for the bags (default {DEFAULT_OUT}); '
                        'with --out, demo_sweep goes under it too')
    parser.add_argument('--params', type=Path, default=DEFAULT_PARAMS,
                        help='ROS 2 parameter file giving the tilt limits (default config/antenna.yaml)')
    parser.add_argument('--force', action='store_true', help='replace existing bags')
    args = parser.parse_args(argv)
    out = args.out or DEFAULT_OUT
    demo = out / 'demo_sweep' if args.out else DEFAULT_DEMO
    for path in write_all(out, demo, args.params, args.force):
        print(path)
    return 0


if __name__ == '__main__':
    sys.exit(main())
