"""What the report shows of each trajectory: the export's numbers, computed once.

:func:`report_entries` runs :func:`ctdrill.app.export.job_summary` on every job of a
:class:`~ctdrill.app.export_run.PreparedCase`: the same force series, band and ``summary.json``
document ``ctdrill export`` writes with the same options. Every number on the report's pages is
read from these.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ctdrill.app.export import ForceSeries, job_summary
from ctdrill.app.export_run import PreparedCase
from ctdrill.app.pipeline import PathResult
from ctdrill.model.band import ForceBand


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
