"""``force.png``: force, HU (with Misch bands) and clearance against depth (matplotlib Agg)."""

from __future__ import annotations

from pathlib import Path
from typing import IO, TYPE_CHECKING

import numpy as np

from ctdrill.app.pipeline import PathResult
from ctdrill.app.records import printable
from ctdrill.imaging.misch import MISCH_BANDS_HU

if TYPE_CHECKING:
    from ctdrill.app.export import ForceSeries

#: Colours of the Misch bands drawn behind the HU trace (D5 is left blank).
_MISCH_COLOURS = {"D1": "#5b3a29", "D2": "#8c6239", "D3": "#c69c6d", "D4": "#e8d4b0"}
#: HU range the open D1 band is drawn up to.
_HU_TOP = 3000.0


def force_png(result: PathResult, series: ForceSeries, path: Path | IO[bytes]) -> None:
    """Draw the export figure into ``path`` (PNG, 1200x1000 px): a file or a binary stream."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure

    fig = Figure(figsize=(8.0, 6.67), dpi=150)
    ax_f, ax_h, ax_c = fig.subplots(3, 1, sharex=True)
    prof = result.profile
    feed = float(series.depth_mm[-1] / series.time_s[-1]) if series.time_s[-1] > 0 else 0.0
    ax_f.plot(
        series.depth_mm, series.force_n, lw=0.4, color="#1f77b4", label="force (with vibration)"
    )
    ax_f.plot(
        prof.depth_mm,
        prof.mean_force_n(feed),
        lw=1.2,
        color="#d62728",
        label="mean force S0 (1 + Ke v)",
    )
    ax_f.set_ylabel("force (N)")
    ax_f.legend(loc="upper left", fontsize=7)

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
    ax_h.plot(prof.depth_mm, prof.hu_mean, color="k", lw=1.0, label="lip-mean HU")
    ax_h.plot(result.depth_mm, result.lip.axis_hu, color="#7f7f7f", lw=0.6, label="axis HU")
    hu_hi = max(2000.0, float(np.max(prof.hu_mean)) + 100.0)
    ax_h.set_ylim(-1100.0, hu_hi)
    ax_h.set_ylabel("HU")
    ax_h.legend(loc="upper left", fontsize=7)

    if result.clearance_mm.shape[1]:
        for j, lm in enumerate(result.landmarks):
            ax_c.plot(result.depth_mm, result.clearance_mm[:, j], lw=1.0, label=printable(lm.name))
        for m in sorted(set(result.margins_mm.tolist())):
            ax_c.axhline(m, color="#d62728", ls="--", lw=0.8)
            ax_c.text(0.0, m, f" margin {m:g} mm", va="bottom", fontsize=7, color="#d62728")
        ax_c.legend(loc="upper right", fontsize=7)
        top = float(np.max(result.clearance_mm[0])) if result.clearance_mm.size else 10.0
        ax_c.set_ylim(min(-1.0, float(np.min(result.clearance_mm)) - 0.5), max(top, 5.0) + 0.5)
    else:
        ax_c.text(0.5, 0.5, "no landmarks in the plan", transform=ax_c.transAxes, ha="center")
    ax_c.set_ylabel("clearance (mm)")
    ax_c.set_xlabel("tip depth from the entry (mm)")

    for ax in (ax_f, ax_h, ax_c):
        ax.axvline(result.stop_depth_mm, color="#d62728", lw=1.2)
        if result.max_safe_depth_mm < result.planned_depth_mm + 1e-9:
            ax.axvline(result.max_safe_depth_mm, color="#ff7f0e", ls=":", lw=1.0)
        ax.axvline(result.planned_depth_mm, color="#7f7f7f", ls="--", lw=0.8)
        ax.grid(alpha=0.3)
    ax_f.text(
        result.stop_depth_mm,
        1.02,
        f"stop {result.stop_depth_mm:.2f} mm ({result.stop_reason})",
        transform=ax_f.get_xaxis_transform(),
        ha="right",
        fontsize=7,
        color="#d62728",
    )
    cal = result.calibration
    label = f"{cal.name} (ILLUSTRATIVE)" if cal.illustrative else cal.name
    # printable: a plan named after a file whose name is not UTF-8 must not fail the plot
    fig.suptitle(printable(f"{result.plan.name}: calibration {label}"), fontsize=9)
    ax_c.set_xlim(0.0, result.planned_depth_mm)
    fig.tight_layout()
    fig.savefig(path, format="png")
