"""The depth plots while a plan is dragged: new curves written into the artists already drawn.

:func:`update_depth_plots` changes the data of the curve artists
:func:`~ctdrill.app.gui.plots.draw_depth_plots` made (lines, bands, stop and planned marks) in
place, so the window redraws only them over a bitmap of the rest (blitting); it refuses (None)
when the new curves need other axes' ranges or other pieces (a band that appears, another
calibration, another margin): the caller then redraws the figure whole.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from matplotlib.figure import Figure

from ctdrill.app.gui.plots import (
    DepthCurves,
    curve_artists,
    curves_key,
    depth_limits,
    stop_title,
)


def update_depth_plots(fig: Figure, curves: DepthCurves) -> list[Any] | None:
    """Write ``curves`` into the curve artists of ``fig``; returns those artists (to be
    drawn), or None when the figure must be redrawn whole."""
    arts = curve_artists(fig)
    if arts is None or curves.depth_mm.size == 0 or arts.key != curves_key(curves):
        return None
    if not arts.limits.contains(depth_limits(curves)):
        return None
    d = curves.depth_mm
    lines, fills = arts.lines, arts.fills
    lines["hu"].set_data(d, curves.hu)
    lines["force"].set_data(d, curves.force_n)
    if "band" in fills and curves.force_band_n is not None:
        band = curves.force_band_n
        fills["band"].set_data(d, curves.force_n - band, curves.force_n + band)
    if "mean" in fills and curves.mean_lo_n is not None and curves.mean_hi_n is not None:
        fills["mean"].set_data(d, curves.mean_lo_n, curves.mean_hi_n)
        lines["mean_lo"].set_data(d, curves.mean_lo_n)
        lines["mean_hi"].set_data(d, curves.mean_hi_n)
    if "clearance" in lines:
        finite = np.isfinite(curves.clearance_mm)
        lines["clearance"].set_data(d[finite], curves.clearance_mm[finite])
    stop, planned = curves.stop_depth_mm, curves.planned_depth_mm
    beyond = planned > stop + 1e-6
    for line in arts.stops:
        line.set_xdata([stop, stop])
    for line, span in zip(arts.planned, arts.spans, strict=True):
        line.set_xdata([planned, planned])
        line.set_visible(beyond)
        span.set_x(stop)
        span.set_width(planned - stop)
        span.set_visible(beyond)
    if arts.stop_text is not None:
        arts.stop_text.set_text(stop_title(curves))
    return arts.all()
