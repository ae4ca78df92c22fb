"""The export of a drill sequence: ``OUT/drill_1/``, ``OUT/drill_2/`` ... and ``OUT/summary.json``.

Each drill's folder holds the usual four files of its own path (its profile cut around the
holes before it, its clearance and stop); the top-level ``summary.json``
(``"format": "ctdrill-sequence/1"``) carries the plan-level keys of the export summary, taken
from the final drill, whose stop rules the plan, and ``drills``: one entry per drill in
drilling order (its folder, geometry, stop depth and reason, peak and mean force, the holes it
cut around). The warnings are every drill's, each once. Written in the same atomic swap as the
drills' files (:func:`ctdrill.app.export.write_exports`).
"""

from __future__ import annotations

import json
from typing import Any

from ctdrill.app.calibration_info import calibration_line
from ctdrill.app.export import ExportJob, force_time_series, summary
from ctdrill.app.export_band import band_summary, path_band
from ctdrill.engine.sequence import SequenceResult, drill_folder, hole_json
from ctdrill.model.band import HuUncertainty

SEQUENCE_FORMAT = "ctdrill-sequence/1"
#: Keys of the final drill's summary that describe the plan (copied to the top level).
PLAN_KEYS = (
    "plan",
    "plan_file",
    "planned_depth_mm",
    "stop_depth_mm",
    "stop_reason",
    "max_safe_depth_mm",
    "max_safe_depth_capped",
    "out_of_volume_depth_mm",
    "min_clearance_mm",
    "plan_clearance_mm",
    "binding_landmark",
    "margin_mm",
    "landmarks",
    "calibration",
    "calibration_illustrative",
    "calibration_source",
    "calibration_method",
    "calibration_covariance",
    "hu_uncertainty",
    "grey_to_hu",
    "feed_mm_s",
    "rate_hz",
    "entry_lps",
    "target_lps",
    "implant",
    "series_uid",
    "series_uid_sha256",
    "include_phi",
    "patient",
)


def sequence_jobs(seq: SequenceResult, subdir: str) -> list[ExportJob]:
    """One export job per drill, into ``subdir/drill_k`` (``drill_k`` when ``subdir`` is "")."""
    return [
        ExportJob(result=step, subdir=_join(subdir, drill_folder(k)))
        for k, step in enumerate(seq.steps)
    ]


def _join(subdir: str, name: str) -> str:
    return f"{subdir}/{name}" if subdir else name


def sequence_summary(
    seq: SequenceResult,
    *,
    feed_mm_s: float | None,
    rate_hz: float,
    series_uid: str,
    patient: dict[str, str] | None = None,
    include_phi: bool = False,
    hu_uncertainty: HuUncertainty | None = None,
    grey_to_hu: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """The top-level ``summary.json`` of a sequence (see the module docstring); each drill
    with its force band at its peak (``hu_uncertainty`` as ``write_exports``').

    Each drill's numbers are those of its own ``summary.json`` (the same functions compute
    them from the same path)."""
    docs = []
    for step in seq.steps:
        feed = step.plan.feed_mm_s if feed_mm_s is None else feed_mm_s
        series = force_time_series(
            step, feed_mm_s=feed, rate_hz=rate_hz, feed_option=feed_mm_s is not None
        )
        docs.append(
            summary(
                step,
                series,
                feed_mm_s=feed,
                rate_hz=rate_hz,
                series_uid=series_uid,
                patient=patient,
                include_phi=include_phi,
                band={
                    **band_summary(
                        step,
                        path_band(step, feed, hu_uncertainty),
                        feed_mm_s=feed,
                        hu=hu_uncertainty,
                    ),
                    "grey_to_hu": grey_to_hu,
                },
            )
        )
    final = docs[-1]
    out: dict[str, Any] = {"format": SEQUENCE_FORMAT}
    out.update({key: final[key] for key in PLAN_KEYS if key in final})
    out["final_drill"] = len(docs)
    out["drills"] = [
        {
            "drill": k + 1,
            "folder": drill_folder(k),
            **step.plan.drill.to_json(),
            "stop_depth_mm": doc["stop_depth_mm"],
            "stop_reason": doc["stop_reason"],
            "max_safe_depth_mm": doc["max_safe_depth_mm"],
            "min_clearance_mm": doc["min_clearance_mm"],
            "peak_force_n": doc["peak_force_n"],
            "mean_force_n": doc["mean_force_n"],
            "force_band": doc["force_band"],
            "inner_holes": [hole_json(h) for h in step.inner_holes],
        }
        for k, (step, doc) in enumerate(zip(seq.steps, docs, strict=True))
    ]
    out["warnings"] = [
        {"code": w.code, "message": w.message} for w in seq.warnings
    ]  # every drill's, once
    return out


def sequence_files(seq: SequenceResult, subdir: str, **options: Any) -> dict[str, str]:
    """``{subdir/summary.json: text}`` for :func:`write_exports`' ``extra_files``; ``options``
    as :func:`sequence_summary`'s."""
    doc = sequence_summary(seq, **options)
    return {_join(subdir, "summary.json"): json.dumps(doc, indent=2, allow_nan=False) + "\n"}


def sequence_lines(doc: dict[str, Any]) -> list[str]:
    """What ``ctdrill export`` prints of a sequence's ``summary.json``: one line per drill,
    then the plan's stop (the final drill's), then one line per warning."""
    lines = []
    n = len(doc["drills"])
    for d in doc["drills"]:
        lines.append(
            f"{doc['plan']} drill {d['drill']}/{n} ({d['diameter_mm']:g} mm): stop at "
            f"{d['stop_depth_mm']:.3f} mm ({d['stop_reason']}), peak force "
            f"{d['peak_force_n']:.3f} N"
            + (
                ""
                if d.get("force_band") is None
                else f", 68 % band of the peak mean force {d['force_band']['peak_lo_n']:.2f}-"
                f"{d['force_band']['peak_hi_n']:.2f} N"
            )
        )
    why = str(doc["stop_reason"])
    binding = doc.get("binding_landmark")
    if why == "margin" and binding is not None:
        why += f": {binding['name']!r}, margin {binding['margin_mm']:g} mm"
    line = (
        f"{doc['plan']}: final drill stops at {doc['stop_depth_mm']:.3f} mm ({why}) of "
        f"{doc['planned_depth_mm']:.3f} mm planned"
    )
    if doc.get("plan_clearance_mm") is not None:
        line += f"; clearance along the planned path {doc['plan_clearance_mm']:.3f} mm"
    lines.append(line)
    if "calibration" in doc:
        lines.append(calibration_line(doc))
    lines += [f"warning [{w['code']}]: {w['message']}" for w in doc.get("warnings", [])]
    return lines
