"""What ``ctdrill export`` (and ``report``, ``demo``) prints of a summary: the stop, the
implant's clearance and walls, the calibration, the force band, the grey map and every
warning, one line each.

Clearances and walls are printed with no more digits than the CT's sampling supports
(:func:`~ctdrill.imaging.resolution.format_clearance_mm` of the summary's
``clearance_accuracy_mm``: one decimal on 0.3-1 mm voxels); depths keep three decimals (they
are the plan's own numbers, not measured on the CT); ``summary.json`` keeps every digit."""

from __future__ import annotations

from ctdrill.app.grey_option import grey_line
from ctdrill.engine.stop import stop_words
from ctdrill.engine.summary import (
    METHOD_NOT_STATED,
    BoneWallsInfo,
    CalibrationInfo,
    ForceBandPeak,
    PlanOutcome,
    SequenceSummary,
    TrajectorySummary,
)
from ctdrill.warning_codes import LoadWarning


def calibration_line(cal: CalibrationInfo) -> str:
    """``calibration NAME (illustrative): how obtained``."""
    how = cal.method or METHOD_NOT_STATED
    if how == METHOD_NOT_STATED:
        how = cal.source or how
    tag = " (illustrative)" if cal.illustrative else ""
    return f"calibration {cal.name}{tag}: {how}"


def band_line(band: ForceBandPeak | None, note: str) -> str:
    """One terminal line: the band at the peak, or why there is none."""
    if band is None:
        return note or "no force band"
    return (
        f"peak mean force {band.peak_mean_force_n:.2f} N at {band.peak_depth_mm:.2f} mm, "
        f"68 % band {band.peak_lo_n:.2f}-{band.peak_hi_n:.2f} N "
        f"(at {band.feed_mm_s:g} mm/s; {note.split(' from ', 1)[-1]})"
    )


def _why(outcome: PlanOutcome) -> str:
    binding = outcome.binding_landmark
    if binding is None:
        return stop_words(outcome.stop_reason)
    return stop_words(outcome.stop_reason, landmark=binding.name, margin_mm=binding.margin_mm)


def clearance_text(value_mm: float, outcome: PlanOutcome) -> str:
    """``value_mm`` with the digits the CT supports (``outcome.clearance_accuracy_mm``;
    three decimals when unknown), without a unit."""
    from ctdrill.imaging.resolution import MAX_DECIMALS, format_clearance_mm

    acc = outcome.clearance_accuracy_mm
    return f"{value_mm:.{MAX_DECIMALS}f}" if acc is None else format_clearance_mm(value_mm, acc)


def _clearance(outcome: PlanOutcome) -> str:
    if outcome.plan_clearance_mm is None:
        return ""
    text = clearance_text(outcome.plan_clearance_mm, outcome)
    return f"; clearance along the planned path {text} mm"


def walls_text(walls: BoneWallsInfo, outcome: PlanOutcome) -> str:
    """``thinnest bone wall 1.2 mm (buccal 1.2, lingual 2.0 mm)``, or why it is unknown."""
    if walls.min_mm is None:
        return "bone walls unknown (the CT ends before bone does; outside it is never bone)"
    at_least = "at least " if walls.capped else ""
    sides = [
        f"{name} {clearance_text(v, outcome)}"
        for name, v in (("buccal", walls.buccal_mm), ("lingual", walls.lingual_mm))
        if v is not None
    ]
    return f"thinnest bone wall {at_least}{clearance_text(walls.min_mm, outcome)} mm" + (
        f" ({', '.join(sides)} mm)" if sides else ""
    )


def implant_line(outcome: PlanOutcome) -> str | None:
    """The implant body's clearance to its binding landmark and its thinnest walls, or None
    without an implant."""
    imp = outcome.implant
    if imp is None:
        return None
    parts = []
    binding = outcome.implant_binding_landmark
    if outcome.implant_clearance_mm is not None and binding is not None:
        parts.append(
            f"clearance {clearance_text(outcome.implant_clearance_mm, outcome)} mm to "
            f"{binding.name!r} (margin {binding.margin_mm:g} mm)"
        )
    if outcome.bone_walls is not None:
        parts.append(walls_text(outcome.bone_walls, outcome))
    acc = outcome.clearance_accuracy_mm
    known = "" if acc is None else f"; +-{acc:.2g} mm on this CT"
    return f"{outcome.plan}: implant {imp.name!r} " + "; ".join(parts) + known


def _warnings(warnings: tuple[LoadWarning, ...]) -> list[str]:
    return [f"warning [{w.code}]: {w.message}" for w in warnings]


def summary_lines(summary: TrajectorySummary | SequenceSummary) -> list[str]:
    """The lines of one summary: the stop (depth, reason, the binding landmark), the planned
    path's clearance, the calibration, the band, the grey map, then one line per warning; a
    drill sequence's (:func:`sequence_lines`)."""
    if isinstance(summary, SequenceSummary):
        return sequence_lines(summary)
    o = summary.outcome
    lines = [
        f"{o.plan}: stop at {o.stop_depth_mm:.3f} mm ({_why(o)}) of "
        f"{o.planned_depth_mm:.3f} mm planned" + _clearance(o),
        calibration_line(o.calibration),
        band_line(summary.force_band, summary.force_band_note),
    ]
    implant = implant_line(o)
    if implant is not None:
        lines.insert(1, implant)
    grey = grey_line(o.grey_to_hu)
    if grey is not None:
        lines.append(grey)
    return lines + _warnings(summary.warnings)


def sequence_lines(summary: SequenceSummary) -> list[str]:
    """A drill sequence's lines: one per drill, then the plan's stop (the final drill's), the
    calibration, then one line per warning."""
    o = summary.outcome
    n = len(summary.drills)
    lines = []
    for d in summary.drills:
        band = d.force_band
        lines.append(
            f"{o.plan} drill {d.drill}/{n} ({d.spec.diameter_mm:g} mm): stop at "
            f"{d.stop_depth_mm:.3f} mm ({d.stop_reason}) of {d.planned_depth_mm:.3f} mm "
            f"planned, peak force {d.peak_force_n:.3f} N"
            + (
                ""
                if band is None
                else f", 68 % band of the peak mean force {band.peak_lo_n:.2f}-"
                f"{band.peak_hi_n:.2f} N"
            )
        )
    lines.append(
        f"{o.plan}: final drill stops at {o.stop_depth_mm:.3f} mm ({_why(o)}) of "
        f"{o.planned_depth_mm:.3f} mm planned" + _clearance(o)
    )
    implant = implant_line(o)
    if implant is not None:
        lines.append(implant)
    lines.append(calibration_line(o.calibration))
    return lines + _warnings(summary.warnings)
