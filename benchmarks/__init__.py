"""Benchmarks of fourbar_ros: run time against error, numerical stress, peers. Entry: ``python -m benchmarks.run``.

Not part of the installed package. The error of every method is measured against :mod:`benchmarks.reference`,
an independent 50-digit evaluation (mpmath) derived from the loop-closure equations, not from the core's code.
This module holds what every benchmark module shares: the repository's paths and the command line.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parent.parent
CONFIG = REPO / 'config' / 'antenna.yaml'


def options(argv: Sequence[str] | None, doc: str | None, **flags: str) -> argparse.Namespace:
    """A benchmark module's command line: ``--quick`` and the boolean ``flags`` (name -> help)."""
    parser = argparse.ArgumentParser(description=(doc or '').splitlines()[0])
    parser.add_argument('--quick', action='store_true', help='smaller sizes and fewer repeats')
    for name, text in flags.items():
        parser.add_argument(f'--{name}', action='store_true', help=text)
    return parser.parse_args(argv)


def print_json(figures: Any) -> int:
    """Print a benchmark's figures as JSON; exit status 0."""
    print(json.dumps(figures, indent=2))
    return 0
