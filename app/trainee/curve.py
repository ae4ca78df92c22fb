"""A trainee's learning curve and percentiles against the experts (``ctdrill assess --out``).

Experts are compared on the same case **and mode** (the plan's hash and ``guarded``, ``exam``
or an exercise's level): an exam session is never ranked among guarded ones. Sessions a device
or its link ended (``device_fault``) and sessions that never reached the goal region
(``attempted`` false) are reported apart: listed in the curve, never ranked, never a peer.

``learning_curve.csv``: one row per session of the trainee in time order
(:data:`CURVE_COLUMNS`): the score, every assessment metric, and the score's percentile among
the expert sessions of the same case and mode. ``percentiles.csv``: for the trainee's latest
ranked session on each case and mode, every metric's percentile among those expert sessions and
the share of them it did better than (:data:`PERCENTILE_COLUMNS`; ``reads``: "better than 62 %
of the experts on this case and mode"). ``learning_curve.png``: the score and the overshoot per
session, with the experts' scores.

A percentile is the mid-rank share of expert values below the trainee's, 0-100 (ties count
half): 50 is the experts' median, whichever way is better for the metric. ``better_than_pct``
turns it the metric's better way (:data:`BETTER`): a lower overshoot, a smaller depth error.
"""

from __future__ import annotations

import io
from collections.abc import Collection, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ctdrill.app.csv_cells import csv_text
from ctdrill.app.records import atomic_output_dir, write_file
from ctdrill.app.trainee.record import RecordError, TraineeRecord, normal_trainee
from ctdrill.haptics.assessment import ASSESSMENT_FIELDS

METRICS = tuple(f for f in ASSESSMENT_FIELDS if f != "score")
CURVE_COLUMNS = (
    "session",
    "recorded_at",
    "session_hash",
    "plan_hash",
    "mode",
    "exam",
    "device_fault",
    "ranked",
    "score",
    *METRICS,
    "expert_sessions",
    "score_expert_percentile",
)
PERCENTILE_COLUMNS = (
    "plan_hash",
    "mode",
    "session_hash",
    "metric",
    "value",
    "expert_sessions",
    "expert_median",
    "percentile",
    "better_than_pct",
    "reads",
)
#: Which way is better for each metric: ``high``, ``low``, ``small`` (closest to 0) or None
#: (neither: a push's size, how fast the goal came).
BETTER: dict[str, str | None] = {
    "score": "high",
    "depth_error_mm": "small",
    "overshoot_mm": "low",
    "breach": "low",
    "time_in_margin_s": "low",
    "canal_entered": "low",
    "peak_hand_force_n": None,
    "mean_hand_force_n": None,
    "time_to_planned_s": None,
    "feed_cv": None,
    "reaction_ms": "low",
    "wall_contacts": "low",
    "peak_wall_force_n": "low",
    "goal_depth_mm": None,
    "attempted": "high",
    "hand_force_cv": "low",
    "plunge_mm": "low",
    "wall_press_s": "low",
    "wall_overrun_mm": "low",
    "display_lag_ms": None,
    "display_lagged": None,
}
CURVE_FILES = frozenset({"learning_curve.csv", "learning_curve.png", "percentiles.csv"})


def percentile(value: float, others: Sequence[float]) -> float | None:
    """Mid-rank percentile of ``value`` among ``others``, 0-100 (None without others)."""
    if not others:
        return None
    arr = np.asarray(others, dtype=float)
    below = float(np.sum(arr < value)) + 0.5 * float(np.sum(arr == value))
    return round(100.0 * below / arr.size, 1)


def _number(value: Any) -> float | None:
    if value is None:
        return None
    return float(value)


def _cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "1" if value else "0"
    return str(value)


def _csv(columns: Sequence[str], rows: Sequence[Mapping[str, Any]]) -> str:
    """Through the one CSV writer: a trainee's or a plan's name that starts like a formula
    (``=HYPERLINK(...)``) is written quoted, never run by a spreadsheet."""
    return csv_text(columns, [[_cell(r.get(c)) for c in columns] for r in rows])


def ranked(row: Mapping[str, Any]) -> bool:
    """A session that is ranked and plotted among its peers: not ended by the device or its
    link, and it reached the goal region (older records: unknown counts as yes)."""
    return not row.get("device_fault") and row.get("attempted") is not False


def better_than(metric: str, value: float, others: Sequence[float]) -> float | None:
    """Share of ``others`` that ``value`` is better than, 0-100 (ties count half; None
    without others or when the metric has no better way)."""
    way = BETTER.get(metric)
    if way is None or not others:
        return None
    if way == "small":
        value, others = abs(value), [abs(o) for o in others]
    pct = percentile(value, others)
    if pct is None:
        return None
    return pct if way == "high" else round(100.0 - pct, 1)


def _mode(row: Mapping[str, Any]) -> str:
    mode = row.get("mode")
    if isinstance(mode, str) and mode:
        return mode
    return "exam" if row.get("exam") else "guarded"


