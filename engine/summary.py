"""The summary of a case, as one typed value: what ``summary.json`` holds, field by field.

A trajectory's summary (:class:`TrajectorySummary`, ``ctdrill-export/1``) is built once
(:func:`ctdrill.engine.summarize.job_summary`) and written once (:func:`to_json`); every
output and reader (``summary.json``, ``trajectories.csv``, the drill sequence's listing, the
terminal lines, the report, ``ctdrill.api``) reads its attributes. The fields are the JSON
keys, in order (:mod:`ctdrill.engine.record`); a new summary field is one field here and one
value in :mod:`ctdrill.engine.summarize`.

:class:`PlanOutcome` is the plan-level part, shared by a sequence's listing
(:class:`SequenceSummary`, ``ctdrill-sequence/1``), which takes it from the final drill.
Values are as written: depths and clearances rounded to 0.1 um, forces to 10 uN.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from ctdrill.engine.record import added, flat, from_json, key, optional, to_json
from ctdrill.model.calibration import Calibration
from ctdrill.warning_codes import LoadWarning

EXPORT_FORMAT = "ctdrill-export/1"
SEQUENCE_FORMAT = "ctdrill-sequence/1"
#: A rehearsal's ``summary.json`` says ``"rehearsal": REHEARSAL_FORMAT`` beside the export's
#: ``format`` (:mod:`ctdrill.engine.rehearsal_summary`).
REHEARSAL_FORMAT = "ctdrill-rehearsal/1"
#: Said when a set has no ``provenance.method`` (sets written before it).
METHOD_NOT_STATED = "not stated by the set (see its source)"


@dataclass(frozen=True)
class LandmarkClearance:
    """One landmark of the plan and the drill's clearance to it at the stop, mm."""

    name: str
    kind: str
    radius_mm: float
    margin_mm: float
    clearance_at_stop_mm: float | None


@dataclass(frozen=True)
class CalibrationInfo:
    """Which calibration set, and how it was obtained (every output says so)."""

    name: str = field(metadata=key("calibration"))
    illustrative: bool = field(metadata=key("calibration_illustrative"))
    source: str = field(metadata=key("calibration_source"))
    method: str = field(metadata=key("calibration_method"))
    covariance: bool = field(metadata=key("calibration_covariance"))

    @staticmethod
    def of(cal: Calibration) -> CalibrationInfo:
        """The fields of ``cal`` (``method`` :data:`METHOD_NOT_STATED` when it has none)."""
        return CalibrationInfo(
            name=cal.name,
            illustrative=cal.illustrative,
            source=cal.source,
            method=cal.method or METHOD_NOT_STATED,
            covariance=cal.covariance is not None,
        )


@dataclass(frozen=True)
class HuUncertaintyInfo:
    """The series' HU uncertainty entered into the force band: where from, its SD."""

    source: str
    sd_hu_at_0_hu: float | None
    sd_hu_at_1000_hu: float | None


@dataclass(frozen=True)
class GreyRegionInfo:
    """A region of known HU the grey map was measured on (``--grey-ref``)."""

    center_lps_mm: tuple[float, ...]
    radius_mm: float
    known_hu: float
    mean_grey: float
    sd_grey: float
    voxels: int


@dataclass(frozen=True)
class GreyMapInfo:
    """The grey-to-HU map applied to the series as loaded (``--grey-to-hu``/``--grey-ref``):
    ``HU = slope x grey + intercept``, its standard errors when known, how it was obtained."""

    slope: float
    intercept: float
    slope_se: float | None
    intercept_se: float | None
    slope_intercept_cov: float | None
    method: str
    regions: tuple[GreyRegionInfo, ...]


