"""`fourbar reindex PATH`: turn what a killed `fourbar record` left into a complete bag (like `ros2 bag reindex`)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

HELP = ('recover a killed recording: rebuild a complete bag (metadata.yaml, mcap summary) from the '
        'hidden .OUT.*.partial directory, or from a bag directory without metadata.yaml')


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of `fourbar reindex`."""
    parser.add_argument('path', type=Path, metavar='PATH',
                        help='the OUT given to `fourbar record` (its .OUT.*.partial work directory is found '
                        'next to it), that work directory, or a bag directory to rebuild in place')


def run(args: argparse.Namespace) -> int:
    """Rebuild the bag; exit 0 with a complete bag, 2 with one line when there is nothing to recover."""
    from fourbar_ros.bags.storage import reindex

    result = reindex(args.path)  # BagError: one line, status 2 (cli)
    per_topic = ', '.join(f'{t}: {n}' for t, n in result.counts.items())
    print(f'fourbar reindex: wrote {result.path}: {result.messages} messages ({per_topic}) from {result.source} '
          f'({result.storage}, {result.kept_bytes} of {result.source_bytes} bytes readable)', file=sys.stderr)
    if result.dropped is not None:
        print(f'fourbar reindex: the rest of {result.source.name} was incomplete and is dropped ({result.dropped})',
              file=sys.stderr)
    if result.removed is not None:
        print(f'fourbar reindex: removed the work directory {result.removed}', file=sys.stderr)
    return 0
