"""Peers of the export's writers: the straightforward way, as ctdrill wrote them before issue 17.

* :func:`peer_force_csv`: ``csv.writer`` over ``"%.Nf"``-formatted strings, one float at a
  time (the output ctdrill's ``force_csv`` must equal byte for byte);
* :func:`peer_force_png`: a fresh matplotlib ``Figure`` per trajectory, ``tight_layout``,
  the full 1 kHz force line, ``savefig`` through Pillow's PNG encoder at its defaults.
"""

from __future__ import annotations

import csv
import io
from typing import IO

from ctdrill.app.export import FORCE_COLUMNS
from ctdrill.engine.path import PathResult
from ctdrill.engine.series import ForceSeries
from ctdrill.imaging.misch import MISCH_BANDS_HU

_MISCH_COLOURS = {"D1": "#5b3a29", "D2": "#8c6239", "D3": "#c69c6d", "D4": "#e8d4b0"}


def peer_force_csv(series: ForceSeries, calibration: str) -> str:
    """``force.csv`` one float at a time."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(FORCE_COLUMNS)
    cols = [
        [f"{v:.6f}" for v in series.time_s.tolist()],
        [f"{v:.6f}" for v in series.depth_mm.tolist()],
        [f"{v:.2f}" for v in series.hu.tolist()],
        [f"{v:.5f}" for v in series.s_t.tolist()],
        [f"{v:.5f}" for v in series.force_n.tolist()],
        [f"{v:.4f}" for v in series.clearance_mm.tolist()],
        [calibration] * len(series.time_s),
    ]
    w.writerows(zip(*cols, strict=True))
    return buf.getvalue()


def peer_force_png(result: PathResult, series: ForceSeries, out: IO[bytes]) -> None:
    """The same three panels, drawn the straightforward way (a new figure every time)."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure

    fig = Figure(figsize=(8.0, 6.67), dpi=150)
    ax_f, ax_h, ax_c = fig.subplots(3, 1, sharex=True)
    prof = result.profile
    feed = float(series.depth_mm[-1] / series.time_s[-1]) if series.time_s[-1] > 0 else 0.0
    ax_f.plot(series.depth_mm, series.force_n, lw=0.4, label="force (with vibration)")
    ax_f.plot(prof.depth_mm, prof.mean_force_n(feed), lw=1.2, label="mean force")
    ax_f.set_ylabel("force (N)")
    ax_f.legend(loc="upper left", fontsize=7)
    for name, lo, top in MISCH_BANDS_HU:
        if name in _MISCH_COLOURS:
            ax_h.axhspan(lo, min(top, 3000.0), color=_MISCH_COLOURS[name], alpha=0.25, lw=0)
            ax_h.text(0.995, lo, name, transform=ax_h.get_yaxis_transform(), fontsize=7)
    ax_h.plot(prof.depth_mm, prof.hu_mean, color="k", lw=1.0, label="lip-mean HU")
    ax_h.plot(result.depth_mm, result.lip.axis_hu, lw=0.6, label="axis HU")
    ax_h.set_ylabel("HU")
    ax_h.legend(loc="upper left", fontsize=7)
    for j, lm in enumerate(result.landmarks):
        ax_c.plot(result.depth_mm, result.clearance_mm[:, j], lw=1.0, label=lm.name)
    for m in sorted(set(result.margins_mm.tolist())):
        ax_c.axhline(m, color="#d62728", ls="--", lw=0.8)
        ax_c.text(0.0, m, f" margin {m:g} mm", fontsize=7)
    ax_c.set_ylabel("clearance (mm)")
    ax_c.set_xlabel("tip depth from the entry (mm)")
    for ax in (ax_f, ax_h, ax_c):
        ax.axvline(result.stop_depth_mm, color="#d62728", lw=1.2)
        ax.axvline(result.planned_depth_mm, color="#7f7f7f", ls="--", lw=0.8)
        ax.grid(alpha=0.3)
    ax_f.text(result.stop_depth_mm, 1.02, "stop", transform=ax_f.get_xaxis_transform())
    fig.suptitle(f"{result.plan.name}: calibration {result.calibration.name}", fontsize=9)
    ax_c.set_xlim(0.0, result.planned_depth_mm)
    fig.tight_layout()
    fig.savefig(out, format="png")
