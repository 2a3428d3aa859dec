"""The `fourbar` command line: one subcommand per module in fourbar_ros.commands.

Each command module defines HELP (one line), add_arguments(parser) and run(args) -> exit status, and imports
anything heavy (rclpy, rosbags, matplotlib) inside run(), so `fourbar solve` stays quick.
"""

from __future__ import annotations

import argparse
import importlib
import os
import pkgutil
import sys
from collections.abc import Sequence

from . import commands
from .errors import FourBarError


def build_parser() -> argparse.ArgumentParser:
    """The top-level parser with every discovered subcommand."""
    parser = argparse.ArgumentParser(prog='fourbar', description=__doc__.splitlines()[0] if __doc__ else None)
    sub = parser.add_subparsers(dest='command', metavar='COMMAND', required=True)
    for info in sorted(pkgutil.iter_modules(commands.__path__), key=lambda m: m.name):
        if info.name.startswith('_'):
            continue
        module = importlib.import_module(f'{commands.__name__}.{info.name}')
        p = sub.add_parser(info.name, help=module.HELP, description=module.HELP)
        module.add_arguments(p)
        p.set_defaults(_run=module.run, _prog=f'fourbar {info.name}')
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the `fourbar` console script; returns the exit status."""
    args = build_parser().parse_args(argv)
    try:
        return int(args._run(args))
    except FourBarError as exc:  # bad input that a command did not word itself
        print(f'{args._prog}: error: {exc}', file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:  # e.g. `fourbar check | head`: the reader left; say nothing more
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141


if __name__ == '__main__':
    sys.exit(main())
