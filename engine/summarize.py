"""A trajectory's (or a drill sequence's) summary, built once from its path and the case.

:func:`job_summary` gives what ``ctdrill export`` writes of one path (the force series, the
band and the :class:`~ctdrill.engine.summary.TrajectorySummary`); ``ctdrill report``, the batch
table and ``ctdrill.api`` read the same value. :func:`sequence_summary` lists a drill
sequence from each drill's own summary. A new summary field is one field of
:mod:`ctdrill.engine.summary` and its value here.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ctdrill.engine.band import band_peak, hu_uncertainty_info, path_band
from ctdrill.engine.budget import summary_budget
from ctdrill.engine.grading import hu_grading
from ctdrill.engine.path import PathResult
from ctdrill.engine.record import from_json
from ctdrill.engine.sequence import SequenceResult, drill_folder
from ctdrill.engine.series import ForceSeries, force_time_series
from ctdrill.engine.settings import ExportSettings
from ctdrill.engine.summary import (
    EXPORT_FORMAT,
    SEQUENCE_FORMAT,
    BoneWallsInfo,
    CalibrationInfo,
    DrillInfo,
    DrillStep,
    Extrapolation,
    GapInfo,
    GreyMapInfo,
    HoleInfo,
    ImplantBindingLandmark,
    ImplantSummary,
    LandmarkClearance,
    MarginBudgetInfo,
    PlanOutcome,
    SequenceSummary,
    SeriesIdentity,
    TrajectorySummary,
)
from ctdrill.engine.verdict import PlanVerdict
from ctdrill.imaging.dicom.identity import series_identity
from ctdrill.imaging.plan.implant_checks import implant_seated
from ctdrill.imaging.plan.implants import implant_placement
from ctdrill.imaging.plan.types import DrillSpec
from ctdrill.imaging.sampling.annulus import Hole
from ctdrill.model.band import ForceBand, HuUncertainty
from ctdrill.text import printable


@dataclass(frozen=True, eq=False)
class CaseContext:
    """What every summary of a case shares, known once the series is loaded.

    Attributes
    ----------
    settings : the export's options (feed override, rate, PHI, plot ...).
    series_uid : the loaded series' SeriesInstanceUID (written hashed unless ``include_phi``).
    patient : the patient's identifiers (``include_phi`` only), else None.
    hu_uncertainty : ``--hu-sigma`` and the grey map's HU error, entered into every band.
    grey_to_hu : the grey map applied to the series, or None.
    clearance_accuracy_mm : what the CT's sampling lets a clearance claim, +- mm
        (:func:`~ctdrill.imaging.resolution.volume_clearance_accuracy_mm`), or None.
    """

    settings: ExportSettings
    series_uid: str
    patient: Mapping[str, str] | None = None
    hu_uncertainty: HuUncertainty | None = None
    grey_to_hu: GreyMapInfo | None = field(default=None)
    clearance_accuracy_mm: float | None = None


@dataclass(frozen=True, eq=False)
class JobSummary:
    """One path as an export writes it: its force series, band and summary."""

    result: PathResult
    series: ForceSeries
    band: ForceBand | None
    summary: TrajectorySummary


def _nm(value: Any) -> Any:
    """A coordinate or depth (or a list of them) rounded to 1 nm, below any meaning: a drill's
    view of an implant plan computes the apex as its tip less the tip length."""
    if isinstance(value, list):
        return [_nm(v) for v in value]
    return round(value, 6) if isinstance(value, float) else value


def _num(v: float | None, digits: int = 4) -> float | None:
    if v is None or not np.isfinite(v):
        return None
    return round(float(v), digits)


def hole_info(hole: Hole) -> HoleInfo:
    """A hole as summaries write it."""
    return HoleInfo(
        diameter_mm=2.0 * hole.radius_mm, tip_length_mm=hole.tip_length_mm, depth_mm=hole.depth_mm
    )


def drill_info(drill: DrillSpec) -> DrillInfo:
    """The drill by its plan-file keys."""
    return DrillInfo(
        drill.diameter_mm,
        drill.tip_length_mm,
        drill.blades,
        drill.rpm,
        drill.point_angle_deg,
        drill.tip_override,
    )


def implant_summary(result: PathResult) -> ImplantSummary | None:
    """The implant's spec and placement and ``seated``: whether the stop reaches its apex
    (else warning ``implant_beyond_stop``); None for a plan without an implant."""
    place = implant_placement(result.plan)
    if place is None:
        return None
    doc = {k: _nm(v) for k, v in place.to_json().items()}  # a drill's view: apex = tip - tip
    seated = implant_seated(place, result.stop_depth_mm, result.plan.overdrill_mm)
    return from_json(ImplantSummary, {**doc, "seated": seated})


def implant_fields(
    result: PathResult,
) -> tuple[float | None, ImplantBindingLandmark | None, BoneWallsInfo | None]:
    """``implant_clearance_mm``, ``implant_binding_landmark`` and ``bone_walls`` of
    ``result``'s implant outcome (:func:`ctdrill.engine.implant.implant_outcome`); Nones
    without an implant."""
    out = result.implant
    if out is None:
        return None, None, None
    binding = None
    if out.binding_name is not None and out.binding_margin_mm is not None:
        binding = ImplantBindingLandmark(printable(out.binding_name), out.binding_margin_mm)
    walls = from_json(BoneWallsInfo, out.bone_walls_json())
    return _num(out.clearance_mm), binding, walls


def plan_outcome(result: PathResult, context: CaseContext, feed_mm_s: float) -> PlanOutcome:
    """The plan-level part of ``result``'s summary."""
    plan = result.plan
    lms = tuple(
        LandmarkClearance(
            name=printable(lm.name),
            kind=lm.kind,
            radius_mm=lm.radius_mm,
            margin_mm=float(result.margins_mm[j]),
            clearance_at_stop_mm=_num(float(result.stop_clearance_mm[j])),
        )
        for j, lm in enumerate(result.landmarks)
    )
    binding = result.binding_landmark
    settings = context.settings
    implant_clear, implant_binding, walls = implant_fields(result)
    accuracy = context.clearance_accuracy_mm
    if accuracy is None and result.implant is not None:
        accuracy = result.implant.accuracy_mm
    identity = series_identity(context.series_uid, include_phi=settings.include_phi)
    budget = summary_budget(result.budgets)
    return PlanOutcome(
        plan=printable(plan.name),
        plan_file=printable(Path(plan.source).name) if plan.source else None,
        planned_depth_mm=_num(result.planned_depth_mm),
        stop_depth_mm=_num(result.stop_depth_mm),
        stop_reason=result.stop_reason,
        max_safe_depth_mm=_num(result.max_safe_depth_mm),
        max_safe_depth_capped=result.max_safe_depth_capped,
        out_of_volume_depth_mm=_num(result.out_of_volume_depth_mm),
        min_clearance_mm=_num(result.min_clearance_mm),
        plan_clearance_mm=_num(result.plan_clearance_mm),
        binding_landmark=None if binding is None else lms[binding],
        margin_mm=plan.margin_mm,
        landmarks=lms,
        calibration=CalibrationInfo.of(result.calibration),
        hu_uncertainty=hu_uncertainty_info(context.hu_uncertainty),
        grey_to_hu=context.grey_to_hu,
        feed_mm_s=feed_mm_s,
        rate_hz=settings.rate_hz,
        entry_lps=tuple(plan.entry_lps.tolist()),
        target_lps=tuple(_nm(plan.planned_target_lps.tolist())),
        implant=implant_summary(result),
        implant_clearance_mm=implant_clear,
        implant_binding_landmark=implant_binding,
        bone_walls=walls,
        overdrill_mm=plan.overdrill_mm,
        clearance_accuracy_mm=_num(accuracy, 6),
        margin_budget_mm=None if budget is None else round(budget.budget_mm, 3),
        margin_budget=None if budget is None else from_json(MarginBudgetInfo, budget.to_json()),
        tooth_distance_mm=None if result.implant is None else _num(result.implant.tooth_mm),
        site=plan.site,
        series=SeriesIdentity(identity["series_uid"], identity["series_uid_sha256"]),
        include_phi=settings.include_phi,
        patient=context.patient,
    )


