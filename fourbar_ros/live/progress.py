"""A one-line progress bar on a terminal (stderr), redrawn at most a few times per second."""

from __future__ import annotations

import sys
import time
from typing import IO


class Progress:
    """A one-line progress bar on stderr, drawn at most 10 times a second; silent unless a TTY."""

    def __init__(self, total: int, label: str, stream: IO[str] | None = None,
                 enabled: bool | None = None) -> None:
        self.total = max(total, 1)
        self.label = label
        self.stream = stream if stream is not None else sys.stderr
        self.enabled = self.stream.isatty() if enabled is None else enabled
        self._last = 0.0
        self._start = time.monotonic()
        self._drawn = False
        self._done = 0

    def update(self, done: int, force: bool = False) -> None:
        """Redraw with ``done`` of ``total`` items finished."""
        self._done = done
        if not self.enabled:
            return
        now = time.monotonic()
        if not force and now - self._last < 0.1:
            return
        self._last = now
        width = 30
        filled = int(width * min(done, self.total) / self.total)
        elapsed = now - self._start
        self.stream.write(f'\r{self.label} [{"#" * filled}{"." * (width - filled)}] '
                          f'{done}/{self.total} {elapsed:5.1f} s')
        self.stream.flush()
        self._drawn = True

    def end(self) -> None:
        """Redraw the last state and end the line (if anything was drawn)."""
        if self.enabled and self._drawn:
            self.update(self._done, force=True)
            self.stream.write('\n')
            self.stream.flush()
