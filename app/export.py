"""Headless export of a planned osteotomy: force/HU/clearance tables, summary and a plot.

Files per trajectory (DESIGN.md section 4): ``force.csv`` (the time series at constant feed
until the stop depth), ``profile.csv`` (per depth), ``summary.json`` and ``force.png``. The
calibration set is named in every file (a ``calibration`` column in the CSVs, a field in the
summary, the plot title), so an illustrative calibration is never mistaken for a measured one.
No patient identifier is written unless asked (``include_phi``).

Everything is computed before anything is written, and files are written into a staging
folder beside the output that then replaces the output folder whole
(:mod:`ctdrill.app.records`): a kill, a full disk or an error leaves the previous export as it
was, never a mix of old and new files.
"""

from __future__ import annotations

import csv
import io
import json
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ctdrill.app.calibration_info import calibration_fields, calibration_line
from ctdrill.app.csv_cells import text_cell
from ctdrill.app.errors import AppInputError
from ctdrill.app.export_band import BAND_COLUMNS, band_line, band_summary, path_band
from ctdrill.app.export_defaults import DEFAULT_RATE_HZ as DEFAULT_RATE_HZ
from ctdrill.app.export_fields import hu_grading, implant_json, interpolated_gaps_json
from ctdrill.app.fixedtext import fixed_csv
from ctdrill.app.grey_option import grey_line
from ctdrill.app.records import printable
from ctdrill.app.text_progress import TextProgress as TextProgress
from ctdrill.engine.path import PathResult
from ctdrill.imaging.misch import misch_class
from ctdrill.model.band import ForceBand, HuUncertainty
from ctdrill.model.profile import force_series_n
from ctdrill.numtext import number_text

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


class ExportInputError(AppInputError):
    """Bad export options (feed, rate, output folder)."""


@dataclass(frozen=True)
class ForceSeries:
    """The force time series at constant feed, arrays of shape (T,)."""

    time_s: np.ndarray
    depth_mm: np.ndarray
    hu: np.ndarray
    s_t: np.ndarray
    force_n: np.ndarray
    clearance_mm: np.ndarray


#: Most rows of a force.csv (at 1000 Hz, 14 hours of drilling).
MAX_FORCE_SAMPLES = 50_000_000


def force_time_series(
    result: PathResult, *, feed_mm_s: float, rate_hz: float, feed_option: bool = False
) -> ForceSeries:
    """Constant-feed time series from depth 0 to the stop depth.

    Parameters
    ----------
    result : the path.
    feed_mm_s : feed, mm/s (> 0).
    rate_hz : sample rate, Hz (> 0).
    feed_option : the feed is ``--feed-mm-s``'s (messages name it), not the plan's.

    Returns
    -------
    ForceSeries with ``time_s = i / rate_hz``, ``depth_mm = feed * time_s`` <= stop depth.
    """
    _check_positive(feed_mm_s, "--feed-mm-s (feed_mm_s)")
    _check_positive(rate_hz, "--rate-hz")
    samples = result.stop_depth_mm / feed_mm_s * rate_hz
    if not samples < MAX_FORCE_SAMPLES:
        plan = result.plan
        whose = "--feed-mm-s" if feed_option else f"plan {plan.name!r}: feed_mm_s"
        raise ExportInputError(
            f"{whose} {number_text(feed_mm_s)} mm/s at --rate-hz {number_text(rate_hz)} gives "
            f"{number_text(samples, 3)} force.csv samples to the stop at "
            f"{number_text(result.stop_depth_mm, 4)} mm, more than the {MAX_FORCE_SAMPLES} "
            "accepted; give a feed in mm/s (0.4 is typical) or lower --rate-hz"
        )
    n = math.floor(samples + 1e-9) + 1
    t = np.arange(n, dtype=np.float64) / rate_hz
    x = np.minimum(feed_mm_s * t, result.stop_depth_mm)
    prof = result.profile
    return ForceSeries(
        time_s=t,
        depth_mm=x,
        hu=np.interp(x, prof.depth_mm, prof.hu_mean),
        s_t=np.interp(x, prof.depth_mm, prof.s_t),
        force_n=force_series_n(prof, x, feed_mm_s, t),
        clearance_mm=np.interp(x, result.depth_mm, result.min_clearance_per_depth_mm),
    )


def _check_positive(value: float, name: str) -> None:
    if not (math.isfinite(value) and value > 0.0):
        raise ExportInputError(f"{name} must be a positive number, got {value!r}")


def _fmt(values: np.ndarray, digits: int) -> list[str]:
    return [f"{v:.{digits}f}" if math.isfinite(v) else repr(float(v)) for v in values.tolist()]


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


