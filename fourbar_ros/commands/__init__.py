"""The `fourbar` command line: one subcommand per module of this package."""

from __future__ import annotations

import argparse
import contextlib
import importlib
import os
import pkgutil
import re
import sys
import threading
from collections.abc import Sequence
from typing import Any, NoReturn

from fourbar_ros.core.errors import FourBarError
from fourbar_ros.interface.topics import DEFAULT_STORAGE, Storage

_NUMBER = r'(?:(?:\d+\.?\d*|\.\d+)(?:e[+-]?\d+)?|inf(?:inity)?|nan)'
#: A token that starts with '-' but is a value: a number or a comma-separated list of numbers (-6e-1, -.5, -inf,
#: -0.5,5.0). argparse's own rule only knows -5 and -0.5, so `--theta -6e-1` and `--pairs -0.5,5.0` read as flags.
NEGATIVE_NUMBER = re.compile(rf'^-{_NUMBER}(?:,[+-]?{_NUMBER})*$', re.IGNORECASE)


class CommandError(FourBarError):
    """A command's failure, with the exit status `main` returns for it (2: bad input, the default)."""

    def __init__(self, message: str, status: int = 2) -> None:
        super().__init__(message)
        self.status = status


class Parser(argparse.ArgumentParser):
    """argparse, taking every token that reads as a negative number (or a list of numbers) as a value.

    As in argparse, this holds while no option itself looks like a negative number (none of ours does); the
    subcommand parsers are of this class too (add_subparsers makes them of the parent's class).
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = NEGATIVE_NUMBER  # argparse's hook for this rule (an instance attribute)

    def parse_args(self, args: Sequence[str] | None = None,  # type: ignore[override]
                   namespace: argparse.Namespace | None = None) -> argparse.Namespace:
        """argparse's parse_args, but an unknown option is reported by the subcommand's parser (its name and
        help), not the top-level one."""
        parsed, unknown = self.parse_known_args(args, namespace)
        if unknown:
            getattr(parsed, '_parser', self).error(f'unrecognized arguments: {" ".join(unknown)}')
        return parsed

    def error(self, message: str) -> NoReturn:
        """A usage error as every other error: one line, ``fourbar <command>: error: ...``, exit status 2."""
        self.exit(2, f'{self.prog}: error: {message} (see {self.prog} --help)\n')


def add_storage_argument(parser: argparse.ArgumentParser, help: str, default: Storage | None = DEFAULT_STORAGE) -> None:
    """``--storage {mcap,sqlite3}``, read as a Storage."""
    names = ', '.join(map(str, Storage))

    def storage(text: str) -> Storage:
        try:
            return Storage(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f'invalid choice: {text!r} (choose from {names})') from None

    if default is not None:
        help = f'{help} (default: {default})'
    parser.add_argument('--storage', type=storage, default=default, metavar='{' + names.replace(' ', '') + '}',
                        help=help)


def command_names() -> list[str]:
    """The subcommands: the modules of this package not starting with '_' (found without importing them)."""
    return sorted(info.name for info in pkgutil.iter_modules(__path__) if not info.name.startswith('_'))


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    """The top-level parser with every discovered subcommand; with ``only``, that command's module alone is
    imported (each imports the package's core, so importing all costs a start-up), the others are placeholders
    without options (enough to parse a command line naming ``only``)."""
    parser = Parser(prog='fourbar', description=__doc__.splitlines()[0] if __doc__ else None)
    sub = parser.add_subparsers(dest='command', metavar='COMMAND', required=True)
    for name in command_names():
        if only is not None and name != only:
            sub.add_parser(name)
            continue
        module = importlib.import_module(f'{__name__}.{name}')
        p = sub.add_parser(name, help=module.HELP, description=module.HELP)
        module.add_arguments(p)
        p.set_defaults(_run=module.run, _prog=f'fourbar {name}', _parser=p)
    return parser


def _chosen(argv: Sequence[str]) -> str | None:
    """The subcommand ``argv`` names (its first token, when that is one); None otherwise (``--help``, a typo),
    where the whole parser is built for its listing and messages."""
    return argv[0] if argv and argv[0] in command_names() else None


def _stop_held() -> contextlib.AbstractContextManager[object]:
    """SIGINT and SIGTERM noted and raised as KeyboardInterrupt (status 130) from the command's start, before it
    imports rclpy (``runtime.stop.stop_on_signals``; in the main thread only, where Python runs signal handlers)."""
    if threading.current_thread() is not threading.main_thread():
        return contextlib.nullcontext()
    from fourbar_ros.runtime.stop import stop_on_signals

    return stop_on_signals()


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the `fourbar` console script; returns the exit status."""
    tokens = sys.argv[1:] if argv is None else list(argv)
    args = build_parser(_chosen(tokens)).parse_args(tokens)
    try:
        with _stop_held():
            return int(args._run(args))
    except FourBarError as exc:  # the one place an error becomes a message and a status
        print(f'{args._prog}: error: {exc}', file=sys.stderr)
        return exc.status if isinstance(exc, CommandError) else 2
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:  # e.g. `fourbar check | head`: the reader left; say nothing more
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141


if __name__ == '__main__':
    sys.exit(main())
