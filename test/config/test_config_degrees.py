"""Every angle in the shipped and test parameter files is the correctly rounded radian value of the degrees its
comment states: a value one ulp off (-0.10471975511965977 for -6 deg) made `fourbar demo` reject the sweep's
-6 deg commands against a file that says -6 deg."""

from __future__ import annotations

import re
from pathlib import Path

import mpmath
import pytest
from support.paths import REPO, TEST_DATA

FILES = [REPO / 'config' / 'antenna.yaml', *sorted(TEST_DATA.glob('*.yaml'))]
#: `name: <rad>   # <deg> deg` (the comment's first number with its sign).
_ANGLE = re.compile(r'^\s*(\w+):\s*(-?[0-9.e+-]+)\s*#\s*([+-]?[0-9.]+) deg\b')


@pytest.mark.parametrize('path', FILES, ids=lambda p: str(p.relative_to(REPO)))
def test_angles_are_the_degrees_their_comments_state(path: Path) -> None:
    found = [(m[1], float(m[2]), m[3]) for line in path.read_text(encoding='utf-8').splitlines()
             if (m := _ANGLE.match(line))]
    assert found, f'{path}: no commented angle'
    for name, rad, deg in found:
        with mpmath.workdps(40):  # the decimal degrees exactly, times pi / 180 to 40 digits, rounded once
            want = float(mpmath.mpf(deg) * mpmath.pi / 180)
        assert rad == want, f'{path.name}: {name} = {rad!r} is not {deg} deg ({want!r})'
