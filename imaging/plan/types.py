"""Drill plans: ``ctdrill-plan/1`` JSON and 3D Slicer markups (``.mrk.json``), in LPS mm.

Everything is converted to LPS at this boundary (RAS: x and y negated) and validated once;
the rest of the code trusts a :class:`Plan`.

Slicer markups (``.mrk.json``, :mod:`ctdrill.imaging.plan.slicer`): **Line** markups are
trajectories (first control point the entry, second the target); **Curve** markups are canals
whose centreline is the spline Slicer draws through their control points
(:mod:`ctdrill.imaging.plan.curve`); **Fiducial** markups are point landmarks, one per control
point, named by its label; other types are skipped with a warning. Settings are ``key=value``
words in the first control point's description, where Slicer keeps them
(:mod:`ctdrill.imaging.plan.settings`), e.g. ``name="IAN canal" radius_mm=1.5 margin_mm=2.5``
on a curve, ``diameter_mm=2.0 tip_length_mm=0.6 blades=2 rpm=900 feed_mm_s=0.4
calibration="NAME" margin_mm=2.0`` on the line; a curve without ``radius_mm`` gets
:data:`~ctdrill.imaging.plan.landmarks.DEFAULT_CANAL_RADIUS_MM` (1.2 mm, a ``plan_default``
note) and the drill defaults are those of :class:`DrillSpec`. Slicer saves one markup per file:
several files (or a folder) merge into plans (:mod:`ctdrill.imaging.plan.merge`).

This module holds the value types and the format's constants only; files are read by
:mod:`ctdrill.imaging.plan.load` (:func:`~ctdrill.imaging.plan.load.load_plan`,
``load_plans``, ``load_plan_set``, ``load_one_plan``) and written by
:mod:`ctdrill.imaging.plan.write` (``save_plan``, ``write_plans``, ``plan_to_dict``,
``plan_to_markups``), both above it.
"""

from __future__ import annotations

import hashlib
import re
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from ctdrill.imaging.bounds import MAX_COORDINATE_MM as MAX_COORDINATE_MM
from ctdrill.imaging.errors import ImagingInputError
from ctdrill.imaging.plan.arch import arch_error
from ctdrill.imaging.plan.budget import DEFAULT_PLACEMENT, placement_error
from ctdrill.imaging.plan.clinical import CLINICAL_MARGIN_MM, CLINICAL_MIN_WALL_MM
from ctdrill.imaging.plan.drill_spec import MAX_DRILLS as MAX_DRILLS
from ctdrill.imaging.plan.drill_spec import DrillSpec, protocol_conflicts, sequence_error
from ctdrill.imaging.plan.implants import ImplantSpec
from ctdrill.imaging.plan.landmarks import (
    Landmark,
)
from ctdrill.imaging.plan.site import site_error
from ctdrill.warning_codes import LoadWarning

PLAN_FORMAT = "ctdrill-plan/1"
#: Calibration used when a plan names none (patient CT): the literature fit, with its covariance
#: (docs/model.md). ``bone-illustrative`` stays available by name.
DEFAULT_CALIBRATION = "bone-literature"
#: A plan's safety margin when it gives none: the clinical margin.
DEFAULT_MARGIN_MM = CLINICAL_MARGIN_MM
#: A trajectory's thinnest bone wall when it gives no ``min_wall_mm``: the clinical one.
DEFAULT_MIN_WALL_MM = CLINICAL_MIN_WALL_MM
#: Plan key recording the series a plan was made on: :func:`series_uid_hash` of its UID.
SERIES_HASH_KEY = "series_uid_sha256"
_SERIES_HASH_RE = re.compile(r"[0-9a-f]{64}")
DEFAULT_FEED_MM_S = 0.4
#: Most trajectories a plan (one file, or the files merged into one plan) may hold: a full
#: mouth has 32 teeth; twice that leaves room for alternatives. Work grows with it (each
#: trajectory is a path, a table row, a report page and with --per-trajectory ~2 MB of files),
#: so more is refused when read and when written, naming the count.
MAX_TRAJECTORIES = 64
_SLICER_SCHEMA = (
    "https://raw.githubusercontent.com/slicer/slicer/master/Modules/Loadable/Markups/"
    "Resources/Schema/markups-schema-v1.0.3.json#"
)
#: Largest accepted value per numeric field: far beyond any real plan, small enough that no
#: arithmetic on it overflows (a typo or a unit error is refused, not computed with).
_MAXIMA = {
    "diameter_mm": 50.0,
    "tip_length_mm": 50.0,
    "rpm": 1e6,
    "feed_mm_s": 1000.0,
    "margin_mm": 1000.0,
    "min_wall_mm": 1000.0,
    "radius_mm": 1000.0,
}