@dataclass(frozen=True)
class ImplantSummary:
    """The implant placed on the trajectory and whether the drill's stop seats it."""

    name: str
    diameter_mm: float
    length_mm: float
    apex_diameter_mm: float
    apex: str
    platform_lps: tuple[float, ...]
    apex_lps: tuple[float, ...]
    axis_lps: tuple[float, ...]
    platform_depth_mm: float
    apex_depth_mm: float
    seated: bool


@dataclass(frozen=True)
class ImplantBindingLandmark:
    """The landmark nearest the implant body for its margin (least ``clearance - margin``)."""

    name: str
    margin_mm: float


@dataclass(frozen=True)
class PerforationInfo:
    """Where the implant surface leaves bone (more than 1 mm below the platform): depths from
    the entry and below the platform (shallowest, deepest), the shallowest exposed point, the
    mean outward direction (LPS), the exposed share of the surface."""

    depth_mm: tuple[float, ...]
    below_platform_mm: tuple[float, ...]
    point_lps: tuple[float, ...]
    direction_lps: tuple[float, ...]
    fraction: float


@dataclass(frozen=True)
class BoneWallsInfo:
    """The thinnest bone wall around the implant body (:mod:`ctdrill.imaging.sampling.walls`).

    ``min_mm`` at ``depth_mm`` from the entry (``below_platform_mm`` from the platform)
    towards ``direction_lps``; ``buccal_mm``/``lingual_mm`` with a dental arch (else None);
    ``capped``: every known wall reaches the ray's end; ``unknown_fraction`` of the rays leave
    the CT first (``outside_ct`` states the rule); ``bone_hu`` is where bone ends.
    """

    min_mm: float | None
    depth_mm: float | None
    below_platform_mm: float | None
    direction_lps: tuple[float, ...] | None
    buccal_mm: float | None
    lingual_mm: float | None
    capped: bool
    unknown_fraction: float
    perforation: PerforationInfo | None
    bone_hu: float
    outside_ct: str


@dataclass(frozen=True)
class MarginBudgetInfo:
    """The margin budget and its three 95th-percentile terms, mm
    (:mod:`ctdrill.imaging.plan.budget`)."""

    budget_mm: float
    placement: str
    canal_source: str
    voxel_mm: float
    placement_mm: float
    canal_mm: float
    ct_mm: float


@dataclass(frozen=True)
class SeriesIdentity:
    """The series: the SHA-256 of its UID, the raw UID only with ``include_phi``."""

    series_uid: str
    series_uid_sha256: str


