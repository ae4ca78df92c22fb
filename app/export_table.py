"""``trajectories.csv``: one row per trajectory, for exports of many trajectories and cohorts.

Every value is taken from the trajectory's ``summary.json`` document (:func:`summary`), so a
row and the summary never disagree. Empty cells are values the summary holds as ``null``
(no landmark binds, the lip never leaves the volume, ...); booleans are ``true``/``false``;
``warnings`` lists the warning codes, ``;``-separated (the messages are in the summaries of
an export with ``--per-trajectory``, and in the terminal). A plan with a drill sequence has
one row per drill (in drilling order; ``drill_diameter_mm`` tells them apart), each that
drill's own summary.
"""

from __future__ import annotations

from collections.abc import Collection, Iterable, Mapping, Sequence
from typing import Any

from ctdrill.app.csv_cells import csv_table
from ctdrill.imaging.misch import MISCH_CLASSES

#: Name of the table in the output folder.
TABLE_NAME = "trajectories.csv"

#: Columns, in order: identity, the stop, clearances, forces, bone, calibration, geometry.
TABLE_COLUMNS: tuple[str, ...] = (
    "trajectory",
    "plan_file",
    "folder",
    "planned_depth_mm",
    "stop_depth_mm",
    "stop_reason",
    "max_safe_depth_mm",
    "max_safe_depth_capped",
    "out_of_volume_depth_mm",
    "min_clearance_mm",
    "plan_clearance_mm",
    "binding_landmark",
    "binding_margin_mm",
    "binding_clearance_at_stop_mm",
    "peak_force_n",
    "mean_force_n",
    "duration_s",
    "feed_mm_s",
    "drill_diameter_mm",
    *(f"misch_{c}_share" for c in MISCH_CLASSES),
    "calibration",
    "calibration_illustrative",
    "entry_x_mm",
    "entry_y_mm",
    "entry_z_mm",
    "target_x_mm",
    "target_y_mm",
    "target_z_mm",
    "series_uid_sha256",
    "warnings",
)


#: Columns of text (names, paths, codes); every other column holds numbers or booleans.
TEXT_COLUMNS: frozenset[str] = frozenset(
    {
        "trajectory",
        "plan_file",
        "folder",
        "stop_reason",
        "binding_landmark",
        "calibration",
        "series_uid_sha256",
        "warnings",
    }
)


def _cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    return str(value)


def table_row(doc: Mapping[str, Any], folder: str) -> dict[str, str]:
    """The row of one trajectory from its ``summary.json`` document; ``folder`` is where its
    own files are (relative to the output folder), empty when they were not written."""
    binding = doc.get("binding_landmark") or {}
    share = doc["hu_grading"]["misch_share"]
    entry = doc["entry_lps"]
    target = doc["target_lps"]
    values: dict[str, Any] = {
        "trajectory": doc["plan"],
        "plan_file": doc.get("plan_file"),
        "folder": folder,
        "planned_depth_mm": doc["planned_depth_mm"],
        "stop_depth_mm": doc["stop_depth_mm"],
        "stop_reason": doc["stop_reason"],
        "max_safe_depth_mm": doc["max_safe_depth_mm"],
        "max_safe_depth_capped": doc["max_safe_depth_capped"],
        "out_of_volume_depth_mm": doc["out_of_volume_depth_mm"],
        "min_clearance_mm": doc["min_clearance_mm"],
        "plan_clearance_mm": doc["plan_clearance_mm"],
        "binding_landmark": binding.get("name"),
        "binding_margin_mm": binding.get("margin_mm"),
        "binding_clearance_at_stop_mm": binding.get("clearance_at_stop_mm"),
        "peak_force_n": doc["peak_force_n"],
        "mean_force_n": doc["mean_force_n"],
        "duration_s": doc["duration_s"],
        "feed_mm_s": doc["feed_mm_s"],
        "drill_diameter_mm": doc["drill"]["diameter_mm"],
        **{f"misch_{c}_share": round(float(share[c]), 6) for c in MISCH_CLASSES},
        "calibration": doc["calibration"],
        "calibration_illustrative": doc["calibration_illustrative"],
        "entry_x_mm": entry[0],
        "entry_y_mm": entry[1],
        "entry_z_mm": entry[2],
        "target_x_mm": target[0],
        "target_y_mm": target[1],
        "target_z_mm": target[2],
        "series_uid_sha256": doc.get("series_uid_sha256"),
        "warnings": ";".join(w["code"] for w in doc.get("warnings", [])),
    }
    return {k: _cell(values[k]) for k in TABLE_COLUMNS}


def table_csv(
    rows: Iterable[Mapping[str, str]],
    columns: Sequence[str] = TABLE_COLUMNS,
    text_columns: Collection[str] = TEXT_COLUMNS,
) -> str:
    """CSV text of ``rows`` (dicts keyed by ``columns``) with a header line; text cells that a
    spreadsheet would run as a formula are neutralised (:mod:`ctdrill.app.csv_cells`)."""
    return csv_table(rows, columns, text_columns=text_columns)


def table_lines(rows: Iterable[Mapping[str, str]]) -> list[str]:
    """One terminal line per trajectory of a table (the stop and the planned path's clearance)."""
    lines = []
    for r in rows:
        why = r["stop_reason"]
        if why == "margin" and r["binding_landmark"]:
            why += f": {r['binding_landmark']!r}, margin {float(r['binding_margin_mm']):g} mm"
        line = (
            f"{r['trajectory']}: stop at {float(r['stop_depth_mm']):.3f} mm ({why}) of "
            f"{float(r['planned_depth_mm']):.3f} mm planned"
        )
        if r["plan_clearance_mm"]:
            line += f"; clearance along the planned path {float(r['plan_clearance_mm']):.3f} mm"
        lines.append(line)
    return lines
