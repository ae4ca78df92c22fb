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
several files (or a folder) merge into plans (:func:`load_plan_set`,
:mod:`ctdrill.imaging.plan.merge`).
"""

from __future__ import annotations

import hashlib
import os
import re
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from ctdrill.imaging.errors import ImagingInputError
from ctdrill.imaging.plan.arch import arch_error
from ctdrill.imaging.plan.drill_spec import MAX_DRILLS as MAX_DRILLS
from ctdrill.imaging.plan.drill_spec import DrillSpec, sequence_error
from ctdrill.imaging.plan.implants import ImplantSpec
from ctdrill.imaging.plan.landmarks import (
    Landmark,
)
from ctdrill.imaging.plan.site import site_error

PLAN_FORMAT = "ctdrill-plan/1"
#: Calibration used when a plan names none (patient CT): the literature fit, with its covariance
#: (docs/model.md). ``bone-illustrative`` stays available by name.
DEFAULT_CALIBRATION = "bone-literature"
#: Clinical safety margin to the inferior alveolar nerve canal, mm (DESIGN.md section 5): its
#: one owner. Margins below it are reported (warning ``margin_below_clinical``).
CLINICAL_MARGIN_MM = 2.0
DEFAULT_MARGIN_MM = CLINICAL_MARGIN_MM
#: Thinnest bone wall to keep around an implant, mm (DESIGN.md section 5: at least 1.5 mm of
#: bone around the implant, buccal above all): its one owner, the default of ``min_wall_mm``.
#: Thinner walls are reported (warning ``thin_wall``).
CLINICAL_MIN_WALL_MM = 1.5
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
#: Largest accepted coordinate magnitude, mm (the plan reader's; the engine refuses a trajectory
#: or landmark point beyond it built in code).
MAX_COORDINATE_MM = 1e5


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
    warnings : other ``(code, message)`` pairs from reading it (e.g. ``markups_skipped``);
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
    warnings: tuple[tuple[str, str], ...] = ()
    series_uid_sha256: str | None = None
    earlier_drills: tuple[DrillSpec, ...] = ()
    implant: ImplantSpec | None = None
    arch_lps: np.ndarray | None = None
    min_wall_mm: float = DEFAULT_MIN_WALL_MM
    site: int | None = None
    overdrill_mm: float = 0.0

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
        wall = self.min_wall_mm
        if isinstance(wall, bool) or not (isinstance(wall, int | float) and 0.0 <= wall <= 1e3):
            raise PlanInputError(f"plan {self.name!r}: min_wall_mm must be a number 0-1000 mm")
        object.__setattr__(self, "min_wall_mm", float(wall))
        if self.site is not None:
            bad = site_error(self.site)
            if bad is not None:
                raise PlanInputError(f"plan {self.name!r}: site {bad}, got {self.site!r}")
            object.__setattr__(self, "site", int(self.site))
        over = self.overdrill_mm
        if not over >= 0.0 or (
            over > 0.0 and (self.implant is None or not over < self.planned_depth_mm)
        ):
            raise PlanInputError(
                f"plan {self.name!r}: overdrill_mm must be >= 0, shorter than the path, and 0 "
                "without an implant"
            )

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


# --------------------------------------------------------------------------- public API


def load_plans(path: str | os.PathLike[str]) -> tuple[Plan, ...]:
    """Read every trajectory of a plan file, converted to LPS and validated.

    A ``ctdrill-plan/1`` file holds one trajectory, or several in ``trajectories``; a Slicer
    ``.mrk.json`` holds one per Line markup (all sharing the file's landmarks and arch).

    Raises
    ------
    PlanInputError
        Naming the file and the field path (``plan.json: drill.diameter_mm must be ...``).
    """
    from ctdrill.imaging.plan.read import read_plans

    return read_plans(path)


def load_plan_set(paths: Sequence[str | os.PathLike[str]]) -> tuple[Plan, ...]:
    """Read several plan files (or folders of them) and merge them into plans.

    Every file's landmarks protect every trajectory; a trajectory or landmark given by two
    files must agree (see :mod:`ctdrill.imaging.plan.merge`).
    """
    from ctdrill.imaging.plan.merge import load_merged

    return load_merged(paths)


def load_one_plan(paths: Sequence[str | os.PathLike[str]], trajectory: str | None = None) -> Plan:
    """:func:`load_plan_set` for commands that drill one trajectory (rehearse).

    ``trajectory`` picks one of several by its name, or by its number (1-based, in the order
    :func:`load_plan_set` gives them); None requires the files to hold exactly one.
    """
    plans = load_plan_set(paths)
    names = ", ".join(f"{i + 1}: {p.name!r}" for i, p in enumerate(plans))
    if trajectory is not None:
        for p in plans:
            if p.name == trajectory:
                return p
        if trajectory.strip().isdigit() and 1 <= int(trajectory) <= len(plans):
            return plans[int(trajectory) - 1]
        raise PlanInputError(
            f"--trajectory {trajectory!r}: the plan files hold no trajectory of that name or "
            f"number; they hold {names}"
        )
    if len(plans) != 1:
        raise PlanInputError(
            f"the plan files hold {len(plans)} trajectories ({names}); pick one with "
            "--trajectory NAME (or its number)"
        )
    return plans[0]


def plan_warnings(plan: Plan) -> tuple[tuple[str, str], ...]:
    """``(code, message)`` of everything the user must know about ``plan`` itself.

    ``plan_default`` for each default the reader filled in, the reader's own warnings
    (``markups_skipped``, ``implant_protocol``), and ``no_landmarks`` when nothing is
    protected: the drill then stops only at the planned depth or where the volume ends.
    (Whether the final drill suits the implant is a check of the whole plan, not of one
    drill's plan: :func:`~ctdrill.imaging.plan.protocol.final_drill_warnings`.)
    """
    out = [("plan_default", note) for note in plan.notes]
    out += list(plan.warnings)
    if not plan.landmarks:
        out.append(
            (
                "no_landmarks",
                f"plan {plan.name!r} has no landmark: no safety margin is enforced, the drill "
                "stops only at the planned depth; add the canal (a Curve, a segmentation or "
                "a landmark in the plan)",
            )
        )
    return tuple(out)


def load_plan(path: str | os.PathLike[str]) -> Plan:
    """Read a plan file holding exactly one trajectory (see :func:`load_plans`)."""
    plans = load_plans(path)
    if len(plans) != 1:
        raise PlanInputError(
            f"{Path(path).name}: holds {len(plans)} trajectories (Line markups); "
            "keep one or load them with load_plans()"
        )
    return plans[0]


def plan_to_dict(plan: Plan) -> dict[str, Any]:
    """The ``ctdrill-plan/1`` document of ``plan`` (LPS); mask paths are kept as given."""
    from ctdrill.imaging.plan.write import plan_document

    return plan_document(plan)


def plan_to_markups(plan: Plan | Sequence[Plan]) -> dict[str, Any]:
    """The 3D Slicer markups document of ``plan`` (LPS; settings in descriptions), or of
    several trajectories sharing their landmarks and arch (one Line each)."""
    from ctdrill.imaging.plan.write import markups_document

    return markups_document(plan if isinstance(plan, Plan) else tuple(plan))


def save_plan(plan: Plan, path: str | os.PathLike[str], *, series_uid: str | None = None) -> None:
    """Write ``plan`` atomically: Slicer markups if ``path`` ends in ``.mrk.json``, else
    ``ctdrill-plan/1`` JSON (LPS).

    ``series_uid`` (the SeriesInstanceUID the plan was made on) is recorded hashed
    (:func:`series_uid_hash`); without it the plan keeps the hash it has, if any.
    """
    write_plans((plan,), path, series_uid=series_uid)


def write_plans(
    plans: Sequence[Plan], path: str | os.PathLike[str], *, series_uid: str | None = None
) -> None:
    """Write every trajectory of ``plans`` into one file, atomically (written aside, then
    renamed): Slicer markups (one Line each) if ``path`` ends in ``.mrk.json``, else
    ``ctdrill-plan/1`` (one trajectory: the single form; several: ``trajectories``).

    The plans must share their landmarks and arch (a file holds one set of each) and their
    series hash; ``series_uid`` records one for all of them.

    Raises
    ------
    PlanInputError
        No plan, names not unique, landmarks/arch/series that differ between the plans.
    """
    from ctdrill.imaging.plan.write import write_plan_file

    if series_uid is not None:
        plans = [replace(p, series_uid_sha256=series_uid_hash(series_uid)) for p in plans]
    write_plan_file(tuple(plans), Path(path))