class PlanInputError(ImagingInputError):
    """A plan file that cannot be used; the message names the file and the field path."""


@dataclass(frozen=True, eq=False)
class Plan:
    """One planned osteotomy, LPS mm.

    Attributes
    ----------
    entry_lps, target_lps : (3,) read-only float64; depth 0 is the entry point.
    drill : the final drill: it makes the final osteotomy, its clearance and stop rule the
        plan.
    earlier_drills : the drills drilled before ``drill`` along the same axis, in drilling order
        (a pilot 2.0 mm, then 2.8 ...); empty for a single-drill plan. Diameters strictly
        increase along :attr:`drills`. Use :meth:`with_drills` to set a whole sequence;
        ``replace(plan, drill=d)`` changes the final drill only.
    feed_mm_s : feed rate for exports and rehearsal, mm/s.
    calibration : calibration set name (``assets/calibration/``) or path.
    margin_mm : safety margin to every landmark without its own ``margin_mm``.
    landmarks : the structures to protect.
    name : a short label (the file stem, or the Slicer line's name).
    source : the file it was read from ("" if built in code).
    notes : defaults the reader filled in that the user should know (e.g. a canal radius).
    warnings : other warnings from reading it (e.g. ``markups_skipped``);
        :func:`plan_warnings` gives all of them.
    series_uid_sha256 : :func:`series_uid_hash` of the series the plan was made on, or None
        (a plan written by hand or by an older ctdrill).
    implant : the implant placed on this trajectory (apex at the target,
        :func:`ctdrill.imaging.plan.implants.implant_placement`), or None.
    arch_lps : (K, 3) read-only float64, the dental arch polyline (K >= 2, consecutive points
        distinct; :mod:`ctdrill.imaging.plan.arch`), shared by every trajectory of a plan
        like the landmarks; None when the plan gives none.
    min_wall_mm : thinnest bone wall to keep around the implant, mm (plan key ``min_wall_mm``,
        default :data:`DEFAULT_MIN_WALL_MM`; warning ``thin_wall`` below it).
    placement : how the implant will be placed (``freehand``, ``static`` guide, ``dynamic``
        navigation, ``robot``): the margin budget's placement error
        (:mod:`ctdrill.imaging.plan.budget`; plan key ``placement``, ``--placement``).
    site : the implant site, an FDI tooth number 11-48 (:mod:`ctdrill.imaging.plan.site`),
        or None.
    overdrill_mm : how far ``target_lps`` lies beyond the plan's target (the implant's apex,
        :attr:`planned_target_lps`): 0 for a plan as drawn; for a drill as it is drilled for
        the implant (:meth:`drilled`) the drill's tip length, so that the drill's full diameter
        reaches the apex and its tip goes beyond.
    """

    entry_lps: np.ndarray
    target_lps: np.ndarray
    drill: DrillSpec = field(default_factory=DrillSpec)
    feed_mm_s: float = DEFAULT_FEED_MM_S
    calibration: str = DEFAULT_CALIBRATION
    margin_mm: float = DEFAULT_MARGIN_MM
    landmarks: tuple[Landmark, ...] = ()
    name: str = "plan"
    source: str = ""
    notes: tuple[str, ...] = ()
    warnings: tuple[LoadWarning, ...] = ()
    series_uid_sha256: str | None = None
    earlier_drills: tuple[DrillSpec, ...] = ()
    implant: ImplantSpec | None = None
    arch_lps: np.ndarray | None = None
    min_wall_mm: float = DEFAULT_MIN_WALL_MM
    site: int | None = None
    overdrill_mm: float = 0.0
    placement: str = DEFAULT_PLACEMENT

    def __post_init__(self) -> None:
        for attr in ("entry_lps", "target_lps"):
            arr = np.array(getattr(self, attr), dtype=np.float64).reshape(3)
            arr.flags.writeable = False
            object.__setattr__(self, attr, arr)
        if self.arch_lps is not None:
            problem = arch_error(self.arch_lps, MAX_COORDINATE_MM)
            if problem is not None:
                raise PlanInputError(f"plan {self.name!r}: arch{problem}")
            arch = np.array(self.arch_lps, dtype=np.float64).reshape(-1, 3)
            arch.flags.writeable = False
            object.__setattr__(self, "arch_lps", arch)
        if self.implant is not None and not isinstance(self.implant, ImplantSpec):
            raise PlanInputError(f"plan {self.name!r}: implant must be an ImplantSpec or None")
        object.__setattr__(self, "landmarks", tuple(self.landmarks))
        object.__setattr__(self, "earlier_drills", tuple(self.earlier_drills))
        problem = sequence_error(self.drills)
        if problem is not None:
            raise PlanInputError(f"plan {self.name!r}: drills{problem}")
        if self.implant is not None and self.implant.drills:
            self._reconcile_drills(self.implant)
        wall = self.min_wall_mm
        if isinstance(wall, bool) or not (isinstance(wall, int | float) and 0.0 <= wall <= 1e3):
            raise PlanInputError(f"plan {self.name!r}: min_wall_mm must be a number 0-1000 mm")
        object.__setattr__(self, "min_wall_mm", float(wall))
        if self.site is not None:
            bad = site_error(self.site)
            if bad is not None:
                raise PlanInputError(f"plan {self.name!r}: site {bad}, got {self.site!r}")
            object.__setattr__(self, "site", int(self.site))
        bad = placement_error(self.placement)
        if bad is not None:
            raise PlanInputError(f"plan {self.name!r}: placement {bad}")
        over = self.overdrill_mm
        if not over >= 0.0 or (
            over > 0.0 and (self.implant is None or not over < self.planned_depth_mm)
        ):
            raise PlanInputError(
                f"plan {self.name!r}: overdrill_mm must be >= 0, shorter than the path, and 0 "
                "without an implant"
            )

    def _reconcile_drills(self, implant: ImplantSpec) -> None:
        """Give each drill that contradicts ``implant``'s protocol (the same diameter with
        another tip or point angle) the protocol's, with a ``drills_reconciled`` warning: a
        plan never holds (nor saves) drills that contradict its implant."""
        conflicts = protocol_conflicts(self.drills, implant.drills)
        if not conflicts:
            return
        seq = list(self.drills)
        notes = []
        for i, d, p in conflicts:
            seq[i] = replace(d, tip_length_mm=p.tip_length_mm, point_angle_deg=p.point_angle_deg)
            notes.append(
                LoadWarning(
                    "drills_reconciled",
                    f"plan {self.name!r}: drills[{i}] (the {d.name}) had a "
                    f"{d.tip_length_mm:g} mm tip, but implant {implant.name!r}'s protocol "
                    f"drills it with {p.tip_length_mm:g} mm: using the protocol's tip (edit "
                    "the implant's drills to change it)",
                )
            )
        object.__setattr__(self, "drill", seq[-1])
        object.__setattr__(self, "earlier_drills", tuple(seq[:-1]))
        object.__setattr__(self, "warnings", (*self.warnings, *notes))

    @property
    def drills(self) -> tuple[DrillSpec, ...]:
        """Every drill in drilling order; the last is :attr:`drill` (``(drill,)`` for one)."""
        return (*self.earlier_drills, self.drill)

    def with_drills(self, drills: Sequence[DrillSpec]) -> Plan:
        """This plan drilled with the sequence ``drills`` (drilling order; the last is final).

        Raises
        ------
        PlanInputError
            An empty list, or diameters that do not strictly increase.
        """
        seq = tuple(drills)
        problem = sequence_error(seq)
        if problem is not None:
            raise PlanInputError(f"plan {self.name!r}: drills{problem}")
        whole = replace(self, target_lps=self.planned_target_lps, overdrill_mm=0.0)
        return replace(whole, drill=seq[-1], earlier_drills=seq[:-1])

    def for_drill(self, index: int) -> Plan:
        """The single-drill plan of drill ``index`` (0-based) of the sequence: the same axis,
        target, landmarks and settings with that drill alone (its own clearance and stop).

        Its tip is planned at the plan's target. With an implant, the drill as it is drilled
        for the implant (its tip beyond the apex) is :meth:`drilled`.
        """
        return replace(self, drill=self.drills[index], earlier_drills=())

    def drilled(self, index: int) -> Plan:
        """Drill ``index`` (0-based) alone, as it is drilled for the plan's implant.

        The plan's target is the implant's apex and the drill's full diameter reaches it: its
        tip goes beyond by the drill's tip length, so the result's ``target_lps`` (the planned
        tip position) and ``planned_depth_mm`` are the apex's plus that tip length
        (:attr:`overdrill_mm`), while :attr:`planned_target_lps` and the implant's placement
        stay at the apex. Without an implant it is :meth:`for_drill`.
        """
        drill = self.drills[index]
        if self.implant is None:
            return replace(self, drill=drill, earlier_drills=())
        over = drill.tip_length_mm
        tip = self.planned_target_lps + over * self.direction
        return replace(self, drill=drill, earlier_drills=(), target_lps=tip, overdrill_mm=over)

    def drill_depths_mm(self) -> tuple[float, ...]:
        """Each drill's planned depth (its tip's, :meth:`drilled`), in drilling order, mm."""
        return tuple(self.drilled(k).planned_depth_mm for k in range(len(self.drills)))

    @property
    def planned_depth_mm(self) -> float:
        """``|target - entry|``: the drill tip's planned depth, mm (for a drill's view of an
        implant plan, the apex's depth plus the drill's tip length)."""
        return float(np.linalg.norm(self.target_lps - self.entry_lps))

    @property
    def planned_target_lps(self) -> np.ndarray:
        """(3,) the plan's target as drawn, LPS mm: the implant's apex when it places one
        (``target_lps`` less :attr:`overdrill_mm` along the axis)."""
        if self.overdrill_mm == 0.0:
            return self.target_lps
        out: np.ndarray = self.target_lps - self.overdrill_mm * self.direction
        return out

    @property
    def direction(self) -> np.ndarray:
        """(3,) unit vector from entry to target."""
        out: np.ndarray = (self.target_lps - self.entry_lps) / self.planned_depth_mm
        return out

    def landmark_margin_mm(self, landmark: Landmark) -> float:
        """The margin that applies to ``landmark`` (its own, else the plan's), mm."""
        return self.margin_mm if landmark.margin_mm is None else float(landmark.margin_mm)

    def point_at_depth_lps(self, depth_mm: float) -> np.ndarray:
        """(3,) LPS point on the axis at ``depth_mm`` from the entry."""
        out: np.ndarray = self.entry_lps + depth_mm * self.direction
        return out


