"""Depth plots (HU with Misch bands, predicted force, clearance with the margin): what they
show and where, as pure functions (the curves, the axes' ranges, their ticks, the frames in a
widget of a given size, the titles). The window paints them with ``QPainter``
(:mod:`ctdrill.app.gui.plots_paint`); ``force.png`` is drawn by :mod:`ctdrill.app.export_plot`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ctdrill.engine.stop import stop_words
from ctdrill.hu import AIR_HU
from ctdrill.imaging.misch import MISCH_BANDS_HU

#: Misch bands as drawn: the owner's (``ctdrill.imaging.misch``), open ends clipped to the
#: plotted HU range.
MISCH_BANDS: tuple[tuple[str, float, float], ...] = tuple(
    (label, max(lo, AIR_HU), min(hi, 3000.0)) for label, lo, hi in MISCH_BANDS_HU
)
#: Each Misch band's fill, in the order of :data:`MISCH_BANDS`.
BAND_COLOURS = ("#c8d7f0", "#d4e8d0", "#f2ecc4", "#f5dcc4", "#f1d0d0")
#: The plots' colours by role.
COLOURS = {
    "hu": "#203060",
    "force": "#c04000",
    "force_band": "#e07020",
    "mean": "#4060c0",
    "clearance": "#207040",
    "stop": "#d02080",
    "planned": "#808080",
    "margin_line": "#d02020",
    "live": "#1060ff",
    "grid": "#d8d8d8",
    "text": "#202020",
}

#: Resolution the window's matplotlib figures are made at (the teleop and debrief views),
#: dots per inch: a point is 80/72 px there.
WINDOW_DPI = 80.0
#: Smallest text, pt: 9 pt is 10 px at :data:`WINDOW_DPI` (issue 16: 7-8 pt, 8-9 px, was
#: hard to read at the window's default size). Tick labels, axis labels and notes.
TEXT_PT = 9.0
#: Titles above each axes, pt (11 px at the window's resolution).
TITLE_PT = 10.0
#: The same sizes in pixels (the depth plots are painted in pixels).
TEXT_PX = round(TEXT_PT * WINDOW_DPI / 72.0)
TITLE_PX = round(TITLE_PT * WINDOW_DPI / 72.0)
#: Room around the axes, px (the tick and axis labels are never clipped however the window is
#: sized): left of the y tick labels and axis label, right of the Misch labels, above the
#: first title, below the x label, and between axes for a title.
MARGIN_PX = {"left": 62.0, "right": 34.0, "top": 6.0, "bottom": 40.0, "gap": 22.0}
#: Pixels per tick step at least, along the depth axis and up a value axis (labels 10 px
#: high; the steps: :func:`ctdrill.app.raster_plot.nice_ticks`, as ``force.png``'s).
TICK_SPACING_PX = {"x": 48.0, "y": 18.0}


@dataclass(frozen=True, eq=False)
class DepthCurves:
    """What the depth plots show; arrays share the depth axis.

    Attributes
    ----------
    depth_mm : (N,) tip depth from the entry point, mm.
    hu : (N,) lip-mean HU at each depth.
    force_n : (N,) predicted mean cutting force at the planned feed, N.
    force_band_n : (N,) half-width of the vibration (sum of harmonic amplitudes), N, or None.
    clearance_mm : (N,) clearance from the drill to the nearest landmark, mm (inf: none).
    mean_lo_n, mean_hi_n : (N,) the mean force's 68 % band from the calibration's covariance
        (``ctdrill.model.band``), or None when the set gives none (``band_note`` says so).
    """

    depth_mm: np.ndarray
    hu: np.ndarray
    force_n: np.ndarray
    clearance_mm: np.ndarray
    planned_depth_mm: float
    stop_depth_mm: float
    stop_reason: str
    margin_mm: float
    force_band_n: np.ndarray | None = None
    calibration: str = ""
    mean_lo_n: np.ndarray | None = None
    mean_hi_n: np.ndarray | None = None
    band_note: str = ""


#: Room added to the axes' ranges while a plan is dragged (:mod:`ctdrill.app.gui.plots_live`),
#: so most moves fit the axes already drawn.
LIVE_HEADROOM = 1.25
#: Curves need a redraw of the axes when they shrink below this share of an axis' range.
MIN_FILL = 0.15


@dataclass(frozen=True)
class DepthLimits:
    """The axes' ranges for some curves: depth (0 to ``depth_max``), HU, force, clearance."""

    depth_max: float
    hu: tuple[float, float]
    force: tuple[float, float]
    clearance: tuple[float, float] | None

    def contains(self, need: DepthLimits) -> bool:
        """True when curves needing ``need`` are drawn well on axes of ``self``: everything
        inside, nothing squeezed below :data:`MIN_FILL` of the range."""

        def fits(have: tuple[float, float], want: tuple[float, float]) -> bool:
            span = have[1] - have[0]
            inside = have[0] <= want[0] and want[1] <= have[1]
            return inside and want[1] - want[0] >= MIN_FILL * span

        if not (MIN_FILL * self.depth_max <= need.depth_max <= self.depth_max):
            return False
        if (self.clearance is None) != (need.clearance is None):
            return False
        clear_ok = (
            self.clearance is None or need.clearance is None or fits(self.clearance, need.clearance)
        )
        return (
            self.hu[0] <= need.hu[0]
            and need.hu[1] <= self.hu[1]
            and fits(self.force, need.force)
            and clear_ok
        )


