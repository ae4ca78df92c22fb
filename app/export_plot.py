"""``force.png``: force, HU (with Misch bands) and clearance against depth, and the same figure
on matplotlib axes for ``ctdrill report``.

What is drawn is decided once, by :func:`ctdrill.app.force_figure.force_figure`. ``force.png``
is rasterised by :func:`ctdrill.app.raster_plot.render` (Pillow): a fresh ``ctdrill export``
of one plan spent about 0.5 s of CPU importing matplotlib and building its figure, more than
the whole export's work, while the raster renderer costs about 50 ms. The PNG is encoded by
:func:`png_bytes` (one filter, zlib-ng's fastest level) instead of Pillow's adaptive filtering.
:func:`draw_force_figure` draws the same figure on matplotlib axes (the report's curves page).
"""

from __future__ import annotations

import os
import struct
import zlib
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

import numpy as np

from ctdrill.app.force_figure import ForceFigure, Panel, force_figure

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from ctdrill.engine.path import PathResult
    from ctdrill.engine.series import ForceSeries
    from ctdrill.model.band import ForceBand

#: Canvas: 1200 x 1000 px (8 x 6.67 in at 150 dpi).
SIZE_PX = (1200, 1000)
#: zlib level of the PNG (level 6 spends about 2.5 times as long on this canvas as level 1,
#: for a file about 15 % smaller).
PNG_COMPRESS_LEVEL = 1
#: Axis label positions (axes fractions): left of the widest tick labels, below the x ones.
YLABEL_AT = (-0.075, 0.5)
XLABEL_AT = (0.5, -0.2)


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
    from ctdrill.app.raster_plot import render

    data = png_bytes(render(force_figure(result, series, band), SIZE_PX))
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
    idat = _deflate(raw.tobytes(), PNG_COMPRESS_LEVEL)
    return b"".join(
        [b"\x89PNG\r\n\x1a\n", _chunk(b"IHDR", header), _chunk(b"IDAT", idat), _chunk(b"IEND", b"")]
    )


def _deflate(data: bytes, level: int) -> bytes:
    """zlib-ng's deflate where installed (about 4 times as fast at level 1 on this canvas, a
    file about 20 % larger), else zlib's: either is a valid zlib stream."""
    try:
        from zlib_ng import zlib_ng
    except ImportError:  # pragma: no cover - zlib-ng is a dependency
        return zlib.compress(data, level)
    out: bytes = zlib_ng.compress(data, level)
    return out


def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


_LS = {"-": "-", "--": "--", ":": ":"}


def _transform(ax: Axes, coords: str) -> Any:
    return {
        "data": ax.transData,
        "axes": ax.transAxes,
        "xdata": ax.get_xaxis_transform(),
        "ydata": ax.get_yaxis_transform(),
    }[coords]


def _draw_panel(ax: Axes, panel: Panel, legend_pt: float) -> None:
    for s in panel.spans:
        ax.axhspan(s.lo, s.hi, color=s.colour, alpha=s.alpha, lw=0)
    for f in panel.fills:
        ax.fill_between(
            f.x, f.lo, f.hi, color=f.colour, alpha=f.alpha, lw=f.edge_pt, label=f.label or None
        )
    for ln in panel.lines:
        ax.plot(ln.x, ln.y, color=ln.colour, lw=ln.width_pt, label=ln.label or None)
    for r in panel.rules:
        draw = ax.axvline if r.vertical else ax.axhline
        draw(r.at, color=r.colour, lw=r.width_pt, ls=_LS[r.style])
    for t in panel.texts:
        ax.text(
            t.x,
            t.y,
            t.text,
            transform=_transform(ax, t.coords),
            ha=t.ha,
            va=t.va,
            fontsize=t.size_pt,
            color=t.colour,
        )
    ax.set_ylabel(panel.ylabel)
    ax.set_ylim(*panel.ylim)
    if panel.legend:
        ax.legend(loc=panel.legend, fontsize=legend_pt)
    ax.grid(alpha=0.3)
    # fixed label positions: matplotlib otherwise measures every tick label to place them
    ax.yaxis.set_label_coords(*YLABEL_AT)


def draw_force_figure(
    fig: Figure, axes: tuple[Axes, Axes, Axes], figure: ForceFigure, *, title: bool = True
) -> None:
    """Draw ``figure`` on three stacked axes sharing x (the report's curves page);
    ``title=False`` leaves the figure's title to the caller."""
    for ax, panel in zip(axes, figure.panels, strict=True):
        _draw_panel(ax, panel, figure.legend_pt)
    axes[2].set_xlabel(figure.xlabel)
    axes[2].xaxis.set_label_coords(*XLABEL_AT)
    axes[2].set_xlim(*figure.xlim)
    if title:
        fig.suptitle(figure.title, fontsize=9, y=0.985)
