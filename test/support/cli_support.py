"""The `fourbar` command line in this process: ``fourbar(*args)`` runs ``fourbar_ros.commands.main(argv)``
with stdout and stderr captured, and returns what ``subprocess.run`` would (status, stdout, stderr).

The console script itself (a separate process, its exit status) is tested once in test_design_check.py;
every other command-line test calls ``main`` here, which is what the console script calls.
"""

from __future__ import annotations

import io
import os
import subprocess
from contextlib import redirect_stderr, redirect_stdout

from fourbar_ros.commands import main


def fourbar(*args: str | os.PathLike[str]) -> subprocess.CompletedProcess[str]:
    """``fourbar ARGS``: its exit status (argparse's usage errors and --help included) and its output."""
    argv = [os.fspath(a) for a in args]
    out, err = io.StringIO(), io.StringIO()
    with redirect_stdout(out), redirect_stderr(err):
        try:
            status = main(argv)
        except SystemExit as exc:  # argparse: a usage error (2) or --help (0)
            status = exc.code if isinstance(exc.code, int) else int(exc.code is not None)
    return subprocess.CompletedProcess(['fourbar', *argv], status, out.getvalue(), err.getvalue())
