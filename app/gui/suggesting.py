"""What the window shows of a suggestion (``ctdrill suggest``), as pure functions: the top
feasible candidates as table rows and as 3D lines, and one line of summary."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

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


def distinct_mm(s: Suggestion) -> float:
    """How far apart two shown axes' entries or targets must be: the drill's diameter, mm."""
    return float(s.plan.drill.diameter_mm)


def top_rows(s: Suggestion, k: int = TOP_K) -> tuple[CandidateRow, ...]:
    """The ``k`` best distinct feasible candidates, best first (fewer when fewer are
    feasible): each next one is the best whose entry or target lies at least one drill
    diameter (:func:`distinct_mm`) from those of every axis already taken: closer, both ends
    drill largely the same bone. Ranks are those of ``candidates.csv``."""
    c = s.candidates
    limit = distinct_mm(s)
    taken: list[int] = []
    for i in s.order[: s.n_feasible]:
        j = int(i)
        if any(
            np.linalg.norm(c.entries_lps[j] - c.entries_lps[t]) < limit
            and np.linalg.norm(c.targets_lps[j] - c.targets_lps[t]) < limit
            for t in taken
        ):
            continue
        taken.append(j)
        if len(taken) == k:
            break
    return tuple(row(s, j) for j in taken)


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
            slot=slot,
        )
        for slot, r in enumerate(top_rows(s, k))
    )


def summary_text(s: Suggestion) -> str:
    """How many candidates are feasible (of those checked exactly), and where the planned
    axis ranks."""
    checked = f"{s.n_checked} checked exactly of {s.candidates.size}"
    head = f"{s.n_feasible} candidates keep every margin and bone wall ({checked})"
    if s.best_index is None:
        head = f"no feasible candidate: none keeps every margin and bone wall ({checked})"
    score = float(s.scores.total[0])
    planned = f"score {score:.3f}" if math.isfinite(score) else "not scored"
    state = "keeps every margin and bone wall" if s.feasible[0] else s.reason[0]
    return f"{head} ({s.total_s:.1f} s). Planned axis: rank {s.rank_of(0)}, {planned}, {state}."
