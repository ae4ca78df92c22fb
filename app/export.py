"""Headless export of a planned osteotomy: force/HU/clearance tables, summary and a plot.

Files per trajectory (DESIGN.md section 4): ``force.csv`` (the time series at constant feed
until the stop depth), ``profile.csv`` (per depth), ``summary.json`` and ``force.png``. The
calibration set is named in every file (a ``calibration`` column in the CSVs, a field in the
summary, the plot title), so an illustrative calibration is never mistaken for a measured one.
No patient identifier is written unless asked (``include_phi``). What they hold is computed by
the engine (:func:`ctdrill.engine.summarize.job_summary`: the force series, the band, the
typed summary); this module writes it.

Everything is computed before anything is written, and files are written into a staging
folder beside the output that then replaces the output folder whole
(:mod:`ctdrill.app.records`): a kill, a full disk or an error leaves the previous export as it
was, never a mix of old and new files.
"""

from __future__ import annotations

import io
import json
import math
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

import numpy as np

from ctdrill.app.csv_cells import csv_text, text_cell
from ctdrill.app.fixedtext import fixed_csv
from ctdrill.engine.band import BAND_COLUMNS
from ctdrill.engine.case import ExportJob
from ctdrill.engine.series import ForceSeries
from ctdrill.engine.summarize import CaseContext, JobSummary, job_summary
from ctdrill.imaging.misch import misch_class

FORCE_COLUMNS = ("time_s", "depth_mm", "hu", "s_t", "force_n", "clearance_mm", "calibration")
PROFILE_COLUMNS = (
    "depth_mm",
    "hu",
    "s_t",
    "s0_n",
    "s1_n",
    "s2_n",
    "clearance_mm",
    "misch",
    "calibration",
)


def force_csv(series: ForceSeries, calibration: str) -> str:
    """``force.csv`` text: ``time_s, depth_mm, hu, s_t, force_n`` then extras.

    Formatted whole columns at a time (:func:`ctdrill.app.fixedtext.fixed_csv`), byte for
    byte what ``csv.writer`` writes of ``"%.6f"``-style strings (``inf`` and ``nan`` as
    Python writes them).
    """
    columns = [
        (series.time_s, 6),
        (series.depth_mm, 6),
        (series.hu, 2),
        (series.s_t, 5),
        (series.force_n, 5),
        (series.clearance_mm, 4),
    ]
    return fixed_csv(FORCE_COLUMNS, columns, tail=text_cell(calibration))


def _fmt(values: np.ndarray, digits: int) -> list[str]:
    return [f"{v:.{digits}f}" if math.isfinite(v) else repr(float(v)) for v in values.tolist()]


def profile_csv(job: JobSummary) -> str:
    """``profile.csv`` text: one row per depth of the profile grid; then ``mean_force_n``
    (``S0 (1 + Ke v)`` at the export's feed, always), ``mean_force_lo_n`` and
    ``mean_force_hi_n`` (its 68 % band; empty when the set gives no band: docs/export.md)."""
    result, band = job.result, job.band
    prof = result.profile
    feed = job.summary.outcome.feed_mm_s
    sk = [prof.sk_n[k] if k < prof.sk_n.shape[0] else np.zeros_like(prof.s0_n) for k in (0, 1)]
    empty = [""] * len(prof.depth_mm)
    mean = prof.mean_force_n(feed) if band is None else band.mean_n
    cols = [
        _fmt(prof.depth_mm, 4),
        _fmt(prof.hu_mean, 2),
        _fmt(prof.s_t, 5),
        _fmt(prof.s0_n, 5),
        _fmt(sk[0], 5),
        _fmt(sk[1], 5),
        _fmt(result.min_clearance_per_depth_mm, 4),
        misch_class(prof.hu_mean).tolist(),
        [text_cell(prof.calibration)] * len(prof.depth_mm),
        _fmt(mean, 5),
        *([empty] * 2 if band is None else [_fmt(band.lo_n, 5), _fmt(band.hi_n, 5)]),
    ]
    header = PROFILE_COLUMNS + BAND_COLUMNS
    return csv_text(header, zip(*cols, strict=True), text_columns={"misch", "calibration"})


