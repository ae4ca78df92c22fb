"""What the report shows of each trajectory: the export's numbers, computed once.

:func:`report_entries` runs :func:`ctdrill.engine.summarize.job_summary` on every job of a
:class:`~ctdrill.engine.case.PreparedCase`: the same force series, band and summary
``ctdrill export`` writes with the same settings. Every number on the report's pages is read
from these.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from ctdrill.engine.case import PreparedCase
from ctdrill.engine.path import PathResult
from ctdrill.engine.series import ForceSeries
from ctdrill.engine.summarize import job_summary
from ctdrill.engine.summary import TrajectorySummary
from ctdrill.model.band import ForceBand

#: Most trajectories that get their own pages (a cross-section and the curves); the summary's
#: table and lines, the panorama and the 3D view cover every one. Pages are the report's cost
#: (a 64-trajectory report drew 346 pages in 6 minutes), so a plan of more trajectories is
#: reported with pages for the first ones and a note naming the others.
MAX_DRAWN_TRAJECTORIES = 12


@dataclass(frozen=True, eq=False)
class Entry:
    """One trajectory (or one drill of a drill sequence) as the report shows it.

    Attributes
    ----------
    result : its path (``plan_path``).
    series : the force time series at the export's feed and rate.
    band : the mean force's 68 % band, or None (the set gives no covariance).
    summary : its summary, as ``ctdrill export`` writes it.
    label : how the report names it: the trajectory's name, plus ``drill k of n`` in a
        sequence.
    drill_index : (k, n), 1-based, in a drill sequence; None for a single drill.
    """

    result: PathResult
    series: ForceSeries
    band: ForceBand | None
    summary: TrajectorySummary
    label: str
    drill_index: tuple[int, int] | None = None


def report_entries(case: PreparedCase) -> list[Entry]:
    """One :class:`Entry` per job of ``case``, in order."""
    in_sequence: dict[int, tuple[int, int]] = {}
    for seq, _ in case.sequences:
        for k, step in enumerate(seq.steps):
            in_sequence[id(step)] = (k + 1, len(seq.steps))
    out = []
    for job in case.jobs:
        done = job_summary(job.result, case.context, job.verdict)
        index = in_sequence.get(id(job.result))
        label = done.summary.outcome.plan
        if index is not None:
            label += f", drill {index[0]} of {index[1]}"
        out.append(Entry(job.result, done.series, done.band, done.summary, label, index))
    return out


def drawn_entries(entries: Sequence[Entry]) -> list[Entry]:
    """The entries of the first :data:`MAX_DRAWN_TRAJECTORIES` trajectories (every drill of
    a sequence with its trajectory), in order."""
    names: list[str] = []
    out = []
    for e in entries:
        name = e.result.plan.name
        if name not in names:
            if len(names) == MAX_DRAWN_TRAJECTORIES:
                continue
            names.append(name)
        out.append(e)
    return out


def undrawn_note(entries: Sequence[Entry]) -> str | None:
    """What the summary says when some trajectories get no pages of their own (else None)."""
    every = list(dict.fromkeys(e.result.plan.name for e in entries))
    if len(every) <= MAX_DRAWN_TRAJECTORIES:
        return None
    rest = every[MAX_DRAWN_TRAJECTORIES:]
    shown = ", ".join(rest[:10]) + (f" and {len(rest) - 10} more" if len(rest) > 10 else "")
    return (
        f"Cross-section and curve pages are drawn for the first {MAX_DRAWN_TRAJECTORIES} of "
        f"{len(every)} trajectories; the table and the lines cover all, the panorama and the 3D "
        f"view draw all. Without pages: {shown}. For their pages, report them from a plan "
        "that holds them (ctdrill report --plan with those files)."
    )
