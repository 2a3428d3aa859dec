"""`fourbar demo` runs on an exported ROS_DOMAIN_ID (so a user's other terminals see its topics) and says which
domain it runs on and why; a bad exported value is one line."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from bag_support import CONFIG, Tool
from ros_support import DomainLease


def _env(domain: str) -> dict[str, str]:
    return {**os.environ, 'ROS_DOMAIN_ID': domain}


@pytest.mark.ros
@pytest.mark.slow
def test_demo_runs_on_the_exported_domain(lease: DomainLease, tmp_path: Path) -> None:
    with Tool(['demo', '--params', CONFIG, '--out', tmp_path / 'demo'], _env(str(lease.domain_id))) as demo:
        first = demo.wait_line('fourbar demo: fourbar_node (mode trajectory) and the simulated actuator with',
                               stdout=True)
        assert demo.wait(120.0) == 0, demo.lines
    assert f' on ROS_DOMAIN_ID {lease.domain_id} (from ROS_DOMAIN_ID; this host only); ' in first, first


@pytest.mark.parametrize('value', ['abc', '233', '-1'])
def test_a_bad_exported_domain_is_one_line(value: str, tmp_path: Path) -> None:
    with Tool(['demo', '--params', CONFIG, '--out', tmp_path / 'demo'], _env(value)) as demo:
        assert demo.wait(60.0) == 2
    assert demo.lines == [f'fourbar demo: error: ROS_DOMAIN_ID={value!r} must be an integer in 0..232 (unset it '
                          'to let the demo pick a free one)']
