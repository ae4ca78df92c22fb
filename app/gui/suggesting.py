"""What the window shows of a suggestion (``ctdrill suggest``), as pure functions: the top
feasible candidates as table rows and as 3D lines, and one line of summary."""

from __future__ import annotations

import math
from dataclasses import dataclass

from ctdrill.app.gui.scene import CandidateLine
from ctdrill.app.search.suggest import Suggestion

#: How many of the best feasible candidates the window shows.
TOP_K = 5


@dataclass(frozen=True)
class CandidateRow:
    """One shown candidate: its index in the suggestion, its rank (1 = best) and terms."""

    index: int
    rank: int
    score: float
    body_hu: float
    crest_cortical: float
    apex_cortical: float
    offset_mm: float
    tilt_deg: float
    min_clearance_mm: float


def row(s: Suggestion, index: int) -> CandidateRow:
    """Candidate ``index`` as the table shows it."""
    return CandidateRow(
        index=index,
        rank=s.rank_of(index),
        score=float(s.scores.total[index]),
        body_hu=float(s.scores.body_hu[index]),
        crest_cortical=float(s.scores.crest_cortical[index]),
        apex_cortical=float(s.scores.apex_cortical[index]),
        offset_mm=float(s.candidates.offset_mm[index]),
        tilt_deg=float(s.candidates.tilt_deg[index]),
        min_clearance_mm=float(s.min_clearance_mm[index]),
    )


def top_rows(s: Suggestion, k: int = TOP_K) -> tuple[CandidateRow, ...]:
    """The ``k`` best feasible candidates, best first (fewer when fewer are feasible)."""
    return tuple(row(s, int(i)) for i in s.order[: min(k, s.n_feasible)])


def candidate_lines(
    s: Suggestion | None, adopted: int | None, k: int = TOP_K
) -> tuple[CandidateLine, ...]:
    """The top ``k`` feasible candidates as 3D lines (none without a suggestion)."""
    if s is None:
        return ()
    c = s.candidates
    return tuple(
        CandidateLine(
            entry_lps=c.entries_lps[r.index],
            target_lps=c.targets_lps[r.index],
            rank=r.rank,
            adopted=r.index == adopted,
        )
        for r in top_rows(s, k)
    )


def summary_text(s: Suggestion) -> str:
    """How many candidates are feasible, and where the planned axis ranks."""
    head = f"{s.n_feasible} of {s.candidates.size} candidates keep every margin"
    if s.best_index is None:
        head = (
            f"no feasible candidate: none of the {s.candidates.size} axes reaches the planned "
            f"depth {s.plan.planned_depth_mm:.2f} mm keeping every margin"
        )
    score = float(s.scores.total[0])
    planned = f"score {score:.3f}" if math.isfinite(score) else "not scored"
    state = "keeps every margin" if s.feasible[0] else s.reason[0]
    return f"{head} ({s.total_s:.1f} s). Planned axis: rank {s.rank_of(0)}, {planned}, {state}."
