"""The report's summary: the case, the table of every trajectory, then each one's lines.

Every value is read from the trajectory's summary (:attr:`Entry.summary`) and formatted as
``ctdrill export`` prints it (depths and clearances to 3 decimals, mm); the lines under the
table are :func:`ctdrill.app.summary_lines.summary_lines` of the same summary: the stop,
the calibration and how it was obtained, the force band, the grey map and every warning in
full, wrapped.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from ctdrill.app.report.entries import Entry, undrawn_note
from ctdrill.app.report.layout import Column, TextPages
from ctdrill.app.summary_lines import summary_lines
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
    Column("peak mean force (N)", 1.0),
    Column("calibration", 1.25),
)

#: How the table words a stop reason.
STOP_WORDS = {
    "planned_depth": "planned depth",
    "margin": "safety margin",
    "out_of_volume": "end of the CT",
}


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
        f"{mm(binding.clearance_at_stop_mm)} at stop)"
    )
    band = s.force_band
    force = "-"
    if s.peak_force_n is not None:
        force = f"{s.peak_force_n:.2f} (peak with vibration; no band)"
    if band is not None:
        force = (
            f"{band.peak_mean_force_n:.2f} at {band.peak_depth_mm:.2f} mm; "
            f"68 %: {band.peak_lo_n:.2f}-{band.peak_hi_n:.2f}"
        )
    cal = o.calibration.name
    if o.calibration.illustrative:
        cal += " - ILLUSTRATIVE, not measured on bone"
    return [
        entry.label,
        drill_text,
        implant_text(entry),
        mm(o.planned_depth_mm),
        f"{mm(o.stop_depth_mm)} ({STOP_WORDS.get(o.stop_reason, o.stop_reason)})",
        max_safe,
        mm(o.min_clearance_mm),
        mm(o.plan_clearance_mm),
        binding_text,
        force,
        cal,
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
        "keeping every margin) and where the drill leaves the CT.",
        size_pt=8.0,
        colour="#444444",
    )
    pages.gap(0.2)
    for entry in entries:
        pages.paragraph(entry.label, size_pt=10.0, bold=True, keep_with_next_in=0.3)
        warned = 0
        lines = summary_lines(entry.summary)
        for line in lines:
            warn = line.startswith("warning [")
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
        pages.gap(0.12)