@dataclass(frozen=True)
class PlanOutcome:
    """What the plan is and where its drill stops (a sequence's: the final drill's).

    Attributes
    ----------
    plan, plan_file : the trajectory's name and its file's name.
    site : the implant site, an FDI tooth number (plan key ``site``), or None.
    planned_depth_mm, stop_depth_mm : mm; ``stop_reason`` ``planned_depth`` | ``margin`` |
        ``out_of_volume``.
    max_safe_depth_mm : deepest depth keeping every margin; ``max_safe_depth_capped``: the
        search stopped past the planned depth ("at least this deep").
    out_of_volume_depth_mm : where the lip leaves the scan, or None.
    min_clearance_mm : smallest clearance down to the stop; ``plan_clearance_mm`` over the
        planned path (None without landmarks).
    binding_landmark : the landmark whose margin binds (else nearest at the stop), or None.
    margin_mm : the plan's margin; ``landmarks`` each landmark's.
    calibration : which set and how obtained (flattened: ``calibration``, ...).
    hu_uncertainty, grey_to_hu : the band's HU error and the grey map, or None.
    feed_mm_s, rate_hz : the force series' feed and sample rate.
    entry_lps, target_lps : the trajectory, LPS mm.
    implant : its placement and seat, or None.
    implant_clearance_mm : signed distance from the implant body at its placement to the
        binding landmark, mm (< 0 inside; None without an implant or landmarks);
        ``implant_binding_landmark`` that landmark's name and margin.
    bone_walls : the thinnest bone walls around the implant body, or None without one.
    overdrill_mm : how far the drill's planned depth lies beyond the plan's target (the
        implant's apex): the drill's tip length with an implant, else 0.
    clearance_accuracy_mm : what the CT's sampling lets a clearance claim, +- mm (half its
        coarsest sampling; text for people prints clearances to it), or None when unknown.
    series : the series' identity (flattened); ``include_phi``; ``patient`` only with it.
    margin_budget_mm : the clearance the 95th percentile of the placement, canal and CT errors
        needs (the largest landmark's; ``margin_budget`` its terms), or None without
        landmarks; warning ``margin_below_budget`` under it. ``tooth_distance_mm``: implant to
        the nearest tooth (negative: in it), None without an implant or a tooth near.
    """

    plan: str
    plan_file: str | None
    planned_depth_mm: float | None
    stop_depth_mm: float | None
    stop_reason: str
    max_safe_depth_mm: float | None
    max_safe_depth_capped: bool
    out_of_volume_depth_mm: float | None
    min_clearance_mm: float | None
    plan_clearance_mm: float | None
    binding_landmark: LandmarkClearance | None
    margin_mm: float
    landmarks: tuple[LandmarkClearance, ...]
    calibration: CalibrationInfo = field(metadata=flat())
    hu_uncertainty: HuUncertaintyInfo | None
    grey_to_hu: GreyMapInfo | None
    feed_mm_s: float
    rate_hz: float
    entry_lps: tuple[float, ...]
    target_lps: tuple[float, ...]
    implant: ImplantSummary | None
    implant_clearance_mm: float | None = field(metadata=added())
    implant_binding_landmark: ImplantBindingLandmark | None = field(metadata=added())
    bone_walls: BoneWallsInfo | None = field(metadata=added())
    overdrill_mm: float = field(metadata=added(0.0))
    clearance_accuracy_mm: float | None = field(metadata=added())
    site: int | None = field(metadata=added())
    margin_budget_mm: float | None = field(metadata=added())
    margin_budget: MarginBudgetInfo | None = field(metadata=added())
    tooth_distance_mm: float | None = field(metadata=added())
    series: SeriesIdentity = field(metadata=flat())
    include_phi: bool
    patient: Mapping[str, str] | None = field(default=None, metadata=optional())


@dataclass(frozen=True)
class ForceBandPeak:
    """The 68 % band of the mean cutting force at its peak down to the stop depth."""

    level: float
    feed_mm_s: float
    method: str
    peak_depth_mm: float | None
    peak_mean_force_n: float | None
    peak_lo_n: float | None
    peak_hi_n: float | None
    peak_sd_log: float | None
    peak_sd_log_calibration: float | None
    peak_sd_log_hu: float | None


@dataclass(frozen=True)
class DrillInfo:
    """The drill, by its plan-file keys; ``tip_length_mm`` is the tip rule's for the diameter
    and point angle unless ``tip_override`` (a tip given that differs, warning
    ``drill_tip_override``)."""

    diameter_mm: float
    tip_length_mm: float
    blades: int
    rpm: float
    point_angle_deg: float = field(metadata=added(120.0))
    tip_override: bool = field(metadata=added(False))


@dataclass(frozen=True)
class Extrapolation:
    """Cut lip samples whose C' lies outside the calibration's range (clipped to it)."""

    clipped_samples: int
    samples: int
    share: float | None


@dataclass(frozen=True)
class HuSegment:
    """The integral mean of the lip-mean HU over one segment of the path, its Misch class."""

    from_mm: float
    to_mm: float
    mean_hu: float | None
    misch: str | None


@dataclass(frozen=True)
class HuGrading:
    """The path down to the stop: each Misch class's share of the depths, and the mean HU of
    :data:`~ctdrill.engine.grading.N_HU_SEGMENTS` equal segments."""

    misch_share: Mapping[str, float]
    segments: tuple[HuSegment, ...]