def job_summary(
    result: PathResult, context: CaseContext, verdict: PlanVerdict | None = None
) -> JobSummary:
    """One trajectory's force series, force band and summary, exactly as ``ctdrill export``
    writes them (``ctdrill report`` shows the same numbers); the feed is the settings'
    override, else the plan's. The warnings are ``verdict``'s findings (the trajectory's
    :class:`~ctdrill.engine.verdict.PlanVerdict`), else the path's own (one drill of a
    sequence)."""
    settings = context.settings
    feed = settings.feed_for(result.plan.feed_mm_s)
    series = force_time_series(
        result, feed_mm_s=feed, rate_hz=settings.rate_hz, feed_option=settings.feed_mm_s is not None
    )
    band = path_band(result, feed, context.hu_uncertainty)
    peak, note = band_peak(result, band, context.hu_uncertainty)
    prof = result.profile
    summary = TrajectorySummary(
        format=EXPORT_FORMAT,
        outcome=plan_outcome(result, context, feed),
        force_band=peak,
        force_band_note=note,
        duration_s=_num(float(series.time_s[-1]), 6),
        peak_force_n=_num(float(np.max(series.force_n)), 5),
        mean_force_n=_num(float(np.mean(series.force_n)), 5),
        drill=drill_info(result.plan.drill),
        depth_step_mm=_num(prof.step_mm, 6),
        extrapolation=Extrapolation(
            clipped_samples=prof.n_clipped,
            samples=prof.n_samples,
            share=_num(prof.n_clipped / prof.n_samples if prof.n_samples else 0.0, 6),
        ),
        hu_grading=hu_grading(prof.depth_mm, prof.hu_mean, result.stop_depth_mm),
        interpolated_gaps=tuple(
            GapInfo(
                lower_mm=round(g.lower_mm, 4),
                upper_mm=round(g.upper_mm, 4),
                nominal_step_mm=round(abs(g.nominal_step_mm), 4),
                depth_from_mm=round(g.depth_from_mm, 4),
                depth_to_mm=round(g.depth_to_mm, 4),
            )
            for g in result.interpolated_gaps
        ),
        warnings=tuple(result.warnings) if verdict is None else verdict.findings,
        inner_holes=tuple(hole_info(h) for h in result.inner_holes),
        plot=settings.plot,
    )
    return JobSummary(result, series, band, summary)


