"""Shared pytest setup: test helpers importable as plain modules; hypothesis made deterministic; ulp jitter.

Property tests draw the same examples on every run (derandomize), so CI cannot pass or fail by luck. Set
HYPOTHESIS_PROFILE=explore to search with fresh random examples locally.

``--ulp-jitter`` (or FOURBAR_ULP_JITTER=1) runs the session as if on another CPU: numpy's transcendental ufuncs
move their results by one ulp on a fixed share of the elements (see ulp_jitter.py; the share is
``--ulp-jitter-share`` or FOURBAR_ULP_JITTER_SHARE, default 0.25; ``--ulp-jitter-seed`` or
FOURBAR_ULP_JITTER_SEED picks another set of elements). Only this process is affected, not the
processes a test starts.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable
from pathlib import Path

import pytest
from hypothesis import settings

sys.path.insert(0, str(Path(__file__).parent))

import ulp_jitter  # found through the path above

settings.register_profile('deterministic', derandomize=True, deadline=None, print_blob=True)
settings.register_profile('explore', derandomize=False, deadline=None, print_blob=True)
settings.load_profile(os.environ.get('HYPOTHESIS_PROFILE', 'deterministic'))

_undo_jitter: list[Callable[[], None]] = []


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup('fourbar')
    group.addoption('--ulp-jitter', action='store_true', default=os.environ.get('FOURBAR_ULP_JITTER', '') not in
                    ('', '0'), help='move numpy transcendental results by one ulp on a fixed share of elements '
                    '(as another CPU might); also FOURBAR_ULP_JITTER=1')
    group.addoption('--ulp-jitter-share', type=float,
                    default=float(os.environ.get('FOURBAR_ULP_JITTER_SHARE', ulp_jitter.DEFAULT_SHARE)),
                    help=f'share of elements moved (default {ulp_jitter.DEFAULT_SHARE}); also '
                    'FOURBAR_ULP_JITTER_SHARE')
    group.addoption('--ulp-jitter-seed', type=int, default=int(os.environ.get('FOURBAR_ULP_JITTER_SEED', '0')),
                    help='another deterministic choice of the moved elements; also FOURBAR_ULP_JITTER_SEED')


def pytest_configure(config: pytest.Config) -> None:
    if config.getoption('--ulp-jitter'):
        _undo_jitter.append(ulp_jitter.install(config.getoption('--ulp-jitter-share'),
                                               config.getoption('--ulp-jitter-seed')))


def pytest_unconfigure(config: pytest.Config) -> None:
    while _undo_jitter:
        _undo_jitter.pop()()


def pytest_report_header(config: pytest.Config) -> str | None:
    if config.getoption('--ulp-jitter'):
        return (f'ulp jitter: on (share {config.getoption("--ulp-jitter-share")}, seed '
                f'{config.getoption("--ulp-jitter-seed")}): numpy transcendentals moved by one ulp')
    return None
