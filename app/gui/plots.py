"""Depth plots (HU with Misch bands, predicted force, clearance with the margin), drawn on any
matplotlib ``Figure``: the window's ``FigureCanvasQTAgg`` and headless tests use the same code.
"""

from __future__ import annotations

import textwrap
from dataclasses import dataclass

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from ctdrill.hu import AIR_HU
from ctdrill.imaging.misch import MISCH_BANDS_HU

#: Misch bands as drawn: the owner's (``ctdrill.imaging.misch``), open ends clipped to the
#: plotted HU range.
MISCH_BANDS: tuple[tuple[str, float, float], ...] = tuple(
    (label, max(lo, AIR_HU), min(hi, 3000.0)) for label, lo, hi in MISCH_BANDS_HU
)
_BAND_COLOURS = ("#c8d7f0", "#d4e8d0", "#f2ecc4", "#f5dcc4", "#f1d0d0")


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


def draw_depth_plots(fig: Figure, curves: DepthCurves | None, *, message: str = "") -> None:
    """Redraw ``fig`` with three stacked axes sharing depth: HU, force, clearance.

    With ``curves`` None the axes are drawn empty with ``message`` (e.g. "computing...").
    The axes are created once and reused (redrawing is then cheap enough for live updates).
    """
    ax_hu, ax_f, ax_c = _axes(fig)
    for label, lo, hi in MISCH_BANDS:
        colour = _BAND_COLOURS[[b[0] for b in MISCH_BANDS].index(label)]
        ax_hu.axhspan(lo, hi, color=colour, alpha=0.8, lw=0, zorder=0)
    ax_hu.set_ylabel("HU")
    ax_f.set_ylabel("force (N)")
    ax_c.set_ylabel("clearance (mm)")
    ax_c.set_xlabel("depth (mm)")
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
            fontsize=8,
            transform=ax_f.transAxes,
        )
        return
    d = curves.depth_mm
    ax_hu.plot(d, curves.hu, color="#203060", lw=1.2)
    hu_lo = min(-200.0, float(np.nanmin(curves.hu)) - 100.0)
    hu_hi = max(1600.0, float(np.nanmax(curves.hu)) + 100.0)
    ax_hu.set_ylim(hu_lo, hu_hi)
    for label, lo, hi in MISCH_BANDS:
        mid = (max(lo, hu_lo) + min(hi, hu_hi)) / 2.0
        if hu_lo < mid < hu_hi:
            ax_hu.text(1.005, mid, label, transform=ax_hu.get_yaxis_transform(), fontsize=7)
    if curves.force_band_n is not None:
        ax_f.fill_between(
            d,
            curves.force_n - curves.force_band_n,
            curves.force_n + curves.force_band_n,
            color="#e07020",
            alpha=0.25,
            lw=0,
        )
    if curves.mean_lo_n is not None and curves.mean_hi_n is not None:
        ax_f.fill_between(
            d, curves.mean_lo_n, curves.mean_hi_n, color="#4060c0", alpha=0.18, lw=0, zorder=0
        )
        for edge in (curves.mean_lo_n, curves.mean_hi_n):
            ax_f.plot(d, edge, color="#4060c0", lw=0.7, ls="--")
    ax_f.plot(d, curves.force_n, color="#c04000", lw=1.2)
    title = "predicted force"
    if curves.calibration:
        title += f" ({curves.calibration})"
    if curves.band_note:
        title += f"; {curves.band_note}"
    ax_f.set_title(title, fontsize=8, loc="left")
    finite = np.isfinite(curves.clearance_mm)
    if finite.any():
        ax_c.plot(d[finite], curves.clearance_mm[finite], color="#207040", lw=1.2)
        top = max(float(np.max(curves.clearance_mm[finite])), curves.margin_mm * 2.0)
        ax_c.set_ylim(min(0.0, float(np.min(curves.clearance_mm[finite]))), top * 1.05)
    else:
        ax_c.text(0.5, 0.5, "no landmarks", ha="center", va="center", transform=ax_c.transAxes)
    ax_c.axhline(curves.margin_mm, color="#d02020", ls="--", lw=1.0)
    ax_c.text(
        0.0,
        curves.margin_mm,
        f" margin {curves.margin_mm:g} mm",
        color="#d02020",
        fontsize=7,
        va="bottom",
        transform=ax_c.get_yaxis_transform(),
    )
    for ax in (ax_hu, ax_f, ax_c):
        ax.axvline(curves.stop_depth_mm, color="#d02080", lw=1.4)
        if curves.planned_depth_mm > curves.stop_depth_mm + 1e-6:
            ax.axvline(curves.planned_depth_mm, color="#808080", ls=":", lw=1.0)
            ax.axvspan(
                curves.stop_depth_mm, curves.planned_depth_mm, color="#d02080", alpha=0.08, lw=0
            )
    ax_hu.set_title(
        f"stop {curves.stop_depth_mm:.2f} mm ({curves.stop_reason}) of "
        f"{curves.planned_depth_mm:.2f} mm planned",
        fontsize=8,
        loc="left",
    )
    ax_c.set_xlim(0.0, max(float(d[-1]), curves.planned_depth_mm) * 1.02 + 1e-6)


LIVE_GID = "live-depth"


def set_live_depth(fig: Figure, depth_mm: float | None) -> None:
    """Show (or with None remove) the live drill depth as a vertical cursor on every axis."""
    for ax in fig.axes:
        for line in [ln for ln in ax.lines if ln.get_gid() == LIVE_GID]:
            line.remove()
        if depth_mm is not None:
            ax.axvline(depth_mm, color="#1060ff", lw=1.6, gid=LIVE_GID)


def _axes(fig: Figure) -> tuple[Axes, Axes, Axes]:
    """The figure's three depth axes, emptied (created on first use)."""
    if len(fig.axes) != 3:
        fig.clear()
        fig.subplots(3, 1, sharex=True)
        fig.subplots_adjust(left=0.08, right=0.965, top=0.95, bottom=0.13, hspace=0.5)
    ax_hu, ax_f, ax_c = fig.axes
    for ax in (ax_hu, ax_f, ax_c):
        for artist in [*ax.lines, *ax.collections, *ax.patches, *ax.texts]:
            artist.remove()
        ax.set_title("")
    return ax_hu, ax_f, ax_c
