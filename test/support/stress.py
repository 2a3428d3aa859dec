"""Statistical repeats: a case runs once in every run, and ``n`` times where the ``stress`` marker is selected
(``make test-stress``; conftest.py leaves ``stress`` items out otherwise)."""

from __future__ import annotations

from typing import Any

import pytest


def once_and_stress(n: int) -> list[Any]:
    """Values for ``@pytest.mark.parametrize('repeats', ...)``: 1 (id ``once``) and ``n`` (id ``xN``, ``stress``)."""
    return [pytest.param(1, id='once'), pytest.param(n, id=f'x{n}', marks=pytest.mark.stress)]