def profile_csv(result: PathResult, band: ForceBand | None = None) -> str:
    """``profile.csv`` text: one row per depth of the profile grid; then ``mean_force_n``,
    ``s0_lo_n``, ``s0_hi_n`` (the mean force at the band's feed and its 68 % band; empty
    without a band: docs/export.md)."""
    prof = result.profile
    sk = [prof.sk_n[k] if k < prof.sk_n.shape[0] else np.zeros_like(prof.s0_n) for k in (0, 1)]
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(PROFILE_COLUMNS + BAND_COLUMNS)
    empty = [""] * len(prof.depth_mm)
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
        *(
            [empty] * 3
            if band is None
            else [_fmt(band.mean_n, 5), _fmt(band.lo_n, 5), _fmt(band.hi_n, 5)]
        ),
    ]
    w.writerows(zip(*cols, strict=True))
    return buf.getvalue()


def _num(v: float | None, digits: int = 4) -> float | None:
    if v is None or not math.isfinite(v):
        return None
    return round(float(v), digits)


def summary(
    result: PathResult,
    series: ForceSeries,
    *,
    feed_mm_s: float,
    rate_hz: float,
    series_uid: str,
    patient: dict[str, str] | None = None,
    include_phi: bool = False,
    band: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """The ``summary.json`` document (no patient identifiers unless ``patient`` is given);
    ``band``: :func:`ctdrill.app.export_band.band_summary`'s fields (and ``grey_to_hu``).

    ``series_uid`` is written as the SHA-256 of the SeriesInstanceUID (as plans record it),
    the raw UID only with ``include_phi``; ``series_uid_sha256`` always.
    """
    from ctdrill.imaging.dicom.identity import series_identity

    plan = result.plan
    cal = result.calibration
    lms = []
    for j, lm in enumerate(result.landmarks):
        lms.append(
            {
                "name": printable(lm.name),
                "kind": lm.kind,
                "radius_mm": lm.radius_mm,
                "margin_mm": float(result.margins_mm[j]),
                "clearance_at_stop_mm": _num(float(result.stop_clearance_mm[j])),
            }
        )
    binding = result.binding_landmark
    prof = result.profile
    doc: dict[str, Any] = {
        "format": "ctdrill-export/1",
        "plan": printable(plan.name),
        "plan_file": printable(Path(plan.source).name) if plan.source else None,
        "planned_depth_mm": _num(result.planned_depth_mm),
        "stop_depth_mm": _num(result.stop_depth_mm),
        "stop_reason": result.stop_reason,
        "max_safe_depth_mm": _num(result.max_safe_depth_mm),
        # the search stops past the planned depth: true means "at least this deep"
        "max_safe_depth_capped": result.max_safe_depth_capped,
        "out_of_volume_depth_mm": _num(result.out_of_volume_depth_mm),
        "min_clearance_mm": _num(result.min_clearance_mm),
        "plan_clearance_mm": _num(result.plan_clearance_mm),
        "binding_landmark": None if binding is None else lms[binding],
        "margin_mm": plan.margin_mm,
        "landmarks": lms,
        **calibration_fields(cal),
        **(band or {}),
        "feed_mm_s": feed_mm_s,
        "rate_hz": rate_hz,
        "duration_s": _num(float(series.time_s[-1]), 6),
        "peak_force_n": _num(float(np.max(series.force_n)), 5),
        "mean_force_n": _num(float(np.mean(series.force_n)), 5),
        "drill": plan.drill.to_json(),
        "entry_lps": plan.entry_lps.tolist(),
        "target_lps": plan.target_lps.tolist(),
        "implant": implant_json(result),
        "depth_step_mm": _num(prof.step_mm, 6),
        **series_identity(series_uid, include_phi=include_phi),
        "include_phi": include_phi,
        "extrapolation": {
            "clipped_samples": prof.n_clipped,
            "samples": prof.n_samples,
            "share": _num(prof.n_clipped / prof.n_samples if prof.n_samples else 0.0, 6),
        },
        "hu_grading": hu_grading(result),
        "interpolated_gaps": interpolated_gaps_json(result),
        "warnings": [{"code": w.code, "message": w.message} for w in result.warnings],
    }
    if result.inner_holes:  # a drill of a sequence: the holes its profile cut around
        from ctdrill.engine.sequence import hole_json

        doc["inner_holes"] = [hole_json(h) for h in result.inner_holes]
    if patient is not None:
        doc["patient"] = patient
    return doc


def summary_lines(doc: dict[str, Any]) -> list[str]:
    """What ``ctdrill export`` prints of one ``summary.json``: the stop (depth, reason, the
    binding landmark), the planned path's clearance, then one line per warning."""
    if doc.get("format") == "ctdrill-sequence/1":
        from ctdrill.app.sequence_export import sequence_lines

        return sequence_lines(doc)
    binding = doc.get("binding_landmark")
    why = str(doc["stop_reason"])
    if why == "margin" and binding is not None:
        why += f": {binding['name']!r}, margin {binding['margin_mm']:g} mm"
    line = (
        f"{doc['plan']}: stop at {doc['stop_depth_mm']:.3f} mm ({why}) of "
        f"{doc['planned_depth_mm']:.3f} mm planned"
    )
    if doc.get("plan_clearance_mm") is not None:
        line += f"; clearance along the planned path {doc['plan_clearance_mm']:.3f} mm"
    lines = [line]
    if "calibration" in doc:
        lines.append(calibration_line(doc))
    if "force_band_note" in doc:
        lines.append(band_line(doc))
    grey = grey_line(doc)
    if grey is not None:
        lines.append(grey)
    lines += [f"warning [{w['code']}]: {w['message']}" for w in doc.get("warnings", [])]
    return lines


def job_summary(
    result: PathResult,
    *,
    feed_mm_s: float | None,
    rate_hz: float,
    series_uid: str,
    patient: dict[str, str] | None = None,
    include_phi: bool = False,
    hu_uncertainty: HuUncertainty | None = None,
    grey_to_hu: dict[str, Any] | None = None,
) -> tuple[ForceSeries, ForceBand | None, dict[str, Any]]:
    """One trajectory's force series, force band and ``summary.json`` document, exactly as
    ``ctdrill export`` writes them (``ctdrill report`` shows the same numbers).

    ``feed_mm_s`` None uses the plan's feed; the other parameters are :func:`write_exports`'.
    """
    feed = result.plan.feed_mm_s if feed_mm_s is None else feed_mm_s
    series = force_time_series(
        result, feed_mm_s=feed, rate_hz=rate_hz, feed_option=feed_mm_s is not None
    )
    band = path_band(result, feed, hu_uncertainty)
    doc = summary(
        result,
        series,
        feed_mm_s=feed,
        rate_hz=rate_hz,
        series_uid=series_uid,
        patient=patient,
        include_phi=include_phi,
        band={
            **band_summary(result, band, feed_mm_s=feed, hu=hu_uncertainty),
            "grey_to_hu": grey_to_hu,
        },
    )
    return series, band, doc


@dataclass(frozen=True)
class ExportJob:
    """One trajectory's results, ready to write into ``subdir`` of the output folder."""

    result: PathResult
    subdir: str


def write_exports(
    jobs: Sequence[ExportJob],
    out_dir: Path,
    *,
    feed_mm_s: float | None,
    rate_hz: float,
    series_uid: str,
    patient: dict[str, str] | None = None,
    progress: Callable[[int, int, str], None] | None = None,
    extra_files: Mapping[str, bytes | str] | None = None,
    include_phi: bool = False,
    plot: bool = True,
    files: bool = True,
    table: bool = False,
    hu_uncertainty: HuUncertainty | None = None,
    grey_to_hu: dict[str, Any] | None = None,
) -> list[Path]:
    """Write every job's four files into a staging folder swapped in for ``out_dir`` whole.

    ``feed_mm_s`` None uses each plan's feed; ``include_phi`` writes the raw series UID (see
    :func:`summary`). ``plot`` False leaves out ``force.png`` (each summary says
    ``"plot": false``); ``files`` False writes no per-job files; ``table`` writes
    ``trajectories.csv`` (:mod:`ctdrill.app.export_table`), one row per job.
    ``hu_uncertainty`` enters every force band (``--hu-sigma``, a grey map); ``grey_to_hu``
    (the map applied to the series, or None) is recorded in every summary.
    ``extra_files`` (relative path -> content) are written in the same swap (the demo's
    marker, the GUI's session record); their names may be present when the folder is next
    replaced. ``out_dir`` is replaced as a whole
    (:func:`ctdrill.app.records.atomic_output_dir`): a kill, a full disk or an error leaves the
    previous export exactly as it was; a folder holding other files is refused. Returns the
    written paths (under ``out_dir``).
    """
    from ctdrill.app.export_plot import force_png
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
            series, band, doc = job_summary(
                job.result,
                feed_mm_s=feed_mm_s,
                rate_hz=rate_hz,
                series_uid=series_uid,
                patient=patient,
                include_phi=include_phi,
                hu_uncertainty=hu_uncertainty,
                grey_to_hu=grey_to_hu,
            )
            doc["plot"] = plot
            if table:
                rows.append(table_row(doc, job.subdir if files else ""))
            if not files:
                continue
            target = staging / job.subdir
            target.mkdir(parents=True, exist_ok=True)
            cal = job.result.calibration.name
            outputs: dict[str, bytes | str] = {
                "force.csv": force_csv(series, cal),
                "profile.csv": profile_csv(job.result, band),
                "summary.json": json.dumps(doc, indent=2, allow_nan=False) + "\n",
            }
            if plot:
                png = io.BytesIO()
                force_png(job.result, series, png, band=band)
                outputs["force.png"] = png.getvalue()
            for name, data in outputs.items():
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
