"""Entry point: ``python -m benchmarks.run [--quick] [--out docs/bench] [--doc docs/benchmarks.md]``.

Runs the common sweep (accuracy of every method against the 50-digit reference), the timings (scalar and
vectorized, interleaved medians on the Turnantenna geometry, with the ufunc floor and the Python call overhead
as same-run baselines), the numerical stress suite, and the node, bag (replay) and `fourbar process` benchmarks;
writes results.json, markdown tables and PNG plots under --out and the README section --doc.
"""

from __future__ import annotations

import argparse
import importlib
import json
import sys
import time
from pathlib import Path
from typing import Any

from benchmarks import report, stress
from benchmarks.methods import SHIPPED, all_methods
from benchmarks.peers import peer_methods, peer_versions
from benchmarks.sweep import accuracy, dominators, pareto_front, timings
from benchmarks.timing import machine_info

#: The benchmarks of the node and the bag tools: results.json key -> module of benchmarks/ with ``run(quick)``.
#: ``module:function`` names another function than ``run``.
NODE_AND_BAG_BENCHMARKS = {'node': 'node_bench', 'node_completion': 'node_bench:run_completion', 'bag': 'bag_bench',
                           'process': 'process_bench'}


def guarded_bench(module: str, quick: bool) -> dict[str, Any]:
    """Figures from benchmarks.<module>.run(quick); a failure is reported in the figures, not raised, so
    one broken benchmark (say, no ROS on this machine) does not take the rest of the report down."""
    name, _, function = module.partition(':')
    try:
        return dict(getattr(importlib.import_module(f'benchmarks.{name}'), function or 'run')(quick))
    except Exception as exc:
        return {'error': f'{type(exc).__name__}: {exc}'}


def lookup_summary(by: dict[str, Any]) -> dict[str, Any]:
    """The offered table (fourbar_ros.core.lookup) on Turnantenna's tilt range; its sweep figures against shipped."""
    import math

    from benchmarks.cases import TURNANTENNA
    from benchmarks.methods import linkage
    from fourbar_ros.core.lookup import RockerTable

    tilt = (math.radians(-6.0), math.radians(7.0))
    tables = []
    for tol in (1e-6, 1e-9):
        t = RockerTable.build(linkage(TURNANTENNA), *tilt, tolerance=tol)
        tables.append({'tolerance_rad': tol, 'points': t.points, 'max_error_rad': t.max_error,
                       'max_error_float32_rad': t.max_error_float32, 'float32_bytes': 2 * 4 * 4 * (t.points - 1)})
    ship, lk = by[SHIPPED], by.get('lookup-1e-06')
    out: dict[str, Any] = {'tilt_range_rad': list(tilt), 'tables': tables}
    if lk is not None:
        for key in ('seconds_per_solve_scalar', 'seconds_per_solve_vector'):
            a, b = getattr(lk, key), getattr(ship, key)
            out[key.replace('seconds_per_solve', 'time_ratio_to_shipped')] = None if not a or not b else a / b
        out['sweep_max_error_rad'] = lk.max_error
    return out