def summary_json(summary: object) -> str:
    """A summary's ``summary.json`` text (a record with ``to_json``)."""
    doc = summary.to_json()  # type: ignore[attr-defined]
    return json.dumps(doc, indent=2, allow_nan=False) + "\n"


def job_files(job: JobSummary, *, plot: bool) -> dict[str, bytes | str]:
    """One job's files by name: ``force.csv``, ``profile.csv``, ``summary.json`` and, with
    ``plot``, ``force.png``."""
    from ctdrill.app.export_plot import force_png

    cal = job.result.calibration.name
    outputs: dict[str, bytes | str] = {
        "force.csv": force_csv(job.series, cal),
        "profile.csv": profile_csv(job),
        "summary.json": summary_json(job.summary),
    }
    if plot:
        png = io.BytesIO()
        force_png(job.result, job.series, png, band=job.band)
        outputs["force.png"] = png.getvalue()
    return outputs


def write_exports(
    jobs: Sequence[ExportJob],
    out_dir: Path,
    context: CaseContext,
    *,
    files: bool = True,
    table: bool = False,
    progress: Callable[[int, int, str], None] | None = None,
    extra_files: Mapping[str, bytes | str] | None = None,
    done: Sequence[JobSummary] | None = None,
) -> list[Path]:
    """Write every job's four files into a staging folder swapped in for ``out_dir`` whole.

    ``context`` holds the settings (feed, rate, PHI, plot: ``plot`` False leaves out
    ``force.png``, each summary saying ``"plot": false``), the series and the HU error
    every summary shares. ``files`` False writes no per-job files; ``table`` writes
    ``trajectories.csv`` (:mod:`ctdrill.app.export_table`), one row per job. ``extra_files``
    (relative path -> content) are written in the same swap (the demo's marker, the GUI's
    session record, a sequence's listing); their names may be present when the folder is
    next replaced. ``out_dir`` is replaced as a whole
    (:func:`ctdrill.app.records.atomic_output_dir`): a kill, a full disk or an error leaves
    the previous export exactly as it was; a folder holding other files is refused. Returns
    the written paths (under ``out_dir``). ``done`` holds the jobs' summaries when the
    caller computed them already (one per job, in order).
    """
    from ctdrill.app.export_table import TABLE_NAME, table_csv, table_row
    from ctdrill.app.records import OUTPUT_NAMES, atomic_output_dir, write_file

    out_dir = Path(out_dir)
    relative: list[Path] = []
    rows: list[dict[str, str]] = []
    extra = dict(extra_files or {})
    owned = OUTPUT_NAMES | {Path(rel).name for rel in extra}
    with atomic_output_dir(out_dir, what="--out", owned_names=owned) as staging:
        for n, job in enumerate(jobs):
            if progress is not None:
                progress(n, len(jobs), job.result.plan.name)
            one = job_summary(job.result, context, job.verdict) if done is None else done[n]
            if table:
                rows.append(table_row(one.summary, job.subdir if files else ""))
            if not files:
                continue
            target = staging / job.subdir
            target.mkdir(parents=True, exist_ok=True)
            for name, data in job_files(one, plot=context.settings.plot).items():
                write_file(target / name, data)
                relative.append(Path(job.subdir) / name)
        if table:
            write_file(staging / TABLE_NAME, table_csv(rows))
            relative.append(Path(TABLE_NAME))
        for rel, data in extra.items():
            (staging / rel).parent.mkdir(parents=True, exist_ok=True)
            write_file(staging / rel, data)
            relative.append(Path(rel))
        if progress is not None:
            progress(len(jobs), len(jobs), "done")
    return [out_dir / rel for rel in sorted(relative)]
