"""What the force figure shows, as data: force, HU (with the Misch bands) and clearance against
depth, the stop, the max safe and the planned depth on each panel.

:func:`force_figure` decides every curve, band, line, label, colour and limit once;
``force.png`` is drawn from it by a small raster renderer (:mod:`ctdrill.app.raster_plot`,
Pillow, no matplotlib import: a fresh ``ctdrill export`` of one plan would spend most of its
time importing matplotlib and building its figure) and ``ctdrill report``'s curves page by
:func:`ctdrill.app.export_plot.draw_force_figure` on matplotlib axes. Pure: no drawing here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Literal

import numpy as np

from ctdrill.engine.stop import stop_words
from ctdrill.imaging.misch import MISCH_BANDS_HU
from ctdrill.text import printable

if TYPE_CHECKING:
    from ctdrill.engine.path import PathResult
    from ctdrill.engine.series import ForceSeries
    from ctdrill.model.band import ForceBand

#: Colours of the Misch bands drawn behind the HU trace (D5 is left blank).
MISCH_COLOURS = {"D1": "#5b3a29", "D2": "#8c6239", "D3": "#c69c6d", "D4": "#e8d4b0"}
#: Colours of the landmark lines, in turn (matplotlib's default cycle, "C0".."C9").
CYCLE = (
    "#1f77b4",
    "#ff7f0e",
    "#2ca02c",
    "#d62728",
    "#9467bd",
    "#8c564b",
    "#e377c2",
    "#7f7f7f",
    "#bcbd22",
    "#17becf",
)
#: HU range the open D1 band is drawn up to.
HU_TOP = 3000.0
#: Room above the highest force for the legend, a share of the force range.
LEGEND_ROOM = 0.3
#: Envelope columns across the depth axis: at least one per pixel of the axes (~1060 px).
ENVELOPE_COLUMNS = 1200
#: Text size of the labels inside the panels (points).
SMALL_PT = 7.0

Style = Literal["-", "--", ":"]
#: Where a text's (x, y) is read: ``data`` both in data units, ``axes`` both as fractions of
#: the panel, ``xdata`` x in data units and y as a fraction, ``ydata`` the other way round.
Coords = Literal["data", "axes", "xdata", "ydata"]


@dataclass(frozen=True)
class Line:
    """A polyline (``x``, ``y`` in data units); ``label`` goes in the legend."""

    x: np.ndarray
    y: np.ndarray
    colour: str
    width_pt: float
    label: str = ""


@dataclass(frozen=True)
class Fill:
    """The area between ``lo`` and ``hi`` over ``x``; ``edge_pt`` outlines it in its colour."""

    x: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    colour: str
    alpha: float = 1.0
    edge_pt: float = 0.0
    label: str = ""


@dataclass(frozen=True)
class Rule:
    """A line across the panel: horizontal at ``y`` or vertical at ``x`` (data units)."""

    at: float
    vertical: bool
    colour: str
    width_pt: float
    style: Style = "-"


@dataclass(frozen=True)
class Span:
    """A horizontal band from ``lo`` to ``hi`` (data units) across the panel."""

    lo: float
    hi: float
    colour: str
    alpha: float


@dataclass(frozen=True)
class Text:
    """A label at (``x``, ``y``) read as ``coords``, aligned by ``ha`` / ``va``."""

    x: float
    y: float
    text: str
    coords: Coords
    size_pt: float = SMALL_PT
    colour: str = "#000000"
    ha: Literal["left", "center", "right"] = "left"
    va: Literal["bottom", "center", "top", "baseline"] = "baseline"


@dataclass(frozen=True)
class Panel:
    """One of the three stacked panels: drawn in the order spans, fills, lines, rules, texts."""

    ylabel: str
    ylim: tuple[float, float]
    spans: tuple[Span, ...] = ()
    fills: tuple[Fill, ...] = ()
    lines: tuple[Line, ...] = ()
    rules: tuple[Rule, ...] = ()
    texts: tuple[Text, ...] = ()
    legend: Literal["upper right", "upper left", ""] = ""


@dataclass(frozen=True)
class ForceFigure:
    """The three panels (force, HU, clearance) sharing the depth axis ``xlim`` (mm)."""

    title: str
    xlabel: str
    xlim: tuple[float, float]
    panels: tuple[Panel, Panel, Panel]
    legend_pt: float = field(default=SMALL_PT)


def envelope(
    x: np.ndarray, y: np.ndarray, x_lo: float, x_hi: float, columns: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Min/max decimation of a dense series for drawing: per column of ``[x_lo, x_hi]`` the
    mean ``x`` and the smallest and largest ``y`` of the points that fall in it.

    Filled between the two, it covers the pixels the full line covers when a column is no
    wider than a pixel: within a column the full line spans min..max. ``x`` must be
    non-decreasing (a drilling at constant feed); points outside ``[x_lo, x_hi]`` go to the
    end columns. Returns (x, y_min, y_max), one entry per non-empty column.
    """
    if x.shape[0] == 0 or not x_hi > x_lo:
        return x, y, y
    col = np.clip(((x - x_lo) / (x_hi - x_lo) * columns).astype(np.int64), 0, columns - 1)
    starts = np.flatnonzero(np.r_[True, col[1:] != col[:-1]])
    counts = np.diff(np.r_[starts, x.shape[0]])
    x_mid = np.add.reduceat(x, starts) / counts
    return x_mid, np.minimum.reduceat(y, starts), np.maximum.reduceat(y, starts)


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


