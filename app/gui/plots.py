"""Depth plots (HU with Misch bands, predicted force, clearance with the margin), drawn on any
matplotlib ``Figure``: the window's ``FigureCanvasQTAgg`` and headless tests use the same code.
"""

from __future__ import annotations

import textwrap
from dataclasses import dataclass
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from ctdrill.engine.stop import stop_words
from ctdrill.hu import AIR_HU
from ctdrill.imaging.misch import MISCH_BANDS_HU

#: Misch bands as drawn: the owner's (``ctdrill.imaging.misch``), open ends clipped to the
#: plotted HU range.
MISCH_BANDS: tuple[tuple[str, float, float], ...] = tuple(
    (label, max(lo, AIR_HU), min(hi, 3000.0)) for label, lo, hi in MISCH_BANDS_HU
)
_BAND_COLOURS = ("#c8d7f0", "#d4e8d0", "#f2ecc4", "#f5dcc4", "#f1d0d0")

#: Resolution the window's figure is made at (:class:`ctdrill.app.gui.plots_view.PlotsView`),
#: dots per inch: a point is 80/72 px there.
WINDOW_DPI = 80.0
#: Smallest text, pt: 9 pt is 10 px at :data:`WINDOW_DPI` (issue 16: 7-8 pt, 8-9 px, was
#: hard to read at the window's default size). Tick labels, axis labels and notes.
TEXT_PT = 9.0
#: Titles above each axes, pt (11 px at the window's resolution).
TITLE_PT = 10.0
#: Room around the axes, px (converted to figure fractions for the figure's current size, so
#: the tick and axis labels are never clipped however the window is sized): left of the y tick
#: labels and axis label, right of the Misch labels, above the first title, below the x label,
#: and between axes for a title.
_MARGIN_PX = {"left": 62.0, "right": 34.0, "top": 6.0, "bottom": 40.0, "gap": 22.0}


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
    """The stop in words, as the HU plot's title says it."""
    return (
        f"stop {curves.stop_depth_mm:.2f} mm ({stop_words(curves.stop_reason, form='code')}) of "
        f"{curves.planned_depth_mm:.2f} mm planned"
    )


def force_title(curves: DepthCurves) -> str:
    """The force plot's title: the calibration and what the bands are."""
    title = "predicted force"
    if curves.calibration:
        title += f" ({curves.calibration})"
    if curves.band_note:
        title += f"; {curves.band_note}"
    return title


@dataclass
class CurveArtists:
    """The artists that depend on the curves, by role (what a live update changes in place).

    ``key`` is what must not change for an in-place update (which pieces exist, the force
    title, the margin); ``limits`` the axes' ranges they were drawn in.
    """

    key: tuple[object, ...]
    limits: DepthLimits
    lines: dict[str, Any]
    fills: dict[str, Any]
    stops: list[Any]
    planned: list[Any]
    spans: list[Any]
    stop_text: Any = None

    def all(self) -> list[Any]:
        """Every artist, in drawing order."""
        out = [*self.fills.values(), *self.lines.values(), *self.spans, *self.planned]
        out += self.stops
        return out if self.stop_text is None else [*out, self.stop_text]


def curves_key(curves: DepthCurves) -> tuple[object, ...]:
    """What the curves' drawing is made of (see :class:`CurveArtists`)."""
    return (
        curves.force_band_n is not None,
        curves.mean_lo_n is not None and curves.mean_hi_n is not None,
        bool(np.isfinite(curves.clearance_mm).any()),
        force_title(curves),
        curves.margin_mm,
    )


