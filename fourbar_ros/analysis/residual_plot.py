"""The residual plot of `fourbar calibrate`, drawn with Pillow in the command's process (docs/how-to/calibrate.md).

Pillow rather than matplotlib: importing matplotlib alone costs more CPU than reading a 10-minute recording."""

from __future__ import annotations

import io
import math
from typing import Any

import numpy as np
import numpy.typing as npt

#: Points per series drawn (every k-th reading beyond that); the mean per bin uses them all.
PLOT_POINTS = 4000
BINS = 40
#: Image size (px), font size (px) and the colours (as matplotlib's tab:blue and tab:red).
WIDTH, HEIGHT = 800, 600
FONT_PX = 13
BLUE, RED, GREEN = (31, 119, 180), (214, 39, 40), (44, 160, 44)
GREY, BLACK, WHITE = (200, 200, 200), (0, 0, 0), (255, 255, 255)
#: Plot area of a panel: left and right margins, and per panel its top and bottom (px).
LEFT, RIGHT = 80, WIDTH - 24
PANELS = ((70, 290), (345, 545))


def ticks(lo: float, hi: float, count: int = 6) -> list[float]:
    """Round tick values (1, 2 or 5 times a power of ten apart) covering [lo, hi] with about ``count`` of them."""
    span = hi - lo if hi > lo else max(abs(hi), 1.0)
    raw = span / count
    power = 10.0 ** math.floor(math.log10(raw))
    step = next(m * power for m in (1.0, 2.0, 5.0, 10.0) if m * power >= raw)
    first = math.ceil(lo / step - 1e-9)
    values = []
    k = first
    while k * step <= hi + 1e-9 * step:
        values.append(round(k * step, 12))
        k += 1
    return values


def _label(value: float, values: list[float]) -> str:
    step = values[1] - values[0] if len(values) > 1 else 1.0
    decimals = max(0, -math.floor(math.log10(step) + 1e-9))
    text = f'{value:.{decimals}f}'
    return '0' if float(text) == 0.0 else text


def _font(size: int) -> Any:
    from PIL import ImageFont

    try:
        return ImageFont.load_default(size=size)
    except (TypeError, OSError, ImportError):  # a Pillow without FreeType: its bitmap font
        return ImageFont.load_default()