def learning_curve(
    record: TraineeRecord, trainee: str, *, experts: Collection[str] | None = None
) -> tuple[list[dict[str, Any]], list[dict[str, Any]], dict[tuple[str, str], list[dict[str, Any]]]]:
    """``(curve rows, percentile rows, expert sessions by (plan, mode))`` of ``trainee``;
    the experts are the sessions of the trainees ``experts`` names (a class file's roster),
    or without it the sessions stored as an expert's.

    Raises
    ------
    RecordError
        The record holds no session of ``trainee``.
    """
    sessions = record.sessions(trainee=trainee)
    if not sessions:
        raise RecordError(f"--trainee {trainee!r}: no session of this trainee in {record.path}")
    peers_of: dict[tuple[str, str], list[dict[str, Any]]] = {}
    names = None if experts is None else {normal_trainee(e) for e in experts}
    for plan in {s["plan_hash"] for s in sessions}:
        rows = record.sessions(plan_hash=plan, expert=True if names is None else None)
        for e in rows:
            if ranked(e) and (names is None or e["trainee"] in names):
                peers_of.setdefault((plan, _mode(e)), []).append(e)
    experts_by = peers_of
    curve = []
    for i, s in enumerate(sessions, start=1):
        key = (s["plan_hash"], _mode(s))
        peers = [
            e["score"] for e in experts_by.get(key, []) if e["session_hash"] != s["session_hash"]
        ]
        row = {c: s.get(c) for c in CURVE_COLUMNS}
        row.update(
            session=i,
            mode=key[1],
            ranked=ranked(s),
            expert_sessions=len(peers),
            score_expert_percentile=percentile(s["score"], peers) if ranked(s) else None,
        )
        curve.append(row)
    latest = {(s["plan_hash"], _mode(s)): s for s in sessions if ranked(s)}
    pct = []
    for key, s in latest.items():
        peers = [e for e in experts_by.get(key, []) if e["session_hash"] != s["session_hash"]]
        for metric in ("score", *METRICS):
            value = _number(s[metric])
            values = [v for v in (_number(e[metric]) for e in peers) if v is not None]
            better = None if value is None else better_than(metric, value, values)
            pct.append(
                {
                    "plan_hash": key[0],
                    "mode": key[1],
                    "session_hash": s["session_hash"],
                    "metric": metric,
                    "value": s[metric],
                    "expert_sessions": len(values),
                    "expert_median": round(float(np.median(values)), 4) if values else None,
                    "percentile": None if value is None else percentile(value, values),
                    "better_than_pct": better,
                    "reads": None
                    if better is None
                    else f"better than {better:g} % of the experts on this case and mode",
                }
            )
    return curve, pct, experts_by


def curve_png(
    curve: Sequence[Mapping[str, Any]],
    experts: Mapping[tuple[str, str], Sequence[Mapping[str, Any]]],
    trainee: str,
) -> bytes:
    """``learning_curve.png``: score (breaching sessions in red, sessions not ranked as grey
    crosses, the experts' scores of the same cases and modes as a grey band) and overshoot
    per session; sessions a device fault ended are left out."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(8.0, 5.5), dpi=100)
    FigureCanvasAgg(fig)
    top, bottom = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [2, 1]})
    curve = [r for r in curve if not r.get("device_fault")] or list(curve)
    n = np.array([r["session"] for r in curve])
    score = np.array([float(r["score"]) for r in curve])
    breach = np.array([bool(r["breach"]) for r in curve])
    apart = np.array([not r["ranked"] for r in curve])
    expert_scores = [float(e["score"]) for plan in experts.values() for e in plan]
    if expert_scores:
        lo, hi = min(expert_scores), max(expert_scores)
        if hi > lo:
            top.axhspan(lo, hi, color="0.88", label="experts' range")
        top.axhline(
            float(np.median(expert_scores)),
            color="0.45",
            lw=1.2,
            ls="--",
            label=f"experts' median ({len(expert_scores)} session"
            f"{'' if len(expert_scores) == 1 else 's'})",
        )
    top.plot(n[~apart], score[~apart], "-", color="#1565c0", lw=1.5)
    kept = ~breach & ~apart
    top.plot(n[kept], score[kept], "o", color="#1565c0", label="kept the margin")
    if apart.any():
        top.plot(n[apart], score[apart], "x", color="0.5", label="not ranked (not attempted)")
    if breach.any():
        top.plot(n[breach], score[breach], "o", color="#c62828", label="breached the margin")
    top.set_ylim(0, 100)
    top.set_ylabel("score (0-100)")
    top.set_title(f"learning curve of {trainee}")
    top.legend(loc="best", fontsize=8)  # clear of the sessions' points where it can be
    top.grid(alpha=0.3)
    over = [float(r["overshoot_mm"]) for r in curve]
    bottom.bar(n, over, color="#c62828", width=0.6)
    bottom.set_ylim(0.0, max(1.0, 1.15 * max(over)))
    bottom.set_ylabel("overshoot (mm)")
    bottom.set_xlabel("session")
    bottom.set_xticks(n)
    bottom.grid(alpha=0.3)
    fig.tight_layout()
    out = io.BytesIO()
    fig.savefig(out, format="png")
    return out.getvalue()


def write_learning_curve(
    record: TraineeRecord, trainee: str, out: Path, *, experts: Collection[str] | None = None
) -> list[Path]:
    """Write ``learning_curve.csv``, ``learning_curve.png`` and ``percentiles.csv`` into
    ``out`` (the folder replaced whole; ``experts``: :func:`learning_curve`); returns the
    files."""
    curve, pct, experts_by = learning_curve(record, trainee, experts=experts)
    with atomic_output_dir(out, owned_names=CURVE_FILES) as stage:
        write_file(stage / "learning_curve.csv", _csv(CURVE_COLUMNS, curve))
        write_file(stage / "percentiles.csv", _csv(PERCENTILE_COLUMNS, pct))
        write_file(stage / "learning_curve.png", curve_png(curve, experts_by, trainee))
    return [out / name for name in sorted(CURVE_FILES)]