def draw_depth_plots(
    fig: Figure,
    curves: DepthCurves | None,
    *,
    message: str = "",
    headroom: float = 1.0,
    title_stop: bool = True,
) -> None:
    """Redraw ``fig`` with three stacked axes sharing depth: HU, force, clearance.

    With ``curves`` None the axes are drawn empty with ``message`` (e.g. "computing...").
    The axes are created once and reused. ``headroom`` widens the ranges (a dragged plan's
    next curves then fit them: :mod:`ctdrill.app.gui.plots_live`); ``title_stop`` writes the
    stop as the HU plot's title (the window shows it in a label instead). The artists that
    depend on the curves are kept as :func:`curve_artists`.
    """
    ax_hu, ax_f, ax_c = _axes(fig)
    for ax in (ax_hu, ax_f, ax_c):
        ax.tick_params(labelsize=TEXT_PT)
    for label, lo, hi in MISCH_BANDS:
        colour = _BAND_COLOURS[[b[0] for b in MISCH_BANDS].index(label)]
        ax_hu.axhspan(lo, hi, color=colour, alpha=0.8, lw=0, zorder=0)
    ax_hu.set_ylabel("HU", fontsize=TEXT_PT)
    ax_f.set_ylabel("force (N)", fontsize=TEXT_PT)
    ax_c.set_ylabel("clearance (mm)", fontsize=TEXT_PT)
    ax_c.set_xlabel("depth (mm)", fontsize=TEXT_PT)
    for ax in (ax_hu, ax_f, ax_c):
        ax.grid(True, alpha=0.3)
    if curves is None or curves.depth_mm.size == 0:
        ax_hu.set_ylim(AIR_HU, 2000)
        ax_f.text(
            0.5,
            0.5,
            textwrap.fill(message or "no plan", 120),
            ha="center",
            va="center",
            fontsize=TEXT_PT,
            transform=ax_f.transAxes,
        )
        return
    lims = depth_limits(curves, headroom)
    ax_hu.set_ylim(*lims.hu)
    _misch_labels(fig, ax_hu, *lims.hu)
    ax_f.set_ylim(*lims.force)
    if lims.clearance is not None:
        ax_c.set_ylim(*lims.clearance)
    ax_c.set_xlim(0.0, lims.depth_max)
    ax_f.set_title(force_title(curves), fontsize=TITLE_PT, loc="left")
    if not np.isfinite(curves.clearance_mm).any():
        ax_c.text(0.5, 0.5, "no landmarks", ha="center", va="center", transform=ax_c.transAxes)
    ax_c.axhline(curves.margin_mm, color="#d02020", ls="--", lw=1.0)
    ax_c.text(
        0.0,
        curves.margin_mm,
        f" margin {curves.margin_mm:g} mm",
        color="#d02020",
        fontsize=TEXT_PT,
        va="bottom",
        transform=ax_c.get_yaxis_transform(),
    )
    arts = _draw_curves(fig, curves, lims)
    if title_stop:
        arts.stop_text = ax_hu.set_title(stop_title(curves), fontsize=TITLE_PT, loc="left")
    fig._ctdrill_curves = arts  # type: ignore[attr-defined]


def curve_artists(fig: Figure) -> CurveArtists | None:
    """The curve artists :func:`draw_depth_plots` last drew on ``fig`` (None: a message)."""
    arts = getattr(fig, "_ctdrill_curves", None)
    return arts if isinstance(arts, CurveArtists) else None


