"""`fourbar demo` with a bad exported ROS_DOMAIN_ID: one line, status 2, nothing written (a good one is taken and
said in the first line: test_bag_demo.py's run to the end)."""

from __future__ import annotations

from pathlib import Path

import pytest
from support.bag_support import CONFIG
from support.cli_support import fourbar


@pytest.mark.parametrize('value', ['abc', '233', '-1'])
def test_a_bad_exported_domain_is_one_line(value: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv('ROS_DOMAIN_ID', value)
    result = fourbar('demo', '--params', CONFIG, '--out', tmp_path / 'demo')
    assert result.returncode == 2
    assert result.stderr.splitlines() == [f'fourbar demo: error: ROS_DOMAIN_ID={value!r} must be an integer in '
                                          '0..232 (unset it to let the demo pick a free one)']
    assert not (tmp_path / 'demo').exists()
