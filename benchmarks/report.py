"""Writes the benchmark report: results.json rows, markdown tables, the Pareto PNG and docs/benchmarks.md."""

from __future__ import annotations

import json
import math
from dataclasses import asdict
from pathlib import Path
from typing import Any

from benchmarks import REPO
from benchmarks.sweep import MethodResult

DOC = REPO / 'docs' / 'benchmarks.md'  #: the README section
REL = 'bench'  #: its tables, plots and results.json, relative to it


def sanitize(x: Any) -> Any:
    """JSON-safe copy: non-finite floats become None (a NaN/inf error is also flagged by its method's counts)."""
    if isinstance(x, float):
        return x if math.isfinite(x) else None
    if isinstance(x, dict):
        return {str(k): sanitize(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [sanitize(v) for v in x]
    return x


def json_default(o: object) -> object:
    """Fallback for numpy scalars and other objects."""
    if hasattr(o, 'item'):
        return o.item()
    return str(o)


def method_row(r: MethodResult) -> dict[str, Any]:
    """One entry of results.json 'methods'."""
    return sanitize({**asdict(r), 'max_error_rad': r.max_error,
                     'failed': r.max_error is not None and not math.isfinite(r.max_error)})


def _fmt(x: float | None, digits: int = 3) -> str:
    """x to ``digits`` significant digits; '-' for None, 'fail' for NaN or inf."""
    return '-' if x is None else 'fail' if not math.isfinite(x) else f'{x:.{digits}g}'


def _ns(x: float | None) -> str:
    """Seconds as nanoseconds, 4 digits."""
    return '-' if x is None else f'{x * 1e9:.4g}'


def methods_table(data: dict[str, Any]) -> str:
    """Markdown table of every method: times (ns per solve), max error, Pareto membership."""
    rows = ['| method | dtype | scalar ns/solve | vector ns/solve | max error (rad) | on Turnantenna alone | '
            'Pareto (vector) | Pareto (scalar) | notes |', '|---|---|---:|---:|---:|---:|:---:|:---:|---|']
    for m in sorted(data['methods'], key=lambda m: (m['max_error_rad'] is None, m['max_error_rad'] or 0.0)):
        notes = []
        if m['nan_count']:
            notes.append(f'{m["nan_count"]} NaN')
        if m['exception_count']:
            notes.append(f'{m["exception_count"]} exceptions')
        if m['not_applicable']:
            notes.append('n/a on ' + ', '.join(s.split(':')[0] for s in m['not_applicable']))
        worst = [k for k, v in m['max_error_per_geometry'].items() if v is not None and m['max_error_rad']
                 and v == m['max_error_rad']]
        if m['max_error_rad'] is not None and m['max_error_rad'] > 1.0 and worst:
            notes.append('wrong branch on ' + ', '.join(worst))
        name = f'**{m["name"]}**' if m['name'] == data['shipped'] else m['name']
        err = 'fail (NaN)' if m['failed'] else _fmt(m['max_error_rad'])
        rows.append(f'| {name} | {m["dtype"]} | {_ns(m["seconds_per_solve_scalar"])} | '
                    f'{_ns(m["seconds_per_solve_vector"])} | {err} | '
                    f'{_fmt(m["max_error_per_geometry"].get("turnantenna"))} | '
                    f'{"yes" if m["pareto"] else ""} | '
                    f'{"yes" if m["pareto_scalar"] else ""} | {"; ".join(notes)} |')
    return '\n'.join(rows) + '\n'


def stress_table(stress: dict[str, Any]) -> str:
    """Markdown table: per family and method, cases, max error, max nu, NaN, exceptions, flagged."""
    rows = ['| family | method | cases | max error (rad) | max err / (u (kappa+abs f)) | NaN | exceptions | '
            f'cases over {stress["nu_flag"]:g} |', '|---|---|---:|---:|---:|---:|---:|---:|']
    for fam, per in stress['families'].items():
        for name, t in per.items():
            rows.append(f'| {fam} | {name} | {t["cases"]} | {_fmt(t["max_error"])} | {_fmt(t["max_nu"])} | '
                        f'{t["nans"]} | {t["exceptions"]} | {t["flagged"]} |')
    return '\n'.join(rows) + '\n'


def lookup_text(lk: dict[str, Any] | None) -> str:
    """What the offered table costs and saves, from the same run."""
    if not lk:
        return 'Not measured in this run.\n'
    lines = ['Users who accept a bounded error (a small controller with no fast trigonometry, or a vectorized '
             'batch where 1e-6 rad is plenty) can tabulate the linkage once: `RockerTable.build(link, theta_min, '
             'theta_max, tolerance)` doubles a cubic-Hermite grid until the error, checked against the exact solver '
             'at 16 points per interval, is within half the tolerance; `to_c()` emits float32 C. The exact solve '
             'stays the default everywhere.', '']
    for t in lk['tables']:
        lines.append(f'- Turnantenna tilt range [-6, +7] deg at {t["tolerance_rad"]:g} rad: **{t["points"]} points**, '
                     f'max error {_fmt(t["max_error_rad"])} rad (float64), {_fmt(t["max_error_float32_rad"])} rad in '
                     f'float32 C ({t["float32_bytes"]} bytes of coefficients).')
    if lk.get('time_ratio_to_shipped_vector'):
        lines.append(f'- Built to 1e-6 rad over the whole common sweep (99% of the reach, so many more points): '
                     f'{_fmt(lk["time_ratio_to_shipped_vector"])}x the shipped vectorized time, '
                     f'{_fmt(lk["time_ratio_to_shipped_scalar"])}x its scalar time (in CPython the per-call overhead '
                     f'dominates a scalar lookup), max error {_fmt(lk["sweep_max_error_rad"])} rad.')
    return '\n'.join(lines) + '\n'


def figures_table(title: str, figures: dict[str, Any] | None) -> str:
    """Render a benchmark's figures (a dict, flattened one level) as a two-column table."""
    if figures is None:
        return f'{title}: not measured in this run (--skip-node-bags).\n'
    if 'error' in figures and len(figures) == 1:
        return f'{title}: its benchmark failed in this run: `{figures["error"]}`.\n'
    flat: list[tuple[str, Any]] = []

    def add(prefix: str, d: dict[str, Any]) -> None:
        for k, v in d.items():
            if isinstance(v, dict):
                add(f'{prefix}{k}.', v)
            else:
                flat.append((f'{prefix}{k}', v))

    add('', figures)
    markers = ('ratio', '_over_', 'fraction', 'saved', 'meets', 'lost')
    head = [(k, v) for k, v in flat if any(m in k for m in markers)]
    rest = [(k, v) for k, v in flat if (k, v) not in head]

    def table(items: list[tuple[str, Any]], label: str) -> list[str]:
        return [f'| {label} | value |', '|---|---:|'] + [
            f'| {k} | {_fmt(v) if isinstance(v, float) else v} |' for k, v in items]

    lines = table(head, f'{title}: ratios to same-run baselines')
    lines += ['', '<details><summary>all figures</summary>', '', *table(rest, title), '', '</details>']
    return '\n'.join(lines) + '\n'


def _pyplot() -> Any:
    """matplotlib.pyplot on the file-only backend."""
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    return plt


def _save(fig: Any, path: Path) -> None:
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    _pyplot().close(fig)


def plot(data: dict[str, Any], path: Path) -> None:
    """Log-log time per solve against max error, vectorized and scalar panels, Pareto fronts joined."""
    fig, axes = _pyplot().subplots(1, 2, figsize=(13, 5.5))
    colors = {'annex': 'tab:red', 'shipped': 'tab:green', 'stable': 'tab:olive', 'newton': 'tab:blue',
              'lut': 'tab:purple', 'hybrid': 'tab:cyan', 'peer': 'tab:gray', 'lookup': 'tab:orange'}
    for ax, key, front_key, title in ((axes[0], 'seconds_per_solve_vector', 'pareto', 'vectorized (numpy arrays)'),
                                      (axes[1], 'seconds_per_solve_scalar', 'pareto_scalar', 'scalar (Python float)')):
        pts = [m for m in data['methods'] if m[key] is not None and m['max_error_rad'] is not None]
        for m in pts:
            err = max(m['max_error_rad'], 1e-17)
            ship = m['name'] == data['shipped']
            ax.scatter(m[key] * 1e9, err, s=120 if ship else 30, marker='*' if ship else 'o',
                       color=colors.get(m['family'], 'k'), edgecolor='k' if m[front_key] else 'none', zorder=3)
            ax.annotate(m['name'], (m[key] * 1e9, err), fontsize=6.5, xytext=(3, 2), textcoords='offset points')
        front = sorted((m[key] * 1e9, max(m['max_error_rad'], 1e-17)) for m in pts if m[front_key])
        if front:
            ax.step([p[0] for p in front], [p[1] for p in front], where='post', color='k', lw=0.8, ls='--',
                    label='Pareto front', zorder=2)
        ax.axhspan(0.5, 20.0, color='tab:red', alpha=0.07, zorder=0,
                   label='wrong assembly branch on some geometry (error ~ pi)')
        ax.set_xscale('log')
        ax.set_yscale('log')
        ax.set_ylim(5e-17, 20.0)
        ax.set_xlabel('time per solve (ns), median, Turnantenna geometry')
        ax.set_ylabel('max error over the common sweep (rad)')
        ax.set_title(title)
        ax.grid(True, which='both', alpha=0.3)
        ax.legend(loc='lower right', fontsize=7)
    fig.suptitle(f'time against error ({data["command"]}); shipped = star; outlined = on the front', fontsize=10)
    _save(fig, path)


def latency_plot(data: dict[str, Any], path: Path) -> bool:
    """Distribution (CDF) of the paced round trips per executor and system; False if the run has none."""
    systems = ((data.get('node') or {}).get('executors') or {}).get('systems') or {}
    curves = {name: row['percentiles_us'] for name, row in systems.items() if row.get('percentiles_us')}
    if not curves:
        return False
    fig, ax = _pyplot().subplots(figsize=(8, 4.5))
    styles = {'relay_single': ('tab:gray', '--'), 'relay_events': ('tab:gray', '-'),
              'node_single': ('tab:blue', '--'), 'node_events': ('tab:green', '-')}
    for name, us in curves.items():
        color, ls = styles.get(name, ('k', ':'))
        ax.plot(us, [q / 100 for q in range(len(us))], color=color, ls=ls, lw=1.6, label=name)
    ax.set_xscale('log')
    ax.set_xlabel('command -> JointState round trip (us), paced 200 Hz')
    ax.set_ylabel('fraction of commands')
    ax.grid(True, which='both', alpha=0.3)
    ax.legend(loc='lower right', fontsize=8)
    ex = data['node']['executors']
    ax.set_title(f'latency by executor ({ex["rounds"]} interleaved rounds of {ex["commands_per_round"]}; '
                 f'shipped: {ex["shipped"]})', fontsize=9)
    _save(fig, path)
    return True


def summary(data: dict[str, Any]) -> str:
    """A few lines for the terminal."""
    h = data['headline']
    by = {m['name']: m for m in data['methods']}
    s = by[data['shipped']]
    return (f'shipped: max error {_fmt(s["max_error_rad"])} rad, scalar {_ns(s["seconds_per_solve_scalar"])} ns, '
            f'vector {_ns(s["seconds_per_solve_vector"])} ns/solve; floor ratio {_fmt(h["floor_ratio"])} '
            f'(target <= 1.3); one angle through the array path '
            f'{_ns(data["baselines_seconds"]["array_path_one_angle_per_call"])} ns '
            f'({_fmt(h["array_path_one_ratio_to_scalar"])}x scalar); '
            f'scalar / annex {_fmt(h["scalar_ratio_to_annex"])}; '
            f'on the vector front: {h["shipped_on_pareto_front_vector"]}; stress defects: '
            f'{len(data["stress"]["defects"])}; elapsed {data["elapsed_seconds"]} s')


def write_all(data: dict[str, Any]) -> None:
    """Write results.json, the tables, the PNGs (docs/bench/) and the README section (docs/benchmarks.md)."""
    out = DOC.parent / REL
    out.mkdir(parents=True, exist_ok=True)
    (out / 'methods.md').write_text(methods_table(data), encoding='utf-8')
    (out / 'stress.md').write_text(stress_table(data['stress']), encoding='utf-8')
    plot(data, out / 'pareto.png')
    data['latency_plot'] = latency_plot(data, out / 'latency.png')
    DOC.write_text(readme_section(data), encoding='utf-8')
    (out / 'results.json').write_text(json.dumps(sanitize(data), indent=1, allow_nan=False, default=json_default)
                                      + '\n', encoding='utf-8')


def readme_section(data: dict[str, Any]) -> str:
    """docs/benchmarks.md: headline figures, the command, the tables and what they mean."""
    h = data['headline']
    by = {m['name']: m for m in data['methods']}
    s = by[data['shipped']]
    a = by.get('annex', {})
    peers = data['peers']
    lines = [
        '# Benchmarks: run time against error, and numerical stress',
        '',
        'Regenerate everything below with `make bench` (`python -m benchmarks.run` in the venv; a few minutes) or '
        '`make bench-quick` (`--quick`: smaller sizes, under a minute). '
        f'The figures here come from `{data["command"]}` ({data["elapsed_seconds"]:.0f} s; by part: '
        + ', '.join(f'{k} {v:.0f} s' for k, v in data.get('elapsed_seconds_parts', {}).items()) + '). '
        f'This file, `{REL}/methods.md`, `{REL}/stress.md`, `{REL}/pareto.png` and `{REL}/results.json` are '
        'written by that command; do not edit them by hand.',
        '',
        f'Measured on: {data["machine"]["cpu"]}, {data["machine"]["cores"]} cores, Python '
        f'{data["machine"]["python"]}, numpy {data["machine"]["numpy"]}; load average '
        f'{_fmt(data["machine"]["load_average_1min"])} at the start and '
        f'{_fmt(data["machine"]["load_average_1min_end"])} at the end. **The machine was shared with other '
        'jobs**: absolute times move by tens of percent between runs; the ratios below are measured in the same '
        'run, from medians of interleaved repeats, and are the figures to quote.',
        '' if not data['quick'] else '\n**This is a --quick run** (smaller sizes, fewer repeats).\n',
        '## Headline',
        '',
        f'- Accuracy: the shipped solver (`AntennaLinkage.rocker_angles`) errs by at most '
        f'**{_fmt(s["max_error_rad"])} rad** over the common sweep (every method on the same '
        f'{data["sweep"]["angles_per_geometry"]} angles per geometry, within 99% of the reachable interval of '
        f'{len(data["sweep"]["geometries"])} geometries), against an independent 50-digit mpmath reference. '
        f'The annex formula as written: {_fmt(a.get("max_error_rad"))} rad '
        '(it takes the wrong branch, off by pi, where the coupler is longer than the frame).',
        f'- Vectorized: {_ns(s["seconds_per_solve_vector"])} ns per solve over '
        f'{data["timing"]["n_vector"]:,} angles, **{_fmt(h["floor_ratio"])}x the floor** (the numpy ufuncs the '
        f'stable form cannot avoid: sin, cos, sqrt and two atan2 on the same array; target 1.3x: '
        f'{"met" if h["floor_ratio"] is not None and h["floor_ratio"] <= 1.3 else "NOT met"}); '
        f'{_fmt(h["vector_ratio_to_annex"])}x the annex formula\'s time.',
        f'- Scalar (one Python float): {_ns(s["seconds_per_solve_scalar"])} ns per call, '
        f'**{_fmt(h["scalar_ratio_to_annex"])}x the annex formula** as written (a scalar solve is under 1% '
        'of the node\'s per-command cost, see the node figures); '
        f'a bare Python call returning a tuple costs {_ns(data["baselines_seconds"]["python_call_per_call"])} ns '
        'in the same loop, and the stable form\'s bare math (a closure returning a plain tuple, no validation, '
        f'no NamedTuple) {_ns(data["baselines_seconds"]["stable_plain_scalar_per_call"])} ns: shipped is '
        f'{_fmt(h["scalar_ratio_to_stable_plain"])}x that, the annex formula '
        f'{_fmt(h["annex_scalar_ratio_to_stable_plain"])}x. The same solver given a one-element array (its '
        f'numpy path) costs {_ns(data["baselines_seconds"]["array_path_one_angle_per_call"])} ns per call, '
        f'{_fmt(h["array_path_one_ratio_to_scalar"])}x the scalar path: what the math-module fast path saves.',
        f'- Pareto front (vectorized): shipped on the front: **{h["shipped_on_pareto_front_vector"]}**'
        + ('' if h['shipped_on_pareto_front_vector'] else
           f' (dominated by {", ".join(h["shipped_dominated_by_vector"])})')
        + f'; scalar: {h["shipped_on_pareto_front_scalar"]}'
        + ('' if h['shipped_on_pareto_front_scalar'] else
           f' (dominated by {", ".join(h["shipped_dominated_by_scalar"])})') + '.',
    ]
    for name, p in peers.items():
        lines.append(
            f'- Peer `{name}` {p["version"]}: {_fmt(p["scalar_time_ratio"])}x our scalar time'
            + (f', {_fmt(p["vector_time_ratio"])}x our vectorized time' if p['vector_time_ratio'] else
               ' (no array API)')
            + f', {_fmt(p["error_ratio"])}x our max error on the same positions '
            f'({_fmt(p["error_ratio_turnantenna"])}x on the Turnantenna geometry alone).')
    st = data['stress']
    lines += [
        f'- Stress: {st["cases"]} hard inputs (reach limit to the last float, H -> h, link ratios to 1e6, scales '
        f'1e-6..1e6 m and beyond, |theta| to 6e15, subnormal angles): shipped defects '
        f'(error over {st["nu_flag"]:g} u kappa, NaN or exception on a reachable input): **{len(st["defects"])}**.',
        '',
        f'![time against error]({REL}/pareto.png)',
        '',
        '## Methods (common sweep; times on the Turnantenna geometry)',
        '',
        'Error: the worst of gamma and delta, of the scalar and the vectorized path, over all geometries. '
        '"fail" means NaN or an exception on a reachable input. Time: median of interleaved repeats; '
        f'scalar = a Python loop over {data["timing"]["n_scalar"]} floats (fewer for slow peers), vector = one call on '
        f'{data["timing"]["n_vector"]:,} angles (fewer for slow peers; see n_vector in results.json).',
        '',
        methods_table(data),
        'What the methods are: `annex` is A.13-A.15 as written (atan P, acos Q); `annex-atan2` replaces atan P by '
        'atan2 (the branch fix) but keeps acos Q; `stable-f32` is the shipped form evaluated in float32; '
        '`newton-K` takes K Newton steps on the two loop-closure equations of the transformation-matrix chains, '
        'cold-started from the mid-interval pose (it has no branch control: on the coupler-longer-than-frame '
        'geometry it converges to the other assembly); `lut-*-N` are N-point uniform tables over the swept '
        'interval, interpolated linearly or by cubic Hermite, built once with the core; `+newton1` polishes a '
        'table value with one Newton step; `pylinkage` is its circle_intersect dyad primitive plus atan2; '
        '`mechanism` is its fsolve-based Mechanism (vectorized = its iterate(), warm-started).',
        '',
        '## Numerical stress',
        '',
        'Every input is reachable according to the reference. nu = error / (u (kappa + |f|)), u = 2^-53, '
        'kappa = sum over the inputs x of |df/dx| |x| (the absolute condition number for relative input '
        'perturbations, from the implicit-function derivatives of the loop equations): a backward-stable method '
        'keeps nu of order 1. "beyond-spec" scales (1e+-150, 1e+-300 m and subnormal lengths, 1e-310) lie outside the '
        'specified 1e-6..1e6 m.',
        '',
        stress_table(st),
    ]
    if st['defects']:
        lines += ['Shipped defects (minimal reproducers):', '']
        for d in st['defects'][:20]:
            lines.append(f'- {d["family"]}, {d["method"]}: {d["what"]}; `{d["reproducer"]}` expected '
                         f'{d["expected"]}, got {d["got"]}')
        lines.append('')
    if st['singular']:
        lines += ['At the parallelogram change point (H == h, theta = 0) the pose is undetermined; what each '
                  'method does there:', '']
        for row in st['singular']:
            rest = {k: v for k, v in row.items() if k not in ('geometry', 'theta')}
            lines.append(f'- {row["geometry"]}, theta={row["theta"]}: ' +
                         '; '.join(f'{k}: {v}' for k, v in rest.items()))
        lines.append('')
    lines += [
        '## A cheaper method for some users: `fourbar_ros.core.lookup.RockerTable`',
        '',
        lookup_text(data.get('lookup')),
        '## Completing the linkage from the measured driven joint, against the public approaches',
        '',
        completion_markdown(data.get('completion')),
        '## Node and bag figures',
        '',
        *([f'![latency by executor]({REL}/latency.png)', ''] if data.get('latency_plot') else []),
        figures_table('node (benchmarks/node_bench.py)', data.get('node')),
        figures_table('node completion: measured joint_states in, completed JointState out '
                      '(benchmarks/node_bench.py --completion)', data.get('node_completion')),
        figures_table('bag (benchmarks/bag_bench.py)', data.get('bag')),
        figures_table('fourbar process against a rosbags copy of the same bag (benchmarks/process_bench.py)',
                    data.get('process')),
        '## How it is measured',
        '',
        '- Reference: `benchmarks/reference.py`, derived from the loop-closure equations (B is an intersection of '
        'the circle about A with the circle about D - h (cos theta, -sin theta)), evaluated with mpmath at 60 '
        'digits, each float input taken as exact; its tests check the reference table '
        '(test/data/turnantenna_reference.csv), loop closure to 1e-50 and agreement with a 120-digit '
        'evaluation. Errors are taken against a double-double copy, so they resolve far below one ulp.',
        '- Same inputs: every method sees the same ascending angles per geometry; tables are built over the '
        'same interval they are asked about; Newton and mechanism start from the same mid-interval pose.',
        '- Timing: the process\'s CPU time (`time.process_time`, so time the scheduler gives other jobs is left '
        'out) around whole loops/calls, every case once per round, medians over rounds; wall-clock medians are in '
        'results.json beside them. Baselines (floor, Python call) are timed in the same rounds. OPENBLAS variables '
        'are left as the machine sets them (no BLAS is used on these paths).',
        '',
    ]
    return '\n'.join(lines)


def _g(x: float | None) -> str:
    """Two significant digits (the completion tables)."""
    return _fmt(x, 2)


_WHERE = {'mid': 'mid-range', 'limit_1e-06': '1e-6 rad from the limit', 'limit_1e-12': '1e-12 rad from the limit'}


def completion_markdown(c: dict[str, Any] | None) -> str:
    """The report section: errors (worst over the geometries), cost on Turnantenna, per-geometry positions."""
    if not c or 'error' in c:
        return f'Not measured in this run{": `" + c["error"] + "`" if c else ""}.\n'
    geos = c['geometries']
    names = list(next(iter(geos.values()))['methods'])
    worst: dict[str, dict[str, dict[str, float]]] = {}
    for per in geos.values():
        for m, rows in per['methods'].items():
            for where, row in rows.items():
                w = worst.setdefault(m, {}).setdefault(where, {})
                for k, v in row.items():
                    w[k] = v if v is None or w.get(k) is None else max(w[k], v)
    cost = c['cost']['methods']
    st = c['stream']
    lines = [
        f'From the measured driven rocker ({c["driven"]}: angle, rate and effort, as `joint_state_broadcaster` '
        'publishes them), each method gives the other rocker, the antenna angle theta, its rate and the load '
        'torque. The measured stream moves at '
        f'{st["q_rate_rad_s"]:g} rad/s, one message every {1.0 / st["rate_hz"]:g} s ({st["step_rad"]:g} rad), '
        f'effort {st["effort_n_m"]:g} N m. `exact` is the core\'s closed form (`AntennaLinkage.from_rocker`, '
        'and dq/dtheta from `rates_at`: theta_dot = q_dot / (dq/dtheta), load torque = effort dq/dtheta). '
        f'`cubic` is `numpy.polyfit` of degree 3 per passive joint over the whole driven range ({c["fit_points"]} '
        'exact samples), as a CAD exporter\'s relay does; `cubic-mid` the same fitted over the mid-range only. '
        f'`gauss-newton` solves the loop equations to a {c["tolerance_rad"]:g} rad step, warm-started from the '
        'previous message, as public joint-state transformers do; `lm-scipy` is scipy\'s Levenberg-Marquardt '
        f'(`least_squares(method=\'lm\', xtol={c["tolerance_rad"]:g})`) on the same equations. '
        '**The public relays publish positions only**: their rates and torques below come from the cubic\'s '
        'derivative, or from finite differences of successive messages for the iterative solvers.',
        '',
        f'Errors against the 60-digit reference with the driven angle as input (`benchmarks/reference_driven.py`), '
        f'the worst over {len(geos)} geometries ({", ".join(geos)}); positions in rad, rate and torque relative. '
        'Mid-range: every message within half the distance from the working pose (theta = 0) to the nearest '
        'singular point (on Turnantenna about its tilt range); near the limit: the last message of a stream '
        'running into either reach limit of the driven rocker (its dead point: dq/dtheta = 0, theta_dot '
        'unbounded).',
        '',
        '| method | publishes | where | theta (rad) | other rocker (rad) | theta_dot (rel.) | load torque (rel.) |',
        '|---|---|---|---:|---:|---:|---:|',
    ]
    for m in names:
        for where, label in _WHERE.items():
            row = worst.get(m, {}).get(where)
            if row is None:
                continue
            lines.append(f'| {m} | {c["publishes"].get(m, "")} | {label} | {_g(row["theta_rad"])} | '
                         f'{_g(row["other_rad"])} | {_g(row["theta_dot_rel"])} | {_g(row["load_torque_rel"])} |')
    ex = worst.get('exact', {})
    lines += [
        '',
        'In ulps of their condition (the reference\'s condition number over the driven angle and the lengths), '
        '`exact` errs by at most '
        + ', '.join(f'{_g(r.get("position_ulps"))} (positions) and {_g(r.get("rate_ulps"))} (rate, torque) at '
                    f'{_WHERE[w]}' for w, r in ex.items()) + '. '
        'Near a reach limit the completion itself is ill-conditioned (theta moves as the square root of the '
        'distance to the limit), so every method\'s rate there is only as good as that allows.',
        '',
        f'Cost per message on {c["cost"]["geometry"]} (process CPU time, median of {c["cost"]["repeats"]} '
        'interleaved rounds; scalar: a Python loop, one call per message, what a node does; vectorized: one call '
        'on an array, what a bag conversion does; the iterative solvers are sequential by nature, each message '
        'warm-started from the last):',
        '',
        '| method | scalar us/message | scalar x exact | vectorized ns/message | vectorized x exact |',
        '|---|---:|---:|---:|---:|',
    ]
    for m in names:
        t = cost.get(m, {})
        sc, vc = t.get('scalar_seconds'), t.get('vector_seconds')
        lines.append(f'| {m} | {"-" if sc is None else f"{sc * 1e6:.3g}"} | {_g(t.get("scalar_ratio_to_exact"))} | '
                     f'{"-" if vc is None else f"{vc * 1e9:.3g}"} | {_g(t.get("vector_ratio_to_exact"))} |')
    lines += ['', 'theta error (rad) per geometry, mid-range / 1e-12 rad from the limit:', '',
              '| geometry | ' + ' | '.join(names) + ' |', '|---|' + '---:|' * len(names)]
    for name, per in geos.items():
        cells = [f'{_g(per["methods"][m]["mid"]["theta_rad"])} / '
                 f'{_g(per["methods"][m].get("limit_1e-12", {}).get("theta_rad"))}' for m in names]
        lines.append(f'| {name} | ' + ' | '.join(cells) + ' |')
    steps = []
    for name, per in geos.items():
        gn = per['solver_stats'].get('gauss-newton')
        if gn and gn['messages']:
            steps.append(f'{name} {gn["steps"] / gn["messages"]:.2g}'
                         + (f' ({gn["not_converged"]} not converged)' if gn['not_converged'] else ''))
    lines += ['', 'Newton steps per message (gauss-newton): ' + ', '.join(steps) + '.'
              + ('' if 'lm-scipy' in names else ' `lm-scipy` was not run: scipy is not installed (`make bench-deps`).'),
              '']
    return '\n'.join(lines)
