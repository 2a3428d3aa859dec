"""scripts/test_repeat.py (``make test-repeat``): its summary of a JUnit XML report, on a report written here."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

from support.paths import REPO


def load() -> ModuleType:
    spec = importlib.util.spec_from_file_location('test_repeat_script', REPO / 'scripts' / 'test_repeat.py')
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses look their module up there
    spec.loader.exec_module(module)
    return module


REPORT = '''<?xml version="1.0" encoding="utf-8"?>
<testsuites><testsuite name="pytest" errors="1" failures="1" skipped="1" tests="4" time="1.0">
<testcase classname="test.node.test_x.TestA" name="test_ok" file="test/node/test_x.py" line="3" time="0.1"/>
<testcase classname="test.node.test_x.TestA" name="test_bad" file="test/node/test_x.py" line="5" time="0.1">
<failure message="AssertionError: timed out after 30 s&#10;second line">trace</failure></testcase>
<testcase classname="test.live.test_y" name="test_td[a]" file="test/live/test_y.py" line="9" time="0.1">
<error message="failed on teardown with &quot;RuntimeError: left&quot;">trace</error></testcase>
<testcase classname="test.live.test_y" name="test_skip" file="test/live/test_y.py" line="12" time="0.0">
<skipped message="why"/></testcase>
</testsuite></testsuites>
'''


def test_a_report_gives_counts_and_each_failure_with_its_first_line(tmp_path: Path) -> None:
    tr = load()
    path = tmp_path / 'run-1.xml'
    path.write_text(REPORT, encoding='utf-8')
    run = tr.Run(1, 1, 2.0)
    tr.read_report(path, run)
    assert run.counts == {'tests': 4, 'failures': 1, 'errors': 1, 'skipped': 1}
    assert run.failures == [('test/node/test_x.py::TestA::test_bad', 'AssertionError: timed out after 30 s'),
                            ('test/live/test_y.py::test_td[a]', 'error: failed on teardown with "RuntimeError: left"')]
    text = tr.summarize([run, tr.Run(2, 0, 1.0, {'tests': 4})])
    assert 'run 1: status 1, 1 passed, 1 failed, 1 errors, 1 skipped in 2.0 s' in text
    assert 'run 2: status 0, 4 passed, 0 failed, 0 errors, 0 skipped in 1.0 s' in text
    assert 'test/node/test_x.py::TestA::test_bad: failed in 1 of 2 runs' in text


def test_a_run_without_a_report_or_failed_test_still_counts_as_failed(tmp_path: Path) -> None:
    tr = load()
    run = tr.Run(1, 4, 0.5)
    tr.read_report(tmp_path / 'missing.xml', run)
    assert run.failures == [] and run.counts == {}