def depth_limits(curves: DepthCurves, headroom: float = 1.0) -> DepthLimits:
    """The ranges that show ``curves`` (``headroom`` > 1 widens depth, force and clearance)."""
    d = curves.depth_mm
    depth = (max(float(d[-1]), curves.planned_depth_mm) * 1.02 + 1e-6) * headroom
    hu_lo = min(-200.0, float(np.nanmin(curves.hu)) - 100.0)
    hu_hi = max(1600.0, float(np.nanmax(curves.hu)) + 100.0)
    hu_hi += (headroom - 1.0) * (hu_hi - hu_lo)
    f_lo, f_hi = force_limits_n(curves)
    span = f_hi - f_lo
    f_hi = f_lo + span * headroom
    if f_lo < 0.0:  # a band dipping below 0 N: room below too
        f_lo -= (headroom - 1.0) * span
    finite = np.isfinite(curves.clearance_mm)
    clear = None
    if finite.any():
        top = max(float(np.max(curves.clearance_mm[finite])), curves.margin_mm * 2.0)
        low = min(0.0, float(np.min(curves.clearance_mm[finite])))
        clear = (low - (headroom - 1.0) * top, top * 1.05 * headroom)
    return DepthLimits(depth, (hu_lo, hu_hi), (f_lo, f_hi), clear)


def stop_title(curves: DepthCurves) -> str:
    """The stop in words, the one summary the plots' title and the status bar show (of the
    dragged plan during a drag)."""
    return (
        f"stop at {curves.stop_depth_mm:.2f} mm ({stop_words(curves.stop_reason, form='code')}) "
        f"of {curves.planned_depth_mm:.2f} mm planned"
    )


def force_title(curves: DepthCurves) -> str:
    """The force plot's title: the calibration and what the bands are."""
    title = "predicted force"
    if curves.calibration:
        title += f" ({curves.calibration})"
    if curves.band_note:
        title += f"; {curves.band_note}"
    return title


def curves_key(curves: DepthCurves) -> tuple[object, ...]:
    """What the lasting layer of some curves' plots is made of (which pieces exist, the force
    title, the margin): curves of the same key are drawn on the same axes."""
    return (
        curves.force_band_n is not None,
        curves.mean_lo_n is not None and curves.mean_hi_n is not None,
        bool(np.isfinite(curves.clearance_mm).any()),
        force_title(curves),
        curves.margin_mm,
    )


