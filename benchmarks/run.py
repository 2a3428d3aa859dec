"""Entry point: ``python -m benchmarks.run [--quick] [--skip-node-bags]`` (``make bench``, ``make bench-quick``).

Runs the common sweep (accuracy of every method against the 50-digit reference), the timings (scalar and
vectorized, interleaved medians on the Turnantenna geometry, with the ufunc floor and the Python call overhead
as same-run baselines), the numerical stress suite, the completion and trajectory benchmarks, and the node, bag
(replay) and `fourbar process` benchmarks; writes results.json, markdown tables and PNG plots under docs/bench/ and
the README section docs/benchmarks.md. Exit status 1 if the shipped method is off the vectorized Pareto front.
"""

from __future__ import annotations

import argparse
import importlib
import math
import sys
import time
from typing import Any

from benchmarks import report, stress
from benchmarks.cases import TURNANTENNA
from benchmarks.methods import SHIPPED, all_methods, linkage
from benchmarks.peers import peer_methods, peer_versions
from benchmarks.sweep import MethodResult, accuracy, dominators, pareto_front, timings
from benchmarks.timing import machine_info

#: The benchmarks of other modules: results.json key -> module of benchmarks/ with ``run(quick)`` (``module:function``
#: names another function). The last four are left out by --skip-node-bags.
SECTIONS = {'completion': 'completion_peers', 'trajectory': 'trajectory_bench', 'node': 'node_bench',
            'node_completion': 'node_bench:run_completion', 'bag': 'bag_bench', 'process': 'process_bench'}
NODE_AND_BAGS = ('node', 'node_completion', 'bag', 'process')


def guarded_bench(module: str, quick: bool) -> dict[str, Any]:
    """Figures from benchmarks.<module>.run(quick); a failure is reported in the figures, not raised, so
    one broken benchmark (say, no ROS on this machine) does not take the rest of the report down."""
    name, _, function = module.partition(':')
    try:
        return dict(getattr(importlib.import_module(f'benchmarks.{name}'), function or 'run')(quick))
    except Exception as exc:
        return {'error': f'{type(exc).__name__}: {exc}'}


def ratio(a: float | None, b: float | None) -> float | None:
    """a / b, None when either is missing or b is 0."""
    return None if a is None or b is None or b == 0 else a / b


def lookup_summary(by: dict[str, MethodResult]) -> dict[str, Any]:
    """The offered table (fourbar_ros.core.lookup) on Turnantenna's tilt range; its sweep figures against shipped."""
    from fourbar_ros.core.lookup import RockerTable

    tilt = (math.radians(-6.0), math.radians(7.0))
    tables = []
    for tol in (1e-6, 1e-9):
        t = RockerTable.build(linkage(TURNANTENNA), *tilt, tolerance=tol)
        tables.append({'tolerance_rad': tol, 'points': t.points, 'max_error_rad': t.max_error,
                       'max_error_float32_rad': t.max_error_float32, 'float32_bytes': 2 * 4 * 4 * (t.points - 1)})
    ship, lk = by[SHIPPED], by['lookup-1e-06']
    return {'tilt_range_rad': list(tilt), 'tables': tables, 'sweep_max_error_rad': lk.max_error,
            'time_ratio_to_shipped_scalar': ratio(lk.seconds_per_solve_scalar, ship.seconds_per_solve_scalar),
            'time_ratio_to_shipped_vector': ratio(lk.seconds_per_solve_vector, ship.seconds_per_solve_vector)}


def headline(by: dict[str, MethodResult], results: list[MethodResult], base: dict[str, float]) -> dict[str, Any]:
    """The shipped method against the floor, the bare math, its own array path and the annex formula."""
    shipped, annex = by[SHIPPED], by['annex']
    return {
        'floor_ratio': ratio(shipped.seconds_per_solve_vector, base['floor_per_element']),
        'floor_ratio_target': 1.3,
        'scalar_ratio_to_stable_plain': ratio(shipped.seconds_per_solve_scalar, base['stable_plain_scalar_per_call']),
        'array_path_one_ratio_to_scalar': ratio(base['array_path_one_angle_per_call'],
                                                shipped.seconds_per_solve_scalar),
        'annex_scalar_ratio_to_stable_plain': ratio(annex.seconds_per_solve_scalar,
                                                    base['stable_plain_scalar_per_call']),
        'scalar_ratio_to_annex': ratio(shipped.seconds_per_solve_scalar, annex.seconds_per_solve_scalar),
        'vector_ratio_to_annex': ratio(shipped.seconds_per_solve_vector, annex.seconds_per_solve_vector),
        'error_ratio_annex_to_shipped': ratio(annex.max_error, shipped.max_error),
        'shipped_on_pareto_front_vector': shipped.pareto,
        'shipped_on_pareto_front_scalar': shipped.pareto_scalar,
        'shipped_dominated_by_vector': dominators(results, SHIPPED, vector=True),
        'shipped_dominated_by_scalar': dominators(results, SHIPPED, vector=False),
    }


