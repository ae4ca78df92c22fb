"""The report's summary: the case, the table of every trajectory, then each one's lines.

Every value is read from the trajectory's summary (:attr:`Entry.summary`) and formatted as
``ctdrill export`` prints it (depths to 3 decimals, mm; clearances with the digits the CT
supports, :func:`ctdrill.app.summary_lines.clearance_text`); the lines under the table are
:func:`ctdrill.app.summary_lines.summary_lines` of the same summary (the stop, the implant's
clearance and walls, the grey map and every warning in full, wrapped) without the calibration
and force band, which the engineering appendix gives (:mod:`ctdrill.app.report.clinical`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from ctdrill.app.report.entries import Entry, undrawn_note
from ctdrill.app.report.layout import Column, TextPages
from ctdrill.app.summary_lines import band_line, calibration_line, clearance_text, summary_lines
from ctdrill.engine.stop import stop_words
from ctdrill.engine.summary import TrajectorySummary
from ctdrill.imaging.volume import CTVolume

#: The table's columns (heading, share of the width).
COLUMNS: tuple[Column, ...] = (
    Column("trajectory", 1.3),
    Column("drill", 1.0),
    Column("implant", 1.1),
    Column("planned depth (mm)", 0.8),
    Column("stop depth (mm), reason", 1.1),
    Column("max safe depth (mm)", 0.85),
    Column("clearance at stop (mm)", 0.85),
    Column("clearance of the plan (mm)", 0.85),
    Column("binding landmark", 1.3),
    Column("implant clearance (mm)", 1.0),
    Column("thinnest wall (mm)", 0.9),
)


def mm(value: Any) -> str:
    """A depth or clearance as the export prints it (3 decimals), or ``-`` for none."""
    return "-" if value is None else f"{float(value):.3f}"


def implant_text(entry: Entry) -> str:
    """The implant placed on the trajectory (name, diameter x length), or ``none``."""
    spec = entry.result.plan.implant
    if spec is None:
        return "none"
    return f"{spec.name} ({spec.size_text})"


def table_row(entry: Entry) -> list[str]:
    """The table's cells for ``entry``, every value from its summary."""
    s = entry.summary
    o = s.outcome

    def clear(value: float | None) -> str:
        return "-" if value is None else clearance_text(value, o)

    drill_text = f"{s.drill.diameter_mm:g} mm, tip {s.drill.tip_length_mm:g} mm"
    if entry.drill_index is not None:
        k, n = entry.drill_index
        drill_text = f"drill {k} of {n}{' (final)' if k == n else ''}: " + drill_text
    max_safe = mm(o.max_safe_depth_mm)
    if o.max_safe_depth_capped:
        max_safe = f"at least {max_safe} (search limit)"
    binding = o.binding_landmark
    binding_text = (
        "no landmark"
        if binding is None
        else f"{binding.name} (margin {binding.margin_mm:g} mm; "
        f"{clear(binding.clearance_at_stop_mm)} at stop)"
    )
    implant = "-"
    if o.implant_binding_landmark is not None:
        implant = (
            f"{clear(o.implant_clearance_mm)} to {o.implant_binding_landmark.name} "
            f"(margin {o.implant_binding_landmark.margin_mm:g} mm)"
        )
    wall = "-"
    if o.bone_walls is not None:
        wall = "unknown" if o.bone_walls.min_mm is None else clear(o.bone_walls.min_mm)
    return [
        entry.label,
        drill_text,
        implant_text(entry),
        mm(o.planned_depth_mm),
        f"{mm(o.stop_depth_mm)} ({stop_words(o.stop_reason, form='plain')})",
        max_safe,
        clear(o.min_clearance_mm),
        clear(o.plan_clearance_mm),
        binding_text,
        implant,
        wall,
    ]