@dataclass(frozen=True)
class GapInfo:
    """A slice gap interpolated across on request (``--interpolate-gaps``)."""

    lower_mm: float
    upper_mm: float
    nominal_step_mm: float
    depth_from_mm: float
    depth_to_mm: float


@dataclass(frozen=True)
class HoleInfo:
    """A hole an earlier drill of a sequence left, which this drill's profile cut around."""

    diameter_mm: float
    tip_length_mm: float
    depth_mm: float


@dataclass(frozen=True)
class TrajectorySummary:
    """One trajectory's ``summary.json`` (``format`` :data:`EXPORT_FORMAT`).

    Attributes
    ----------
    outcome : the plan-level part (flattened into the document).
    force_band : the band at the peak mean force, or None; ``force_band_note`` says what it
        includes or why there is none.
    duration_s, peak_force_n, mean_force_n : the force series at constant feed.
    drill : the drill; ``depth_step_mm`` the profile's depth step.
    extrapolation, hu_grading, interpolated_gaps, warnings : as named.
    inner_holes : a drill of a sequence: the holes its profile cut around (else left out).
    plot : whether ``force.png`` was written (left out when no files are).
    """

    format: str
    outcome: PlanOutcome = field(metadata=flat())
    force_band: ForceBandPeak | None
    force_band_note: str
    duration_s: float | None
    peak_force_n: float | None
    mean_force_n: float | None
    drill: DrillInfo
    depth_step_mm: float | None
    extrapolation: Extrapolation
    hu_grading: HuGrading
    interpolated_gaps: tuple[GapInfo, ...]
    warnings: tuple[LoadWarning, ...]
    inner_holes: tuple[HoleInfo, ...] = field(default=(), metadata=optional())
    plot: bool | None = field(default=None, metadata=optional())

    def to_json(self) -> dict[str, Any]:
        """The ``summary.json`` document."""
        return to_json(self)

    @staticmethod
    def from_json(doc: Mapping[str, Any]) -> TrajectorySummary:
        """The summary a ``summary.json`` of format :data:`EXPORT_FORMAT` holds."""
        return from_json(TrajectorySummary, doc)


@dataclass(frozen=True)
class DrillStep:
    """One drill of a sequence in its listing: its folder, geometry, planned depth (with an
    implant the apex's plus its tip length), stop and forces."""

    drill: int
    folder: str
    spec: DrillInfo = field(metadata=flat())
    planned_depth_mm: float | None = field(metadata=added())
    stop_depth_mm: float | None
    stop_reason: str
    max_safe_depth_mm: float | None
    min_clearance_mm: float | None
    peak_force_n: float | None
    mean_force_n: float | None
    force_band: ForceBandPeak | None
    inner_holes: tuple[HoleInfo, ...]


@dataclass(frozen=True)
class SequenceSummary:
    """A drill sequence's top-level ``summary.json`` (``format`` :data:`SEQUENCE_FORMAT`): the
    final drill's plan-level part, one entry per drill in drilling order, every drill's
    warnings once."""

    format: str
    outcome: PlanOutcome = field(metadata=flat())
    final_drill: int
    drills: tuple[DrillStep, ...]
    warnings: tuple[LoadWarning, ...]

    def to_json(self) -> dict[str, Any]:
        """The ``summary.json`` document."""
        return to_json(self)

    @staticmethod
    def from_json(doc: Mapping[str, Any]) -> SequenceSummary:
        """The summary a ``summary.json`` of format :data:`SEQUENCE_FORMAT` holds."""
        return from_json(SequenceSummary, doc)


def read_summary(doc: Mapping[str, Any]) -> TrajectorySummary | SequenceSummary:
    """A written ``summary.json`` document as its summary (by its ``format``)."""
    if doc.get("format") == SEQUENCE_FORMAT:
        return SequenceSummary.from_json(doc)
    return TrajectorySummary.from_json(doc)
