"""``force.png``: force, HU (with Misch bands) and clearance against depth (matplotlib Agg).

The figure is built lean, because a cohort export draws one per trajectory (issue 17: the old
figure cost about 250 ms, most of it matplotlib drawing the whole figure twice for
``tight_layout`` and drawing a 27 000-point line):

* fixed margins for the fixed 1200 x 1000 px canvas instead of ``tight_layout`` (which draws
  the figure once more to measure every label);
* the force time series (one point per millisecond: a band at the vibration frequencies) is
  drawn as the band between its minimum and maximum per pixel column (:func:`envelope`),
  the pixels the full line covered, with 2 vertices per column instead of ~25 points;
* the figure, its axes, ticks and fixed artists built once per process (:class:`_Canvas`);
* the PNG encoded by :func:`png_bytes` (one filter, fast zlib level) instead of Pillow's
  adaptive filtering.
"""

from __future__ import annotations

import math
import os
import struct
import threading
import zlib
from pathlib import Path
from typing import IO, TYPE_CHECKING

import numpy as np

from ctdrill.engine.path import PathResult
from ctdrill.engine.stop import stop_words
from ctdrill.imaging.misch import MISCH_BANDS_HU
from ctdrill.text import printable

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from ctdrill.engine.series import ForceSeries
    from ctdrill.model.band import ForceBand

#: Colours of the Misch bands drawn behind the HU trace (D5 is left blank).
_MISCH_COLOURS = {"D1": "#5b3a29", "D2": "#8c6239", "D3": "#c69c6d", "D4": "#e8d4b0"}
#: HU range the open D1 band is drawn up to.
_HU_TOP = 3000.0
#: Canvas: 8 x 6.67 in at 150 dpi = 1200 x 1000 px.
_SIZE_IN = (8.0, 6.67)
_DPI = 150
#: Axes placement (figure fractions) fixed for that canvas: room for 5-character tick labels
#: and the axis label on the left, the stop label above the top axes and the title.
_MARGINS = {"left": 0.095, "right": 0.975, "bottom": 0.075, "top": 0.915, "hspace": 0.14}
#: Axis label positions (axes fractions): left of the widest tick labels, below the x ones.
_YLABEL_AT = (-0.075, 0.5)
_XLABEL_AT = (0.5, -0.2)
#: zlib level of the PNG (level 6 spends about 2.5 times as long on this canvas as level 1,
#: for a file about 15 % smaller).
PNG_COMPRESS_LEVEL = 1
#: Room above the highest force for the legend, a share of the force range.
LEGEND_ROOM = 0.3
#: Envelope columns across the depth axis: at least one per pixel of the axes (~1060 px).
ENVELOPE_COLUMNS = 1200


