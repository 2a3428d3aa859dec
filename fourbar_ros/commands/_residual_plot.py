"""The residual plot of `fourbar calibrate`, drawn by a worker process that imports matplotlib while the command
reads the recording and fits (the import alone costs about as much as reading a 10-minute recording).

``PlotWorker`` starts this file in a fresh interpreter at once (``python -S``, the command's ``sys.path`` given
as PYTHONPATH, and run by path: the worker imports neither the site hooks nor the package, only numpy and
matplotlib); ``render`` sends it the arrays
(``numpy.save`` on its stdin) and reads the PNG from its stdout. Should the worker fail, the plot is drawn in this
process instead; ``close`` ends a worker not used. Not a subcommand (the leading underscore).
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import os
import subprocess
import sys

import numpy as np
import numpy.typing as npt

#: Points per series drawn (every k-th reading beyond that); the mean per bin uses them all.
PLOT_POINTS = 4000
BINS = 40


def draw(theta_deg: npt.NDArray[np.float64], before: npt.NDArray[np.float64], after: npt.NDArray[np.float64],
         title: str) -> bytes:
    """PNG bytes: the residuals (rad, drawn in mrad) against the antenna angle (deg), before and after."""
    import matplotlib
    matplotlib.use('Agg')
    from matplotlib.figure import Figure

    step = max(1, theta_deg.size // PLOT_POINTS)
    edges = np.linspace(float(theta_deg.min()), float(theta_deg.max()), BINS + 1)
    which = np.clip(np.searchsorted(edges, theta_deg, side='right') - 1, 0, BINS - 1)
    counts = np.bincount(which, minlength=BINS)
    centres = 0.5 * (edges[1:] + edges[:-1])
    fig = Figure(figsize=(8, 6))
    axes = fig.subplots(2, 1, sharex=True)
    for ax, residuals, label in ((axes[0], before, 'before: the given lengths, zero offsets'),
                                 (axes[1], after, 'after: the calibrated lengths and offsets')):
        r = residuals * 1e3
        ax.plot(theta_deg[::step], r[::step], ',', color='tab:blue', alpha=0.6, label='readings (a sample)')
        with np.errstate(invalid='ignore', divide='ignore'):
            mean = np.bincount(which, weights=r, minlength=BINS) / counts
        ax.plot(centres, mean, '-', color='tab:red', linewidth=1.5, label='mean per bin')
        ax.axhline(0.0, color='k', linewidth=0.5)
        rms = math.sqrt(float(np.mean(residuals * residuals))) * 1e3
        ax.set_title(f'{label}: RMS {rms:.3g} mrad', fontsize=10)
        ax.set_ylabel('sensor - model (mrad)')
    axes[0].legend(loc='best', fontsize=8)
    axes[1].set_xlabel('antenna angle theta (deg): the calibrated model at the measured joint')
    fig.suptitle(title)
    fig.subplots_adjust(left=0.1, right=0.97, top=0.88, bottom=0.09, hspace=0.3)
    buf = io.BytesIO()
    fig.savefig(buf, format='png', dpi=80)
    return buf.getvalue()


class PlotWorker:
    """A worker process drawing one plot (see the module docstring)."""

    def __init__(self) -> None:
        env = {**os.environ, 'PYTHONPATH': os.pathsep.join(p for p in sys.path if p)}
        try:
            self.proc: subprocess.Popen[bytes] | None = subprocess.Popen(
                [sys.executable, '-S', '-c', f'import runpy; runpy.run_path({__file__!r}, run_name="__main__")'],
                stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, env=env)
        except OSError:
            self.proc = None

    def render(self, theta_deg: npt.NDArray[np.float64], before: npt.NDArray[np.float64],
               after: npt.NDArray[np.float64], title: str) -> bytes:
        """The PNG, from the worker, else drawn here."""
        proc, self.proc = self.proc, None
        if proc is not None:
            buf = io.BytesIO()
            head = json.dumps({'title': title}).encode()
            buf.write(len(head).to_bytes(4, 'little') + head)
            for a in (theta_deg, before, after):
                np.save(buf, np.ascontiguousarray(a, dtype=np.float64), allow_pickle=False)
            try:
                png, _ = proc.communicate(buf.getvalue(), timeout=120)
            except (OSError, subprocess.TimeoutExpired):
                png = b''
            finally:
                _end(proc)
            if proc.returncode == 0 and png.startswith(b'\x89PNG'):
                return png
        return draw(theta_deg, before, after, title)

    def close(self) -> None:
        """End the worker if it was not used."""
        proc, self.proc = self.proc, None
        if proc is not None:
            _end(proc)


def _end(proc: subprocess.Popen[bytes]) -> None:
    if proc.poll() is None:
        with contextlib.suppress(OSError):
            proc.kill()
    with contextlib.suppress(Exception):
        proc.wait(timeout=10)
    for stream in (proc.stdin, proc.stdout):
        if stream is not None:
            with contextlib.suppress(OSError):
                stream.close()


def _serve() -> int:
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.figure  # imported while the command reads and fits
    del matplotlib.figure

    data = sys.stdin.buffer.read()
    if len(data) < 4:
        return 1  # the command did not need a plot after all
    size = int.from_bytes(data[:4], 'little')
    head = json.loads(data[4:4 + size])
    buf = io.BytesIO(data[4 + size:])
    theta, before, after = (np.load(buf, allow_pickle=False) for _ in range(3))
    sys.stdout.buffer.write(draw(theta, before, after, str(head['title'])))
    sys.stdout.buffer.flush()
    return 0


if __name__ == '__main__':
    try:
        sys.exit(_serve())
    except KeyboardInterrupt:
        sys.exit(130)
