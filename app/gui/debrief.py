"""The debrief of a rehearsal, headless: the session's curves to replay, what the cursor shows,
the expert session to compare with (from the trainee record), and the replay plot's drawing
on any matplotlib ``Figure`` (the window's canvas and tests use the same code)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from ctdrill.app.gui.rehearsal import RehearsalRun
from ctdrill.app.trainee.curve import ranked
from ctdrill.app.trainee.record import TraineeRecord
from ctdrill.app.trainee.session_files import SessionEntry, SessionFiles, session_entry

#: Colours: the session's drill, hand and force; the expert's lines are grey.
DRILL, HAND, FORCE, EXPERT = "#6d4c41", "#1e88e5", "#2e7d32", "#9e9e9e"


@dataclass(frozen=True, eq=False)
class Debrief:
    """An ended session: its files (as exported), its curves and its assessment.

    Attributes
    ----------
    summary_text, csv_text, table_text : ``summary.json``, ``session.csv`` and ``table.json``
        as exported; display_text: ``display.csv`` (None: the window logged no display).
    summary : the parsed summary (``assessment``, ``planned_depth_mm``, ``plan_sha256``...).
    time_s, hand_mm, drill_mm, force_n : (N,) the session's rows (hand = the master).
    """

    summary_text: str
    csv_text: str
    table_text: str
    summary: dict[str, Any]
    time_s: np.ndarray
    hand_mm: np.ndarray
    drill_mm: np.ndarray
    force_n: np.ndarray
    display_text: str | None = None

    @property
    def assessment(self) -> dict[str, Any]:
        """The summary's assessment."""
        out: dict[str, Any] = self.summary["assessment"]
        return out

    @property
    def planned_depth_mm(self) -> float:
        """The plan's depth, mm."""
        return float(self.summary["planned_depth_mm"])

    def entry(self) -> SessionEntry:
        """The session as the trainee record stores it (the hash ``ctdrill assess`` gives the
        exported folder)."""
        display = None if self.display_text is None else self.display_text.encode()
        files = SessionFiles(
            self.summary_text.encode(), self.csv_text.encode(), self.table_text.encode(), display
        )
        return session_entry(Path("window"), files)

    def index_at(self, t_s: float) -> int:
        """The last row at or before ``t_s`` (the first row before the session)."""
        return max(int(np.searchsorted(self.time_s, t_s, side="right")) - 1, 0)

    def cursor_text(self, i: int) -> str:
        """What the replay shows at row ``i``, in plain words."""
        return (
            f"at {self.time_s[i]:.2f} s: drill {self.drill_mm[i]:.2f} mm deep, your hand at "
            f"{self.hand_mm[i]:.2f} mm, the device pushing back with {self.force_n[i]:.1f} N"
        )


def debrief_of(run: RehearsalRun) -> Debrief | None:
    """The debrief of an ended run (None: nothing recorded, or no assessment)."""
    if run.assessment is None or not run.rows:
        return None
    summary_text, csv_text = run.session_files()
    rows = np.asarray([r[:4] for r in run.rows], dtype=float)
    return Debrief(
        summary_text,
        csv_text,
        run.table_text(),
        run.summary(),
        rows[:, 0],
        rows[:, 1],
        rows[:, 2],
        rows[:, 3],
        run.display_text(),
    )


def best_expert(
    record: TraineeRecord, plan_hash: str, *, exclude: str = "", mode: str | None = None
) -> tuple[dict[str, Any], dict[str, np.ndarray]] | None:
    """The best-scored expert session of the plan (and ``mode``: the same case and mode) that
    has a trace and is ranked (no device fault, attempted), and its trace (None: the record
    holds no such session)."""
    rows = record.sessions(plan_hash=plan_hash, expert=True, mode=mode)
    for row in sorted(rows, key=lambda r: -float(r["score"])):
        if row["session_hash"] == exclude or not ranked(row):
            continue
        trace = record.trace(row["session_hash"])
        if trace is not None and trace["time_s"].size:
            return row, trace
    return None


def draw_replay(
    fig: Figure,
    debrief: Debrief | None,
    *,
    cursor_s: float | None = None,
    expert: dict[str, np.ndarray] | None = None,
) -> tuple[Axes, Axes] | None:
    """Depth (drill and hand) and force against time, the expert's dashed, a cursor."""
    fig.clear()
    if debrief is None:
        fig.text(0.5, 0.5, "the debrief appears when a rehearsal ends", ha="center")
        return None
    depth_ax, force_ax = fig.subplots(2, 1, sharex=True)
    t = debrief.time_s
    depth_ax.plot(t, debrief.drill_mm, color=DRILL, lw=1.6, label="drill")
    depth_ax.plot(t, debrief.hand_mm, color=HAND, lw=1.0, label="your hand")
    force_ax.plot(t, debrief.force_n, color=FORCE, lw=0.8, label="device force")
    if expert is not None:
        depth_ax.plot(expert["time_s"], expert["drill_mm"], "--", color=EXPERT, label="expert")
        force_ax.plot(expert["time_s"], expert["force_n"], "--", color=EXPERT, lw=0.8)
    a = debrief.summary
    for value, style, label in (
        (debrief.planned_depth_mm, "--", "planned"),
        (float(a.get("max_safe_depth_mm", np.nan)), ":", "safe depth"),
    ):
        if np.isfinite(value):
            depth_ax.axhline(value, color="#37474f", ls=style, lw=1.0, label=label)
    depth_ax.invert_yaxis()
    depth_ax.set_ylabel("depth (mm)")
    depth_ax.legend(loc="lower left", fontsize=8, ncol=2)
    force_ax.set_ylabel("force (N)")
    force_ax.set_xlabel("time (s)")
    for ax in (depth_ax, force_ax):
        ax.grid(alpha=0.3)
        if cursor_s is not None:
            ax.axvline(cursor_s, color="#c62828", lw=1.2)
    fig.tight_layout()
    return depth_ax, force_ax
