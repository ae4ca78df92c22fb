"""``trajectories.csv``: one row per trajectory, for exports of many trajectories and cohorts.

Every value is read from the trajectory's summary
(:class:`~ctdrill.engine.summary.TrajectorySummary`, what its ``summary.json`` holds), so a
row and the summary never disagree. Empty cells are values the summary holds as ``null``
(no landmark binds, the lip never leaves the volume, ...); booleans are ``true``/``false``;
``warnings`` lists the warning codes, ``;``-separated (the messages are in the summaries of
an export with ``--per-trajectory``, and in the terminal). A plan with a drill sequence has
one row per drill (in drilling order; ``drill_diameter_mm`` tells them apart), each that
drill's own summary.
"""

from __future__ import annotations

from collections.abc import Callable, Collection, Iterable, Mapping, Sequence
from typing import Any

from ctdrill.app.csv_cells import csv_table
from ctdrill.engine.stop import stop_words
from ctdrill.engine.summary import LandmarkClearance, TrajectorySummary
from ctdrill.imaging.misch import MISCH_CLASSES

#: Name of the table in the output folder.
TABLE_NAME = "trajectories.csv"


def _binding(s: TrajectorySummary) -> LandmarkClearance | None:
    return s.outcome.binding_landmark


def _share(c: str) -> Callable[[TrajectorySummary], Any]:
    return lambda s: round(float(s.hu_grading.misch_share[c]), 6)


#: The columns, in order (identity, the stop, clearances, forces, bone, calibration,
#: geometry), each with how it reads the summary: the one list of the table.
COLUMNS: tuple[tuple[str, Callable[[TrajectorySummary], Any]], ...] = (
    ("trajectory", lambda s: s.outcome.plan),
    ("plan_file", lambda s: s.outcome.plan_file),
    ("folder", lambda s: None),  # set by table_row
    ("planned_depth_mm", lambda s: s.outcome.planned_depth_mm),
    ("stop_depth_mm", lambda s: s.outcome.stop_depth_mm),
    ("stop_reason", lambda s: s.outcome.stop_reason),
    ("max_safe_depth_mm", lambda s: s.outcome.max_safe_depth_mm),
    ("max_safe_depth_capped", lambda s: s.outcome.max_safe_depth_capped),
    ("out_of_volume_depth_mm", lambda s: s.outcome.out_of_volume_depth_mm),
    ("min_clearance_mm", lambda s: s.outcome.min_clearance_mm),
    ("plan_clearance_mm", lambda s: s.outcome.plan_clearance_mm),
    ("binding_landmark", lambda s: b.name if (b := _binding(s)) else None),
    ("binding_margin_mm", lambda s: b.margin_mm if (b := _binding(s)) else None),
    (
        "binding_clearance_at_stop_mm",
        lambda s: b.clearance_at_stop_mm if (b := _binding(s)) else None,
    ),
    ("implant_clearance_mm", lambda s: s.outcome.implant_clearance_mm),
    ("bone_wall_min_mm", lambda s: w.min_mm if (w := s.outcome.bone_walls) else None),
    ("clearance_accuracy_mm", lambda s: s.outcome.clearance_accuracy_mm),
    ("peak_force_n", lambda s: s.peak_force_n),
    ("mean_force_n", lambda s: s.mean_force_n),
    ("duration_s", lambda s: s.duration_s),
    ("feed_mm_s", lambda s: s.outcome.feed_mm_s),
    ("drill_diameter_mm", lambda s: s.drill.diameter_mm),
    *((f"misch_{c}_share", _share(c)) for c in MISCH_CLASSES),
    ("calibration", lambda s: s.outcome.calibration.name),
    ("calibration_illustrative", lambda s: s.outcome.calibration.illustrative),
    ("entry_x_mm", lambda s: s.outcome.entry_lps[0]),
    ("entry_y_mm", lambda s: s.outcome.entry_lps[1]),
    ("entry_z_mm", lambda s: s.outcome.entry_lps[2]),
    ("target_x_mm", lambda s: s.outcome.target_lps[0]),
    ("target_y_mm", lambda s: s.outcome.target_lps[1]),
    ("target_z_mm", lambda s: s.outcome.target_lps[2]),
    ("series_uid_sha256", lambda s: s.outcome.series.series_uid_sha256),
    ("warnings", lambda s: ";".join(w.code for w in s.warnings)),
)
#: The table's header.
TABLE_COLUMNS: tuple[str, ...] = tuple(name for name, _ in COLUMNS)


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


def table_row(summary: TrajectorySummary, folder: str) -> dict[str, str]:
    """The row of one trajectory from its summary; ``folder`` is where its own files are
    (relative to the output folder), empty when they were not written."""
    row = {name: _cell(read(summary)) for name, read in COLUMNS}
    row["folder"] = folder
    return row


def table_csv(
    rows: Iterable[Mapping[str, str]],
    columns: Sequence[str] = TABLE_COLUMNS,
    text_columns: Collection[str] = TEXT_COLUMNS,
) -> str:
    """CSV text of ``rows`` (dicts keyed by ``columns``) with a header line; text cells that a
    spreadsheet would run as a formula are neutralised (:mod:`ctdrill.app.csv_cells`)."""
    return csv_table(rows, columns, text_columns=text_columns)


def table_lines(rows: Iterable[Mapping[str, str]]) -> list[str]:
    """The terminal lines of a table: per trajectory the stop and the planned path's
    clearance, with an implant its clearance and thinnest wall, and its warnings' codes
    (clearances with the digits the CT supports, ``clearance_accuracy_mm``)."""
    from ctdrill.imaging.resolution import MAX_DECIMALS, format_clearance_mm

    lines = []
    for r in rows:
        acc = r.get("clearance_accuracy_mm", "")

        def clear(cell: str, acc: str = acc) -> str:
            v = float(cell)
            return f"{v:.{MAX_DECIMALS}f}" if not acc else format_clearance_mm(v, float(acc))

        binding = r["binding_landmark"] or None
        margin = float(r["binding_margin_mm"]) if binding else None
        why = stop_words(r["stop_reason"], landmark=binding, margin_mm=margin)
        line = (
            f"{r['trajectory']}: stop at {float(r['stop_depth_mm']):.3f} mm ({why}) of "
            f"{float(r['planned_depth_mm']):.3f} mm planned"
        )
        if r["plan_clearance_mm"]:
            line += f"; clearance along the planned path {clear(r['plan_clearance_mm'])} mm"
        lines.append(line)
        implant = [
            f"{what} {clear(r[key])} mm"
            for what, key in (
                ("implant clearance", "implant_clearance_mm"),
                ("thinnest bone wall", "bone_wall_min_mm"),
            )
            if r.get(key)
        ]
        if implant:
            lines.append(f"{r['trajectory']}: " + ", ".join(implant))
        if r.get("warnings"):
            lines.append(f"{r['trajectory']}: warnings {r['warnings'].replace(';', ', ')}")
    return lines
