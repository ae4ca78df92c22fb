"""What ``ctdrill export`` (and ``report``, ``demo``) prints of a summary: the stop, the
calibration, the force band, the grey map and every warning, one line each."""

from __future__ import annotations

from ctdrill.app.grey_option import grey_line
from ctdrill.engine.summary import (
    METHOD_NOT_STATED,
    CalibrationInfo,
    ForceBandPeak,
    PlanOutcome,
    SequenceSummary,
    TrajectorySummary,
    WarningEntry,
)


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
    why = outcome.stop_reason
    binding = outcome.binding_landmark
    if why == "margin" and binding is not None:
        why += f": {binding.name!r}, margin {binding.margin_mm:g} mm"
    return why


def _clearance(outcome: PlanOutcome) -> str:
    if outcome.plan_clearance_mm is None:
        return ""
    return f"; clearance along the planned path {outcome.plan_clearance_mm:.3f} mm"


def _warnings(warnings: tuple[WarningEntry, ...]) -> list[str]:
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
            f"{d.stop_depth_mm:.3f} mm ({d.stop_reason}), peak force {d.peak_force_n:.3f} N"
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
    lines.append(calibration_line(o.calibration))
    return lines + _warnings(summary.warnings)