def _misch_spans() -> tuple[tuple[Span, ...], tuple[Text, ...]]:
    spans, texts = [], []
    for name, lo, top in MISCH_BANDS_HU:
        if name not in MISCH_COLOURS:
            continue
        hi = min(top, HU_TOP)
        spans.append(Span(lo, hi, MISCH_COLOURS[name], 0.25))
        mid = (lo + min(hi, 2000.0)) / 2
        texts.append(Text(0.995, mid, name, "ydata", ha="right", va="center"))
    return tuple(spans), tuple(texts)


def _depth_rules(result: PathResult) -> tuple[Rule, ...]:
    """The stop (red), the max safe depth (orange dotted, where before the planned depth) and
    the planned depth (grey dashed)."""
    rules = [Rule(result.stop_depth_mm, True, "#d62728", 1.2)]
    if result.max_safe_depth_mm < result.planned_depth_mm + 1e-9:
        rules.append(Rule(result.max_safe_depth_mm, True, "#ff7f0e", 1.0, ":"))
    rules.append(Rule(result.planned_depth_mm, True, "#7f7f7f", 0.8, "--"))
    return tuple(rules)


def force_figure(result: PathResult, series: ForceSeries, band: ForceBand | None) -> ForceFigure:
    """The figure of one trajectory: the force (its vibration envelope, the mean and the 68 %
    band of the mean when the set gives one), the lip HU over the Misch bands, the clearance
    to each landmark with the margins, and the stop, max safe and planned depths."""
    prof = result.profile
    x_hi = result.planned_depth_mm
    rules = _depth_rules(result)
    feed = float(series.depth_mm[-1] / series.time_s[-1]) if series.time_s[-1] > 0 else 0.0
    env_x, env_lo, env_hi = envelope(series.depth_mm, series.force_n, 0.0, x_hi, ENVELOPE_COLUMNS)
    # the band bounds the mean force S0 (1 + Ke v) at its feed: drawn around that curve
    mean_n = prof.mean_force_n(feed) if band is None else band.mean_n
    fills = [Fill(env_x, env_lo, env_hi, "#1f77b4", edge_pt=0.4, label="force (with vibration)")]
    stop_text = (
        f"stop {result.stop_depth_mm:.2f} mm ({stop_words(result.stop_reason, form='code')})"
    )
    texts = [Text(result.stop_depth_mm, 1.02, stop_text, "xdata", colour="#d62728", ha="right")]
    if band is not None:
        what = "calibration" + (" + HU" if band.hu is not None else "")
        label = f"68 % band of the mean ({what})"
        fills.append(Fill(prof.depth_mm, band.lo_n, band.hi_n, "#d62728", 0.18, label=label))
    else:
        note = f"no band: {result.calibration.name} gives no covariance"
        texts.append(Text(0.99, 0.04, note, "axes", colour="#7f7f7f", ha="right", va="bottom"))
    force = Panel(
        "force (N)",
        force_limits_n(env_lo, env_hi, mean_n, band),
        fills=tuple(fills),
        lines=(Line(prof.depth_mm, mean_n, "#d62728", 1.2, "mean force S0 (1 + Ke v)"),),
        rules=rules,
        texts=tuple(texts),
        legend="upper right",
    )

    hu_max = float(np.max(prof.hu_mean))
    spans, band_names = _misch_spans()
    hu = Panel(
        "HU",
        (-1100.0, max(2000.0, hu_max + 100.0) if math.isfinite(hu_max) else 2000.0),
        spans=spans,
        lines=(
            Line(prof.depth_mm, prof.hu_mean, "#000000", 1.0, "lip-mean HU"),
            Line(result.depth_mm, result.lip.axis_hu, "#7f7f7f", 0.6, "axis HU"),
        ),
        rules=rules,
        texts=band_names,
        legend="upper left",
    )

    if result.clearance_mm.shape[1]:
        lines = tuple(
            Line(result.depth_mm, result.clearance_mm[:, j], CYCLE[j % 10], 1.0, printable(lm.name))
            for j, lm in enumerate(result.landmarks)
        )
        margins = sorted(set(result.margins_mm.tolist()))
        top = float(np.max(result.clearance_mm[0])) if result.clearance_mm.size else 10.0
        lo = min(-1.0, float(np.min(result.clearance_mm)) - 0.5)
        clearance = Panel(
            "clearance (mm)",
            (lo, max(top, 5.0) + 0.5),
            lines=lines,
            rules=tuple(Rule(m, False, "#d62728", 0.8, "--") for m in margins) + rules,
            texts=tuple(
                Text(0.0, m, f" margin {m:g} mm", "data", colour="#d62728", va="bottom")
                for m in margins
            ),
            legend="upper right",
        )
    else:
        clearance = Panel(
            "clearance (mm)",
            (0.0, 1.0),
            rules=rules,
            texts=(Text(0.5, 0.5, "no landmarks in the plan", "axes", 10.0, ha="center"),),
        )
    cal = result.calibration
    label = f"{cal.name} (ILLUSTRATIVE)" if cal.illustrative else cal.name
    return ForceFigure(
        # printable: a plan named after a file whose name is not UTF-8 must not fail the plot
        title=printable(f"{result.plan.name}: calibration {label}"),
        xlabel="tip depth from the entry (mm)",
        xlim=(0.0, x_hi),
        panels=(force, hu, clearance),
    )