def _draw_curves(fig: Figure, curves: DepthCurves, lims: DepthLimits) -> CurveArtists:
    """Draw what depends on ``curves`` on the three axes."""
    ax_hu, ax_f, ax_c = fig.axes
    d = curves.depth_mm
    fills: dict[str, Any] = {}
    lines: dict[str, Any] = {}
    if curves.force_band_n is not None:
        fills["band"] = ax_f.fill_between(
            d,
            curves.force_n - curves.force_band_n,
            curves.force_n + curves.force_band_n,
            color="#e07020",
            alpha=0.25,
            lw=0,
        )
    if curves.mean_lo_n is not None and curves.mean_hi_n is not None:
        fills["mean"] = ax_f.fill_between(
            d, curves.mean_lo_n, curves.mean_hi_n, color="#4060c0", alpha=0.18, lw=0, zorder=0
        )
        (lines["mean_lo"],) = ax_f.plot(d, curves.mean_lo_n, color="#4060c0", lw=0.7, ls="--")
        (lines["mean_hi"],) = ax_f.plot(d, curves.mean_hi_n, color="#4060c0", lw=0.7, ls="--")
    (lines["hu"],) = ax_hu.plot(d, curves.hu, color="#203060", lw=1.2)
    (lines["force"],) = ax_f.plot(d, curves.force_n, color="#c04000", lw=1.2)
    finite = np.isfinite(curves.clearance_mm)
    if finite.any():
        (lines["clearance"],) = ax_c.plot(
            d[finite], curves.clearance_mm[finite], color="#207040", lw=1.2
        )
    beyond = curves.planned_depth_mm > curves.stop_depth_mm + 1e-6
    stops, planned, spans = [], [], []
    for ax in (ax_hu, ax_f, ax_c):
        stops.append(ax.axvline(curves.stop_depth_mm, color="#d02080", lw=1.4))
        planned.append(ax.axvline(curves.planned_depth_mm, color="#808080", ls=":", lw=1.0))
        spans.append(
            ax.axvspan(
                curves.stop_depth_mm, curves.planned_depth_mm, color="#d02080", alpha=0.08, lw=0
            )
        )
        planned[-1].set_visible(beyond)
        spans[-1].set_visible(beyond)
    return CurveArtists(curves_key(curves), lims, lines, fills, stops, planned, spans)


LIVE_GID = "live-depth"


def set_live_depth(fig: Figure, depth_mm: float | None) -> None:
    """Show (or with None remove) the live drill depth as a vertical cursor on every axis."""
    for ax in fig.axes:
        for line in [ln for ln in ax.lines if ln.get_gid() == LIVE_GID]:
            line.remove()
        if depth_mm is not None:
            ax.axvline(depth_mm, color="#1060ff", lw=1.6, gid=LIVE_GID)


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


def _misch_labels(fig: Figure, ax: Axes, hu_lo: float, hu_hi: float) -> None:
    """Name each Misch band at the right of the HU axes where its visible part is tall
    enough for the text; thinner bands keep their colour only (labels would overlap)."""
    px_per_hu = ax.get_position().height * fig.get_figheight() * fig.dpi / (hu_hi - hu_lo)
    text_px = TEXT_PT * fig.dpi / 72.0
    for label, lo, hi in MISCH_BANDS:
        a, b = max(lo, hu_lo), min(hi, hu_hi)
        if b <= a or (b - a) * px_per_hu < text_px:
            continue
        ax.text(
            1.005,
            (a + b) / 2.0,
            label,
            transform=ax.get_yaxis_transform(),
            fontsize=TEXT_PT,
            va="center",
        )


def fit_margins(fig: Figure) -> None:
    """Place the three axes with :data:`_MARGIN_PX` of room at the figure's current size."""
    w_px = max(fig.get_figwidth() * fig.dpi, 1.0)
    h_px = max(fig.get_figheight() * fig.dpi, 1.0)
    m = _MARGIN_PX
    left, right = m["left"] / w_px, 1.0 - m["right"] / w_px
    bottom, top = m["bottom"] / h_px, 1.0 - (m["top"] + m["gap"]) / h_px
    if not (right > left + 0.05 and top > bottom + 0.05):
        return  # a window squeezed to nothing: keep the last layout
    axes_h = (top - bottom) * h_px
    each = (axes_h - 2.0 * m["gap"]) / 3.0
    hspace = m["gap"] / each if each > 1.0 else 0.5
    fig.subplots_adjust(left=left, right=right, bottom=bottom, top=top, hspace=hspace)


def _axes(fig: Figure) -> tuple[Axes, Axes, Axes]:
    """The figure's three depth axes, emptied (created on first use)."""
    if len(fig.axes) != 3:
        fig.clear()
        fig.subplots(3, 1, sharex=True)
    fit_margins(fig)
    ax_hu, ax_f, ax_c = fig.axes
    for ax in (ax_hu, ax_f, ax_c):
        for artist in [*ax.lines, *ax.collections, *ax.patches, *ax.texts]:
            artist.remove()
        ax.set_title("")
        ax.set_title("", loc="left")
    fig._ctdrill_curves = None  # type: ignore[attr-defined]  # set again with curves
    return ax_hu, ax_f, ax_c