def envelope(
    x: np.ndarray, y: np.ndarray, x_lo: float, x_hi: float, columns: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Min/max decimation of a dense series for drawing: per column of ``[x_lo, x_hi]`` the
    mean ``x`` and the smallest and largest ``y`` of the points that fall in it.

    Filled between the two (``fill_between``), it covers the pixels the full line covers when
    a column is no wider than a pixel: within a column the full line spans min..max. ``x``
    must be non-decreasing (a drilling at constant feed); points outside ``[x_lo, x_hi]`` go
    to the end columns. Returns (x, y_min, y_max), one entry per non-empty column.
    """
    if x.shape[0] == 0 or not x_hi > x_lo:
        return x, y, y
    col = np.clip(((x - x_lo) / (x_hi - x_lo) * columns).astype(np.int64), 0, columns - 1)
    starts = np.flatnonzero(np.r_[True, col[1:] != col[:-1]])
    counts = np.diff(np.r_[starts, x.shape[0]])
    x_mid = np.add.reduceat(x, starts) / counts
    return x_mid, np.minimum.reduceat(y, starts), np.maximum.reduceat(y, starts)


def draw_template(ax_f: Axes, ax_h: Axes, ax_c: Axes) -> None:
    """What every force figure draws alike: the Misch bands behind the HU axes, the axis
    labels and the grid (force.png's cached canvas and ``ctdrill report``'s curves page)."""
    for name, lo, top in MISCH_BANDS_HU:
        if name not in _MISCH_COLOURS:
            continue
        hi = min(top, _HU_TOP)
        ax_h.axhspan(lo, hi, color=_MISCH_COLOURS[name], alpha=0.25, lw=0)
        ax_h.text(
            0.995,
            (lo + min(hi, 2000.0)) / 2,
            name,
            transform=ax_h.get_yaxis_transform(),
            ha="right",
            va="center",
            fontsize=7,
        )
    ax_f.set_ylabel("force (N)")
    ax_h.set_ylabel("HU")
    ax_c.set_ylabel("clearance (mm)")
    ax_c.set_xlabel("tip depth from the entry (mm)")
    for ax in (ax_f, ax_h, ax_c):
        ax.grid(alpha=0.3)
        # fixed label positions: matplotlib otherwise measures every tick label of the
        # three shared axes on each draw to place them
        ax.yaxis.set_label_coords(*_YLABEL_AT)
    ax_c.xaxis.set_label_coords(*_XLABEL_AT)


class _Canvas:
    """The figure, its three axes and what every export draws alike (labels, grid, Misch
    bands), built once per process; :func:`force_png` adds a trajectory's artists, draws and
    removes them again (ticks, fonts and text layouts are reused: building them was a third
    of the old figure's cost)."""

    def __init__(self) -> None:
        import matplotlib

        matplotlib.use("Agg", force=False)
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        self.fig = Figure(figsize=_SIZE_IN, dpi=_DPI)
        self.canvas = FigureCanvasAgg(self.fig)
        self.fig.subplots_adjust(**_MARGINS)
        self.ax_f, self.ax_h, self.ax_c = self.fig.subplots(3, 1, sharex=True)
        self.lock = threading.Lock()
        draw_template(self.ax_f, self.ax_h, self.ax_c)
        self.fixed = {id(a) for ax in (self.ax_f, self.ax_h, self.ax_c) for a in ax.get_children()}

    def reset(self) -> None:
        """Remove every artist a trajectory added (keep the template's)."""
        for ax in (self.ax_f, self.ax_h, self.ax_c):
            for artist in [*ax.lines, *ax.texts, *ax.patches, *ax.collections]:
                if id(artist) not in self.fixed:
                    artist.remove()
            if ax.legend_ is not None:
                ax.legend_.remove()
            ax.relim()
            ax.set_autoscaley_on(True)
            ax.set_prop_cycle(None)  # the next trajectory's lines start at C0 again


_CANVAS: _Canvas | None = None
_CANVAS_LOCK = threading.Lock()


def _canvas() -> _Canvas:
    global _CANVAS
    with _CANVAS_LOCK:
        if _CANVAS is None:
            _CANVAS = _Canvas()
        return _CANVAS


def force_png(
    result: PathResult,
    series: ForceSeries,
    path: Path | IO[bytes],
    *,
    band: ForceBand | None = None,
) -> None:
    """Draw the export figure into ``path`` (PNG, 1200x1000 px): a file or a binary stream.

    ``band`` (the mean force's 68 % band) is shaded around the mean force; without one the
    force panel says that the set gives no band.
    """
    c = _canvas()
    with c.lock:
        try:
            _draw(c, result, series, band)
            c.canvas.draw()
            data = png_bytes(np.asarray(c.canvas.buffer_rgba())[:, :, :3])
        finally:
            c.reset()
    if isinstance(path, (str, os.PathLike)):
        Path(path).write_bytes(data)
    else:
        path.write(data)


def png_bytes(rgb: np.ndarray) -> bytes:
    """A PNG file (8-bit RGB, no interlace) of ``rgb`` (H, W, 3) uint8.

    Every row uses the PNG "Up" filter (the byte-wise difference to the row above, modulo
    256) and zlib level :data:`PNG_COMPRESS_LEVEL`: one NumPy subtraction and one ``zlib``
    call. Pillow's encoder tries every filter on every row, which cost 2-3 times as long on
    the export canvas for a file about as large.
    """
    h, w, _ = rgb.shape
    rows = np.ascontiguousarray(rgb, dtype=np.uint8).reshape(h, w * 3)
    raw = np.empty((h, 1 + w * 3), dtype=np.uint8)
    raw[:, 0] = 2  # Up
    raw[0, 0] = 0  # the first row has no row above: None
    raw[0, 1:] = rows[0]
    np.subtract(rows[1:], rows[:-1], out=raw[1:, 1:])
    header = struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)  # 8 bit, RGB, deflate, no interlace
    idat = zlib.compress(raw.tobytes(), PNG_COMPRESS_LEVEL)
    return b"".join(
        [b"\x89PNG\r\n\x1a\n", _chunk(b"IHDR", header), _chunk(b"IDAT", idat), _chunk(b"IEND", b"")]
    )


def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


def _draw(c: _Canvas, result: PathResult, series: ForceSeries, band: ForceBand | None) -> None:
    """Add one trajectory's artists to the cached canvas."""
    draw_trajectory(c.fig, c.ax_f, c.ax_h, c.ax_c, result, series, band)


def force_limits_n(
    env_lo: np.ndarray, env_hi: np.ndarray, mean_n: np.ndarray, band: ForceBand | None
) -> tuple[float, float]:
    """The force axis, N: from 0 (or the lowest value drawn, if below) to above the highest
    with room for the legend, so a flat curve is drawn flat (issue 16: an axis zoomed to
    4.5-5.5 N made a small ripple look like a large swing)."""
    drawn = [env_lo, env_hi, mean_n] + ([] if band is None else [band.lo_n, band.hi_n])
    values = np.concatenate([np.asarray(v, dtype=np.float64).ravel() for v in drawn])
    values = values[np.isfinite(values)]
    lo = min(0.0, float(values.min())) if values.size else 0.0
    hi = float(values.max()) if values.size else 1.0
    if not hi > lo:
        hi = lo + 1.0
    return lo, hi + LEGEND_ROOM * (hi - lo)


def draw_trajectory(
    fig: Figure,
    ax_f: Axes,
    ax_h: Axes,
    ax_c: Axes,
    result: PathResult,
    series: ForceSeries,
    band: ForceBand | None,
) -> None:
    """Draw one trajectory on axes prepared by :func:`draw_template`: the force (with its
    vibration envelope, mean and 68 % band), the lip HU, the clearance to each landmark with
    the margins, and the stop, max safe and planned depths on all three."""
    prof = result.profile
    x_hi = result.planned_depth_mm
    feed = float(series.depth_mm[-1] / series.time_s[-1]) if series.time_s[-1] > 0 else 0.0
    env_x, env_lo, env_hi = envelope(series.depth_mm, series.force_n, 0.0, x_hi, ENVELOPE_COLUMNS)
    ax_f.fill_between(
        env_x, env_lo, env_hi, color="#1f77b4", lw=0.4, label="force (with vibration)"
    )
    # the band bounds the mean force S0 (1 + Ke v) at its feed: drawn around that curve
    mean_n = prof.mean_force_n(feed) if band is None else band.mean_n
    ax_f.plot(
        prof.depth_mm,
        mean_n,
        lw=1.2,
        color="#d62728",
        label="mean force S0 (1 + Ke v)",
    )
    if band is not None:
        what = "calibration" + (" + HU" if band.hu is not None else "")
        ax_f.fill_between(
            prof.depth_mm,
            band.lo_n,
            band.hi_n,
            color="#d62728",
            alpha=0.18,
            lw=0,
            label=f"68 % band of the mean ({what})",
        )
    else:
        ax_f.text(
            0.99,
            0.04,
            f"no band: {result.calibration.name} gives no covariance",
            transform=ax_f.transAxes,
            ha="right",
            va="bottom",
            fontsize=7,
            color="#7f7f7f",
        )
    ax_f.set_ylim(*force_limits_n(env_lo, env_hi, mean_n, band))
    ax_f.legend(loc="upper right", fontsize=7)

    ax_h.plot(prof.depth_mm, prof.hu_mean, color="k", lw=1.0, label="lip-mean HU")
    ax_h.plot(result.depth_mm, result.lip.axis_hu, color="#7f7f7f", lw=0.6, label="axis HU")
    hu_max = float(np.max(prof.hu_mean))
    hu_hi = max(2000.0, hu_max + 100.0) if math.isfinite(hu_max) else 2000.0
    ax_h.set_ylim(-1100.0, hu_hi)
    ax_h.legend(loc="upper left", fontsize=7)

    if result.clearance_mm.shape[1]:
        for j, lm in enumerate(result.landmarks):
            ax_c.plot(
                result.depth_mm,
                result.clearance_mm[:, j],
                lw=1.0,
                color=f"C{j % 10}",
                label=printable(lm.name),
            )
        for m in sorted(set(result.margins_mm.tolist())):
            ax_c.axhline(m, color="#d62728", ls="--", lw=0.8)
            ax_c.text(0.0, m, f" margin {m:g} mm", va="bottom", fontsize=7, color="#d62728")
        ax_c.legend(loc="upper right", fontsize=7)
        top = float(np.max(result.clearance_mm[0])) if result.clearance_mm.size else 10.0
        ax_c.set_ylim(min(-1.0, float(np.min(result.clearance_mm)) - 0.5), max(top, 5.0) + 0.5)
    else:
        ax_c.text(0.5, 0.5, "no landmarks in the plan", transform=ax_c.transAxes, ha="center")
        ax_c.set_ylim(0.0, 1.0)

    for ax in (ax_f, ax_h, ax_c):
        ax.axvline(result.stop_depth_mm, color="#d62728", lw=1.2)
        if result.max_safe_depth_mm < result.planned_depth_mm + 1e-9:
            ax.axvline(result.max_safe_depth_mm, color="#ff7f0e", ls=":", lw=1.0)
        ax.axvline(result.planned_depth_mm, color="#7f7f7f", ls="--", lw=0.8)
    ax_f.text(
        result.stop_depth_mm,
        1.02,
        f"stop {result.stop_depth_mm:.2f} mm ({stop_words(result.stop_reason, form='code')})",
        transform=ax_f.get_xaxis_transform(),
        ha="right",
        fontsize=7,
        color="#d62728",
    )
    cal = result.calibration
    label = f"{cal.name} (ILLUSTRATIVE)" if cal.illustrative else cal.name
    # printable: a plan named after a file whose name is not UTF-8 must not fail the plot
    fig.suptitle(printable(f"{result.plan.name}: calibration {label}"), fontsize=9, y=0.985)
    ax_c.set_xlim(0.0, x_hi)