def main(argv: list[str] | None = None) -> int:
    """Run everything and write the report; exit status 0 (1 if the shipped method is off the Pareto front)."""
    parser = argparse.ArgumentParser(prog='python -m benchmarks.run', description=__doc__)
    parser.add_argument('--quick', action='store_true', help='smaller sizes and fewer repeats (under a minute)')
    parser.add_argument('--out', type=Path, default=Path('docs/bench'), help='directory for tables, PNGs, JSON')
    parser.add_argument('--doc', type=Path, default=Path('docs/benchmarks.md'), help='the README section to write')
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
        r.pareto = r.name in front_v
        r.pareto_scalar = r.name in front_s
    by = {r.name: r for r in results}
    shipped = by[SHIPPED]

    parts = {'sweep_and_timing': time.perf_counter() - started}
    print('stress suite', flush=True)
    t0 = time.perf_counter()
    stress_out = stress.run(quick)
    parts['stress'] = time.perf_counter() - t0
    print('completion against the public approaches (benchmarks/completion_peers.py)', flush=True)
    t0 = time.perf_counter()
    completion = guarded_bench('completion_peers', quick)
    parts['completion'] = time.perf_counter() - t0
    print('antenna trajectory conversion and replanning (benchmarks/trajectory_bench.py)', flush=True)
    t0 = time.perf_counter()
    trajectory = guarded_bench('trajectory_bench', quick)
    parts['trajectory'] = time.perf_counter() - t0
    node_and_bags: dict[str, dict[str, Any]] = {}
    if not args.skip_node_bags:
        for key, module in NODE_AND_BAG_BENCHMARKS.items():
            print(f'{key} benchmark (benchmarks/{module.partition(":")[0]}.py)', flush=True)
            t0 = time.perf_counter()
            node_and_bags[key] = guarded_bench(module, quick)
            parts[key] = time.perf_counter() - t0

    def ratio(a: float | None, b: float | None) -> float | None:
        return None if a is None or b is None or b == 0 else a / b

    annex = by.get('annex')
    headline: dict[str, Any] = {
        'floor_ratio': ratio(shipped.seconds_per_solve_vector, baselines['floor']),
        'floor_ratio_target': 1.3,
        'scalar_ratio_to_stable_plain': ratio(shipped.seconds_per_solve_scalar, baselines['stable_plain']),
        'array_path_one_ratio_to_scalar': ratio(baselines['array_path_one'], shipped.seconds_per_solve_scalar),
        'annex_scalar_ratio_to_stable_plain': ratio(annex.seconds_per_solve_scalar if annex else None,
                                                    baselines['stable_plain']),
        'scalar_ratio_to_annex': ratio(shipped.seconds_per_solve_scalar,
                                       annex.seconds_per_solve_scalar if annex else None),
        'vector_ratio_to_annex': ratio(shipped.seconds_per_solve_vector,
                                       annex.seconds_per_solve_vector if annex else None),
        'error_ratio_annex_to_shipped': ratio(annex.max_error if annex else None, shipped.max_error),
        'shipped_on_pareto_front_vector': shipped.pareto,
        'shipped_on_pareto_front_scalar': shipped.pareto_scalar,
        'shipped_dominated_by_vector': dominators(results, SHIPPED, vector=True),
        'shipped_dominated_by_scalar': dominators(results, SHIPPED, vector=False),
    }
    peers = {}
    for name in ('pylinkage', 'mechanism'):
        p = by.get(name)
        if p is None:
            continue
        peers[name] = {
            'version': peer_versions().get(name),
            'scalar_time_ratio': ratio(p.seconds_per_solve_scalar, shipped.seconds_per_solve_scalar),
            'vector_time_ratio': ratio(p.seconds_per_solve_vector, shipped.seconds_per_solve_vector),
            'error_ratio': ratio(p.max_error, shipped.max_error),
            'error_ratio_turnantenna': ratio(p.per_geometry.get('turnantenna'),
                                             shipped.per_geometry.get('turnantenna')),
            'not_applicable': p.not_applicable,
        }
    info['load_average_1min_end'] = machine_info()['load_average_1min']
    results_json: dict[str, Any] = {
        'shipped': SHIPPED,
        'floor_ratio': headline['floor_ratio'],
        'methods': [report.method_row(r) for r in results],
        'headline': headline,
        'baselines_seconds': {'floor_per_element': baselines['floor'],
                              'python_call_per_call': baselines['python_call'],
                              'stable_plain_scalar_per_call': baselines['stable_plain'],
                              'array_path_one_angle_per_call': baselines['array_path_one'],
                              'floor_per_element_wall': baselines['floor_wall'],
                              'python_call_per_call_wall': baselines['python_call_wall']},
        'peers': peers,
        'sweep': sweep_info,
        'timing': {'geometry': 'turnantenna', 'n_scalar': n_scalar, 'n_vector': n_vector, 'repeats': repeats,
                   'statistic': 'median of interleaved repeats, process CPU time (wall time in *_wall keys)'},
        'stress': stress_out,
        'lookup': lookup_summary(by),
        'completion': completion,
        'trajectory': trajectory,
        **{key: node_and_bags.get(key) for key in NODE_AND_BAG_BENCHMARKS},
        'machine': info,
        'quick': quick,
        'command': 'python -m benchmarks.run' + (' --quick' if quick else ''),
        'elapsed_seconds': None,
    }
    results_json['elapsed_seconds'] = round(time.perf_counter() - started, 1)
    results_json['elapsed_seconds_parts'] = {k: round(v, 1) for k, v in parts.items()}
    args.out.mkdir(parents=True, exist_ok=True)
    report.write_all(results_json, results, args.out, args.doc)
    (args.out / 'results.json').write_text(json.dumps(report.sanitize(results_json), indent=1, allow_nan=False,
                                                      default=report.json_default) + '\n', encoding='utf-8')
    print(report.summary(results_json), flush=True)
    if not shipped.pareto:
        print(f'WARNING: shipped is off the vectorized Pareto front; dominated by: '
              f'{", ".join(headline["shipped_dominated_by_vector"])}', file=sys.stderr)
        return 1
    return 0


if __name__ == '__main__':
    sys.exit(main())