def series_uid_hash(series_uid: str) -> str:
    """The hash a plan records of a SeriesInstanceUID (64 hex digits; never the UID itself).

    SHA-256 of ``"ctdrill-series/1:" + uid`` (UTF-8), so equal UIDs give equal hashes and the
    plan file does not carry the identifier.
    """
    return hashlib.sha256(f"ctdrill-series/1:{series_uid.strip()}".encode()).hexdigest()


def is_series_hash(value: object) -> bool:
    """True for a well-formed :func:`series_uid_hash` value (64 lower-case hex digits)."""
    return isinstance(value, str) and _SERIES_HASH_RE.fullmatch(value) is not None


def plan_warnings(plan: Plan) -> tuple[LoadWarning, ...]:
    """The warnings of everything the user must know about ``plan`` itself.

    ``plan_default`` for each default the reader filled in, the reader's own warnings
    (``markups_skipped``, ``implant_protocol``), and ``no_landmarks`` when nothing is
    protected: the drill then stops only at the planned depth or where the volume ends.
    (Whether the final drill suits the implant is a check of the whole plan, not of one
    drill's plan: :func:`~ctdrill.imaging.plan.protocol.final_drill_warnings`.)
    """
    out = [LoadWarning("plan_default", note) for note in plan.notes]
    out += list(plan.warnings)
    if not plan.landmarks:
        out.append(
            LoadWarning(
                "no_landmarks",
                f"plan {plan.name!r} has no landmark: no safety margin is enforced, the drill "
                "stops only at the planned depth; add the canal (a Curve, a segmentation or "
                "a landmark in the plan)",
            )
        )
    return tuple(out)