def sequence_summary(seq: SequenceResult, context: CaseContext) -> SequenceSummary:
    """The top-level summary of a drill sequence: the final drill's plan-level part, one
    entry per drill (each drill's numbers those of its own summary, the same functions
    computing them from the same path), every drill's warnings once."""
    steps = [job_summary(step, context).summary for step in seq.steps]
    return SequenceSummary(
        format=SEQUENCE_FORMAT,
        outcome=steps[-1].outcome,
        final_drill=len(steps),
        drills=tuple(drill_step(k, s) for k, s in enumerate(steps)),
        warnings=tuple(seq.warnings),
    )


def drill_step(index: int, s: TrajectorySummary) -> DrillStep:
    """Drill ``index`` (0-based) of a sequence in its listing, from its own summary ``s`` (the
    export's listing and the rehearsal's read the same code)."""
    return DrillStep(
        drill=index + 1,
        folder=drill_folder(index),
        spec=s.drill,
        planned_depth_mm=s.outcome.planned_depth_mm,
        stop_depth_mm=s.outcome.stop_depth_mm,
        stop_reason=s.outcome.stop_reason,
        max_safe_depth_mm=s.outcome.max_safe_depth_mm,
        min_clearance_mm=s.outcome.min_clearance_mm,
        peak_force_n=s.peak_force_n,
        mean_force_n=s.mean_force_n,
        force_band=s.force_band,
        inner_holes=s.inner_holes,
    )
