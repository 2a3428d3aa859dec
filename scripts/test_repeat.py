"""Run the same pytest command N times in a row and summarize every failure across the runs.

    python scripts/test_repeat.py N [--keep DIR] -- PYTEST ARGS...

Each run writes a JUnit XML report (pytest's own ``--junitxml``; no other dependency); at the end this prints one
line per run (counts, wall time) and every failed or erroring test of every run with the first line of its
message, grouped by test. The status is 0 only if every run passed. ``make test-repeat N=...`` calls it for the
ROS layers (test/node, test/live, test/package, test/commands).
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path


@dataclass
class Run:
    """One pytest run: its number, exit status, wall time and what its report says."""

    number: int
    status: int
    seconds: float
    counts: dict[str, int] = field(default_factory=dict)
    failures: list[tuple[str, str]] = field(default_factory=list)  # (test id, first line of the message)


def first_line(text: str | None) -> str:
    """The first non-empty line of ``text`` (stripped), or ''."""
    for line in (text or '').splitlines():
        if line.strip():
            return line.strip()
    return ''


def test_id(case: ET.Element) -> str:
    """``path::Class::name`` of a ``testcase`` element of pytest's xunit1 report (its ``file`` attribute)."""
    name = case.get('name', '')
    classname = case.get('classname', '')
    path = case.get('file')
    if not path:
        return f'{classname}::{name}' if classname else name
    module = path.removesuffix('.py').replace('/', '.')
    rest = classname[len(module):].lstrip('.') if classname.startswith(module) else ''
    return '::'.join(filter(None, [path, *rest.split('.'), name]))


def read_report(path: Path, run: Run) -> None:
    """Fill ``run``'s counts and failures from its JUnit XML report (if pytest wrote one)."""
    if not path.exists():
        return
    root = ET.parse(path).getroot()
    suites = [root] if root.tag == 'testsuite' else list(root.iter('testsuite'))
    for suite in suites:
        for key in ('tests', 'failures', 'errors', 'skipped'):
            run.counts[key] = run.counts.get(key, 0) + int(suite.get(key, '0'))
        for case in suite.iter('testcase'):
            for kind in ('failure', 'error'):
                for problem in case.findall(kind):
                    line = first_line(problem.get('message')) or first_line(problem.text)
                    run.failures.append((test_id(case), f'{kind}: {line}' if kind == 'error' else line))


def repeat(times: int, pytest_args: Sequence[str], report_dir: Path) -> list[Run]:
    """Run ``python -m pytest PYTEST_ARGS`` ``times`` times, each with its report in ``report_dir``."""
    runs = []
    for number in range(1, times + 1):
        report = report_dir / f'run-{number}.xml'
        cmd = [sys.executable, '-m', 'pytest', *pytest_args, f'--junitxml={report}', '-o', 'junit_family=xunit1']
        print(f'test-repeat: run {number} of {times}: {" ".join(cmd[1:])}', flush=True)
        start = time.monotonic()
        status = subprocess.run(cmd, check=False).returncode
        run = Run(number, status, time.monotonic() - start)
        read_report(report, run)
        if status != 0 and not run.failures:
            run.failures.append(('(the run)', f'pytest exited with status {status} without a failed test'))
        runs.append(run)
        print(f'test-repeat: run {number} of {times}: {summary_line(run)}', flush=True)
    return runs


def summary_line(run: Run) -> str:
    c = run.counts
    passed = c.get('tests', 0) - c.get('failures', 0) - c.get('errors', 0) - c.get('skipped', 0)
    return (f'status {run.status}, {passed} passed, {c.get("failures", 0)} failed, {c.get("errors", 0)} errors, '
            f'{c.get("skipped", 0)} skipped in {run.seconds:.1f} s')


def summarize(runs: Sequence[Run]) -> str:
    """Every run's line, then every failure grouped by test (the runs it failed in, each first message line)."""
    lines = ['', f'test-repeat summary ({len(runs)} runs, {sum(r.seconds for r in runs):.1f} s):']
    lines += [f'  run {r.number}: {summary_line(r)}' for r in runs]
    by_test: dict[str, list[tuple[int, str]]] = {}
    for run in runs:
        for tid, message in run.failures:
            by_test.setdefault(tid, []).append((run.number, message))
    if not by_test:
        lines.append('no failure in any run')
    else:
        lines.append(f'{len(by_test)} test(s) failed:')
        for tid, seen in sorted(by_test.items()):
            lines.append(f'  {tid}: failed in {len(seen)} of {len(runs)} runs')
            lines += [f'    run {number}: {message}' for number, message in seen]
    return '\n'.join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    ours, pytest_args = (argv[:argv.index('--')], argv[argv.index('--') + 1:]) if '--' in argv else (argv, [])
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0], allow_abbrev=False)
    parser.add_argument('times', type=int, help='how many runs')
    parser.add_argument('--keep', type=Path, help='keep the JUnit XML reports (run-K.xml) in this directory')
    args = parser.parse_args(ours)
    if args.times < 1:
        parser.error('times must be at least 1')
    with tempfile.TemporaryDirectory(prefix='test_repeat_') as tmp:
        report_dir = args.keep or Path(tmp)
        report_dir.mkdir(parents=True, exist_ok=True)
        runs = repeat(args.times, pytest_args, report_dir)
    print(summarize(runs), flush=True)
    return 0 if all(r.status == 0 and not r.failures for r in runs) else 1


if __name__ == '__main__':
    sys.exit(main())