def case_lines(
    volume: CTVolume, entries: Sequence[Entry], *, include_phi: bool, plan_files: Sequence[str]
) -> list[str]:
    """The case: the series (hashed UID unless ``include_phi``), the plans, the patient's
    identifiers with ``include_phi`` only."""
    first = entries[0].summary if entries else None
    nz, ny, nx = volume.hu.shape
    sp = volume.spacing_mm
    lines = [
        f"CT series: {nx} x {ny} x {nz} voxels, spacing {sp[0]:.3g} x {sp[1]:.3g} x {sp[2]:.3g} "
        f"mm; series {_series_id(first)}",
        "plan files: " + (", ".join(plan_files) if plan_files else "-"),
    ]
    patient = None if first is None else first.outcome.patient
    if include_phi and patient:
        lines.append("patient: " + "; ".join(f"{k}: {v}" for k, v in patient.items() if v))
    else:
        lines.append(
            "no patient identifiers in this report (ctdrill report --include-phi adds them)"
        )
    return lines


def _series_id(summary: TrajectorySummary | None) -> str:
    if summary is None:
        return "-"
    o = summary.outcome
    if o.include_phi and o.series.series_uid:
        return f"UID {o.series.series_uid}"
    return f"SHA-256 of the UID {o.series.series_uid_sha256[:16]}..."


#: Most warnings written in full under a trajectory (a plan of many implants packed close
#: together gives one implants_too_close line per neighbour: the square of their number).
MAX_WARNING_LINES = 12


def summary_pages(
    pages: TextPages,
    volume: CTVolume,
    entries: Sequence[Entry],
    *,
    include_phi: bool,
    plan_files: Sequence[str],
) -> None:
    """Add the case, the table and each trajectory's lines to ``pages``."""
    pages.paragraph("Planned osteotomy: summary", size_pt=14.0, bold=True)
    pages.gap(0.08)
    for line in case_lines(volume, entries, include_phi=include_phi, plan_files=plan_files):
        pages.paragraph(line, size_pt=9.0)
    pages.gap(0.15)
    pages.table(COLUMNS, [table_row(e) for e in entries])
    pages.gap(0.1)
    note = undrawn_note(entries)
    if note is not None:
        pages.paragraph(note, size_pt=9.0, bold=True)
        pages.gap(0.1)
    pages.paragraph(
        "Depths are the drill tip's from the entry point along the axis; clearance is the "
        "signed distance from the drill to a landmark's surface (negative: inside it). The "
        "drill stops at the smallest of the planned depth, the max safe depth (the deepest "
        "keeping every margin) and where the drill leaves the CT. With an implant every drill "
        "is drilled to the implant's apex plus its own tip length (the planned depth). "
        "Implant clearance: from the implant body to the landmark whose margin binds. "
        "Clearances and walls are printed with the digits the CT's sampling supports. "
        "Calibrations and forces: the appendix.",
        size_pt=8.0,
        colour="#444444",
    )
    pages.gap(0.2)
    shown: set[str] = set()  # a warning another trajectory (or drill) already gave in full
    for entry in entries:
        pages.paragraph(entry.label, size_pt=10.0, bold=True, keep_with_next_in=0.3)
        warned = repeated = 0
        o = entry.summary.outcome
        engineering = {  # in the appendix
            calibration_line(o.calibration),
            band_line(entry.summary.force_band, entry.summary.force_band_note),
        }
        lines = [line for line in summary_lines(entry.summary) if line not in engineering]
        for line in lines:
            warn = line.startswith("warning [")
            if warn and line in shown:
                repeated += 1
                continue
            shown.add(line)
            warned += warn
            if warn and warned > MAX_WARNING_LINES:
                continue
            pages.paragraph(line, size_pt=8.5, colour="#a01010" if warn else "k", indent_in=0.15)
        if warned > MAX_WARNING_LINES:
            pages.paragraph(
                f"... and {warned - MAX_WARNING_LINES} more warnings: every one is in this "
                "trajectory's summary.json (ctdrill export --per-trajectory)",
                size_pt=8.5,
                colour="#a01010",
                indent_in=0.15,
            )
        if repeated:
            pages.paragraph(
                f"and {repeated} warning{'s' * (repeated > 1)} given in full above",
                size_pt=8.5,
                colour="#a01010",
                indent_in=0.15,
            )
        pages.gap(0.12)