def force_limits_n(curves: DepthCurves) -> tuple[float, float]:
    """The force axis, N: from 0 (or the lowest value drawn, if below) to a little above the
    highest, so a flat curve is drawn flat (issue 16: an axis zoomed to 4.5-5.5 N made a
    0.1 N ripple look like a large swing)."""
    drawn = [curves.force_n]
    if curves.force_band_n is not None:
        drawn += [curves.force_n - curves.force_band_n, curves.force_n + curves.force_band_n]
    if curves.mean_lo_n is not None and curves.mean_hi_n is not None:
        drawn += [curves.mean_lo_n, curves.mean_hi_n]
    values = np.concatenate([np.asarray(v, dtype=np.float64).ravel() for v in drawn])
    values = values[np.isfinite(values)]
    lo = min(0.0, float(values.min())) if values.size else 0.0
    hi = float(values.max()) if values.size else 1.0
    hi = max(hi, lo + 1.0) if hi <= lo else hi
    return lo, hi + 0.08 * (hi - lo)


@dataclass(frozen=True)
class Frame:
    """One axes' rectangle in the widget, px (``x0`` left, ``y0`` top) and its data range."""

    x0: float
    y0: float
    x1: float
    y1: float
    lo: float
    hi: float

    def y_px(self, value: np.ndarray | float) -> np.ndarray:
        """Pixel row of data ``value`` (the range's ``lo`` at the bottom)."""
        scale = (self.y1 - self.y0) / (self.hi - self.lo) if self.hi > self.lo else 0.0
        return self.y1 - (np.asarray(value, dtype=np.float64) - self.lo) * scale

    def value_at(self, y_px: float) -> float:
        """Data value at pixel row ``y_px`` (the inverse of :meth:`y_px`)."""
        return self.lo + (self.y1 - y_px) / (self.y1 - self.y0) * (self.hi - self.lo)


@dataclass(frozen=True)
class PlotLayout:
    """Where the three axes (HU, force, clearance) sit in a widget of ``width`` x ``height``
    px, sharing the depth axis 0 .. ``depth_max``."""

    width: int
    height: int
    depth_max: float
    frames: tuple[Frame, Frame, Frame]

    def x_px(self, depth_mm: np.ndarray | float) -> np.ndarray:
        """Pixel column of ``depth_mm``."""
        f = self.frames[0]
        scale = (f.x1 - f.x0) / self.depth_max if self.depth_max > 0 else 0.0
        return f.x0 + np.asarray(depth_mm, dtype=np.float64) * scale

    def depth_at(self, x_px: float) -> float:
        """Depth, mm, at pixel column ``x_px`` (the inverse of :meth:`x_px`)."""
        f = self.frames[0]
        return (x_px - f.x0) / (f.x1 - f.x0) * self.depth_max


def plot_layout(width: int, height: int, limits: DepthLimits | None) -> PlotLayout | None:
    """The three frames with :data:`MARGIN_PX` of room in ``width`` x ``height`` px; None when
    the widget is too small to hold them. Without ``limits`` (a message) the ranges are the
    empty plots' (depth 0-1 mm, HU from air to 2000)."""
    m = MARGIN_PX
    left, right = m["left"], width - m["right"]
    top, bottom = m["top"] + m["gap"], height - m["bottom"]
    each = (bottom - top - 2.0 * m["gap"]) / 3.0
    if right - left < 20.0 or each < 8.0:
        return None
    if limits is None:
        ranges = ((AIR_HU, 2000.0), (0.0, 1.0), (0.0, 1.0))
        depth = 1.0
    else:
        ranges = (limits.hu, limits.force, limits.clearance or (0.0, 1.0))
        depth = limits.depth_max
    frames = []
    y = top
    for lo, hi in ranges:
        frames.append(Frame(left, y, right, y + each, float(lo), float(hi)))
        y += each + m["gap"]
    return PlotLayout(width, height, float(depth), (frames[0], frames[1], frames[2]))
