"""What the report shows of each trajectory: the export's numbers, computed once.

:func:`report_entries` runs :func:`ctdrill.app.export.job_summary` on every job of a
:class:`~ctdrill.app.export_run.PreparedCase`: the same force series, band and ``summary.json``
document ``ctdrill export`` writes with the same options. Every number on the report's pages is
read from these.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from ctdrill.app.export import ForceSeries, job_summary
from ctdrill.app.export_run import PreparedCase
from ctdrill.engine.path import PathResult
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
    doc : its ``summary.json`` document, as ``ctdrill export`` writes it.
    label : how the report names it: the trajectory's name, plus ``drill k of n`` in a
        sequence.
    drill_index : (k, n), 1-based, in a drill sequence; None for a single drill.
    """

    result: PathResult
    series: ForceSeries
    band: ForceBand | None
    doc: dict[str, Any]
    label: str
    drill_index: tuple[int, int] | None = None


def report_entries(
    case: PreparedCase, *, feed_mm_s: float | None, rate_hz: float, include_phi: bool
) -> list[Entry]:
    """One :class:`Entry` per job of ``case``, in order (``feed_mm_s`` None: each plan's)."""
    in_sequence: dict[int, tuple[int, int]] = {}
    for seq, _ in case.sequences:
        for k, step in enumerate(seq.steps):
            in_sequence[id(step)] = (k + 1, len(seq.steps))
    out = []
    for job in case.jobs:
        series, band, doc = job_summary(
            job.result,
            feed_mm_s=feed_mm_s,
            rate_hz=rate_hz,
            series_uid=case.volume.info.series_uid,
            patient=case.patient,
            include_phi=include_phi,
            hu_uncertainty=case.hu_uncertainty,
            grey_to_hu=case.grey_to_hu,
        )
        index = in_sequence.get(id(job.result))
        label = str(doc["plan"])
        if index is not None:
            label += f", drill {index[0]} of {index[1]}"
        out.append(Entry(job.result, series, band, doc, label, index))
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