def peer_figures(by: dict[str, MethodResult]) -> dict[str, Any]:
    """Each installed peer's time and error as ratios to the shipped method's."""
    shipped, versions = by[SHIPPED], peer_versions()
    return {name: {'version': versions.get(name),
                   'scalar_time_ratio': ratio(p.seconds_per_solve_scalar, shipped.seconds_per_solve_scalar),
                   'vector_time_ratio': ratio(p.seconds_per_solve_vector, shipped.seconds_per_solve_vector),
                   'error_ratio': ratio(p.max_error, shipped.max_error),
                   'error_ratio_turnantenna': ratio(p.max_error_per_geometry.get('turnantenna'),
                                                    shipped.max_error_per_geometry.get('turnantenna')),
                   'not_applicable': p.not_applicable}
            for name, p in by.items() if name in versions}


def main(argv: list[str] | None = None) -> int:
    """Run everything and write the report."""
    parser = argparse.ArgumentParser(prog='python -m benchmarks.run', description=__doc__)
    parser.add_argument('--quick', action='store_true', help='smaller sizes and fewer repeats (under a minute)')
    parser.add_argument('--skip-node-bags', action='store_true',
                        help='do not run the node, replay and `fourbar process` benchmarks')
    args = parser.parse_args(argv)
    quick: bool = args.quick
    started = time.perf_counter()
    info = machine_info()

    methods = all_methods(quick) + peer_methods()
    n_angles, n_scalar, n_vector, repeats = (401, 500, 100_000, 5) if quick else (2001, 2000, 1_000_000, 9)
    print(f'common sweep: {len(methods)} methods x 4 geometries x {n_angles} angles', flush=True)
    results, sweep_info = accuracy(methods, n_angles)
    print(f'timing: scalar loop of {n_scalar}, arrays of {n_vector}, {repeats} interleaved repeats', flush=True)
    baselines = timings(methods, results, n_scalar, n_vector, repeats)
    front_v = pareto_front([(r.name, r.seconds_per_solve_vector, r.max_error) for r in results])
    front_s = pareto_front([(r.name, r.seconds_per_solve_scalar, r.max_error) for r in results])
    for r in results:
        r.pareto, r.pareto_scalar = r.name in front_v, r.name in front_s
    by = {r.name: r for r in results}

    parts = {'sweep_and_timing': time.perf_counter() - started}
    sections: dict[str, Any] = dict.fromkeys(SECTIONS)
    for key in ('stress', *SECTIONS):
        if args.skip_node_bags and key in NODE_AND_BAGS:
            continue
        print(f'{key} benchmark', flush=True)
        t0 = time.perf_counter()
        sections[key] = stress.run(quick) if key == 'stress' else guarded_bench(SECTIONS[key], quick)
        parts[key] = time.perf_counter() - t0
    info['load_average_1min_end'] = machine_info()['load_average_1min']
    data: dict[str, Any] = {
        'shipped': SHIPPED,
        'methods': [report.method_row(r) for r in results],
        'headline': headline(by, results, baselines),
        'baselines_seconds': baselines,
        'peers': peer_figures(by),
        'sweep': sweep_info,
        'timing': {'geometry': 'turnantenna', 'n_scalar': n_scalar, 'n_vector': n_vector, 'repeats': repeats,
                   'statistic': 'median of interleaved repeats, process CPU time (wall time in *_wall keys)'},
        'lookup': lookup_summary(by),
        **sections,
        'machine': info,
        'quick': quick,
        'command': 'python -m benchmarks.run' + (' --quick' if quick else ''),
        'elapsed_seconds': round(time.perf_counter() - started, 1),
        'elapsed_seconds_parts': {k: round(v, 1) for k, v in parts.items()},
    }
    report.write_all(data)
    print(report.summary(data), flush=True)
    if not by[SHIPPED].pareto:
        print(f'WARNING: shipped is off the vectorized Pareto front; dominated by: '
              f'{", ".join(data["headline"]["shipped_dominated_by_vector"])}', file=sys.stderr)
        return 1
    return 0


if __name__ == '__main__':
    sys.exit(main())
