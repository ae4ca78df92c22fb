"""The class dashboard (``dashboard.png`` and ``dashboard.pdf``): per exercise the histogram
of the trainees' graded scores and their learning curves, then the class's confusion matrix of
the bone-quality exercise and each trainee's share of trials named right."""

from __future__ import annotations

import io
import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ctdrill.app.classroom.class_file import ClassFile
from ctdrill.app.exercise.bone_quality import TRIAL_CLASSES

#: Most panels across.
MAX_COLUMNS = 4
_BINS = [float(v) for v in np.linspace(0.0, 100.0, 11)]


def _figure(
    cls: ClassFile,
    curves: Mapping[str, Mapping[str, Sequence[float]]],
    counts: Mapping[tuple[str, str], int],
    accuracy: Mapping[str, float | None],
) -> Any:
    from matplotlib.figure import Figure
    from matplotlib.ticker import MaxNLocator

    n = len(cls.exercises)
    cols = min(max(n, 2), MAX_COLUMNS)
    ex_rows = math.ceil(n / cols)
    fig = Figure(figsize=(4.2 * cols, 3.2 * (2 * ex_rows + 1) + 0.6), dpi=100)
    grid = fig.add_gridspec(2 * ex_rows + 1, cols)
    colours = {t: f"C{i % 10}" for i, t in enumerate(cls.trainees)}
    for i, ex in enumerate(cls.exercises):
        r, c = divmod(i, cols)
        hist = fig.add_subplot(grid[2 * r, c])
        scores = [s for t in cls.trainees for s in list(curves[ex.name][t])[: ex.attempts]]
        hist.hist(scores, bins=_BINS, color="#1565c0", edgecolor="white")
        hist.axvline(ex.pass_mark, color="#c62828", ls="--", lw=1.2, label=f"pass {ex.pass_mark:g}")
        unit = "% named right" if ex.mode == "bone-quality" else "score"
        hist.set_title(f"{ex.name}\n({ex.session_mode})", fontsize=9)
        hist.set_xlabel(f"{unit} of graded attempts", fontsize=8)
        hist.set_ylabel("attempts", fontsize=8)
        hist.set_xlim(0, 100)
        hist.yaxis.set_major_locator(MaxNLocator(integer=True))
        hist.legend(fontsize=7, loc="upper left")
        if not scores:
            hist.text(
                0.5,
                0.5,
                "no attempts yet",
                ha="center",
                va="center",
                transform=hist.transAxes,
                color="0.4",
            )
        curve = fig.add_subplot(grid[2 * r + 1, c])
        spread = 0.08 * (len(cls.trainees) - 1)
        for k, t in enumerate(cls.trainees):
            ys = list(curves[ex.name][t])
            if ys:  # each trainee's points a little apart: equal scores stay visible
                shift = (k / max(len(cls.trainees) - 1, 1) - 0.5) * spread
                xs = np.arange(1, len(ys) + 1) + shift
                curve.plot(xs, ys, "-o", ms=3, color=colours[t], label=t)
        curve.axhline(ex.pass_mark, color="#c62828", ls="--", lw=1.0)
        if ex.attempts < 50:
            curve.axvline(ex.attempts + 0.5, color="0.6", ls=":", lw=1.0)
        curve.set_ylim(-3, 105)  # a score of 0 or 100 stays a whole point
        longest = max([len(curves[ex.name][t]) for t in cls.trainees] + [1])
        curve.set_xlim(0.5, longest + 0.5)
        if longest <= 20:  # each attempt its tick (a locator gives fractions for one)
            curve.set_xticks(range(1, longest + 1))
        else:
            curve.xaxis.set_major_locator(MaxNLocator(integer=True))
        curve.set_xlabel("attempt", fontsize=8)
        curve.set_ylabel(unit, fontsize=8)
        curve.set_title("learning curves", fontsize=9)
        curve.grid(alpha=0.3)
        if any(curves[ex.name][t] for t in cls.trainees):
            curve.legend(fontsize=7, loc="lower right")
    bottom = 2 * ex_rows
    mat = fig.add_subplot(grid[bottom, 0])
    m = np.array([[counts[(t, a)] for a in TRIAL_CLASSES] for t in TRIAL_CLASSES], dtype=float)
    mat.imshow(m, cmap="Blues", vmin=0, vmax=max(1.0, float(m.max())))
    for i in range(len(TRIAL_CLASSES)):
        for j in range(len(TRIAL_CLASSES)):
            mat.text(
                j,
                i,
                f"{int(m[i, j])}",
                ha="center",
                va="center",
                color="white" if m[i, j] > 0.6 * m.max() else "black",
                fontsize=10,
            )
    mat.set_xticks(range(len(TRIAL_CLASSES)), TRIAL_CLASSES)
    mat.set_yticks(range(len(TRIAL_CLASSES)), TRIAL_CLASSES)
    mat.set_xlabel("named by the trainee", fontsize=8)
    mat.set_ylabel("true class", fontsize=8)
    total = int(m.sum())
    right = int(np.trace(m))
    mat.set_title(f"bone quality, the class: {right} of {total} named right", fontsize=9)
    bars = fig.add_subplot(grid[bottom, 1])
    names = list(cls.trainees)
    vals = [accuracy.get(t) for t in names]
    bars.bar(
        range(len(names)),
        [0.0 if v is None else v for v in vals],
        color=[colours[t] for t in names],
    )
    for k, v in enumerate(vals):
        bars.text(k, (v or 0.0) + 2, "-" if v is None else f"{v:.0f}%", ha="center", fontsize=8)
    bars.axhline(100.0 / len(TRIAL_CLASSES), color="0.5", ls=":", lw=1.0, label="chance")
    bars.set_xticks(range(len(names)), names, fontsize=8, rotation=20)
    bars.set_ylim(0, 110)
    bars.set_ylabel("% named right", fontsize=8)
    bars.set_title("bone quality, each trainee", fontsize=9)
    bars.legend(fontsize=7, loc="upper right")
    fig.suptitle(f"class {cls.name}: {len(cls.trainees)} trainees, {n} exercises", fontsize=11)
    fig.tight_layout()
    return fig


def dashboard_files(
    cls: ClassFile,
    curves: Mapping[str, Mapping[str, Sequence[float]]],
    counts: Mapping[tuple[str, str], int],
    accuracy: Mapping[str, float | None],
) -> tuple[bytes, bytes]:
    """``(PNG bytes, PDF bytes)`` of the dashboard."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    fig = _figure(cls, curves, counts, accuracy)
    FigureCanvasAgg(fig)
    png, pdf = io.BytesIO(), io.BytesIO()
    fig.savefig(png, format="png")
    fig.savefig(pdf, format="pdf", metadata={"CreationDate": None, "Creator": "ctdrill"})
    return png.getvalue(), pdf.getvalue()
