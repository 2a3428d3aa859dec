"""Where the tests find the checkout: ``REPO`` (its root) and ``TEST_DATA`` (test/data: bags, parameter files, the
reference table, the rosdep key list)."""

from __future__ import annotations

from pathlib import Path

#: The root of the checkout (this file is test/support/paths.py).
REPO = Path(__file__).resolve().parents[2]
#: The committed test data.
TEST_DATA = REPO / 'test' / 'data'