def draw(theta_deg: npt.NDArray[np.float64], before: npt.NDArray[np.float64], after: npt.NDArray[np.float64],
         title: str, rising: npt.NDArray[np.bool_] | None = None) -> bytes:
    """PNG bytes: the residuals (rad, drawn in mrad) against the antenna angle (deg), before and after; with
    ``rising`` (per reading: the joint's angle rising) the mean per bin of the two directions apart, where a latency
    or a backlash shows as two lines either side of zero."""
    from PIL import Image, ImageDraw

    step = max(1, theta_deg.size // PLOT_POINTS)
    x_lo, x_hi = float(theta_deg.min()), float(theta_deg.max())
    edges = np.linspace(x_lo, x_hi, BINS + 1)
    which = np.clip(np.searchsorted(edges, theta_deg, side='right') - 1, 0, BINS - 1)
    groups = ([(np.ones(theta_deg.size, dtype=bool), RED, 'mean per bin')] if rising is None else
              [(rising, RED, 'mean per bin, rising'), (~rising, GREEN, 'mean per bin, falling')])
    centres = 0.5 * (edges[1:] + edges[:-1])
    if x_hi <= x_lo:
        x_lo, x_hi = x_lo - 0.5, x_hi + 0.5
    x_ticks = [t for t in ticks(x_lo, x_hi) if x_lo <= t <= x_hi]

    def px(x: npt.NDArray[np.float64] | float) -> Any:
        return LEFT + (np.asarray(x) - x_lo) * ((RIGHT - LEFT) / (x_hi - x_lo))

    image = Image.new('RGB', (WIDTH, HEIGHT), WHITE)
    pen = ImageDraw.Draw(image)
    font, big = _font(FONT_PX), _font(FONT_PX + 3)
    pen.text((WIDTH / 2, 12), title, fill=BLACK, font=big, anchor='mt')
    for (top, bottom), residuals, label in ((PANELS[0], before, 'before: the given lengths, zero offsets'),
                                            (PANELS[1], after, 'after: the calibrated lengths and offsets')):
        r = residuals * 1e3
        with np.errstate(invalid='ignore', divide='ignore'):
            means = [np.bincount(which[g], weights=r[g], minlength=BINS) / np.bincount(which[g], minlength=BINS)
                     for g, _, _ in groups]
        shown = r[::step]
        finite = np.concatenate((shown, *(m[np.isfinite(m)] for m in means), [0.0]))
        y_lo, y_hi = float(finite.min()), float(finite.max())
        pad = 0.05 * (y_hi - y_lo) if y_hi > y_lo else 0.5
        y_lo, y_hi = y_lo - pad, y_hi + pad

        def py(y: Any, top: int = top, bottom: int = bottom, y_lo: float = y_lo, y_hi: float = y_hi) -> Any:
            return bottom - (np.asarray(y) - y_lo) * ((bottom - top) / (y_hi - y_lo))

        y_ticks = [t for t in ticks(y_lo, y_hi) if y_lo <= t <= y_hi]
        for t in y_ticks:
            y = float(py(t))
            pen.line([(LEFT, y), (RIGHT, y)], fill=GREY)
            pen.text((LEFT - 6, y), _label(t, y_ticks), fill=BLACK, font=font, anchor='rm')
        for t in x_ticks:
            x = float(px(t))
            pen.line([(x, top), (x, bottom)], fill=GREY)
            pen.text((x, bottom + 4), _label(t, x_ticks), fill=BLACK, font=font, anchor='mt')
        zero = float(py(0.0))
        pen.line([(LEFT, zero), (RIGHT, zero)], fill=BLACK)
        pen.point(list(zip(px(theta_deg[::step]).tolist(), py(shown).tolist(), strict=True)), fill=BLUE)
        for mean, (_, colour, _) in zip(means, groups, strict=True):
            ok = np.isfinite(mean)
            line = list(zip(px(centres[ok]).tolist(), py(mean[ok]).tolist(), strict=True))
            if len(line) > 1:
                pen.line(line, fill=colour, width=2)
        pen.rectangle([LEFT, top, RIGHT, bottom], outline=BLACK)
        rms = math.sqrt(float(np.mean(residuals * residuals))) * 1e3
        pen.text(((LEFT + RIGHT) / 2, top - 6), f'{label}: RMS {rms:.3g} mrad', fill=BLACK, font=font, anchor='md')
        ylabel = 'sensor - model (mrad)'
        box = pen.textbbox((0, 0), ylabel, font=font)
        strip = Image.new('RGB', (int(box[2] - box[0]) + 4, int(box[3] - box[1]) + 4), WHITE)
        ImageDraw.Draw(strip).text((2 - box[0], 2 - box[1]), ylabel, fill=BLACK, font=font)
        strip = strip.rotate(90, expand=True)
        image.paste(strip, (8, int((top + bottom - strip.height) / 2)))
    # The legend, in the top panel's upper right corner.
    lx, ly = RIGHT - 190, PANELS[0][0] + 8
    pen.rectangle([lx - 6, ly - 4, RIGHT - 6, ly + 18 + 18 * len(groups)], fill=WHITE, outline=GREY)
    pen.ellipse([lx + 8, ly + 4, lx + 12, ly + 8], fill=BLUE)
    pen.text((lx + 26, ly + 6), 'readings (a sample)', fill=BLACK, font=font, anchor='lm')
    for k, (_, colour, label) in enumerate(groups, start=1):
        pen.line([(lx, ly + 6 + 18 * k), (lx + 20, ly + 6 + 18 * k)], fill=colour, width=2)
        pen.text((lx + 26, ly + 6 + 18 * k), label, fill=BLACK, font=font, anchor='lm')
    pen.text(((LEFT + RIGHT) / 2, HEIGHT - 14), 'antenna angle theta (deg): the calibrated model at the measured '
             'joint', fill=BLACK, font=font, anchor='md')
    buf = io.BytesIO()
    image.save(buf, format='PNG', optimize=False, compress_level=6)
    return buf.getvalue()
