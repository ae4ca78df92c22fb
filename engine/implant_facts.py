"""What a colleague reads of one implant: the clinical values of the report's implant page.

:func:`implant_facts` computes them headless (the report draws them; the window and notebooks
may call it): the site (FDI), the implant and its drilling protocol with each drill's drilled
depth (the apex plus the drill's tip length, :meth:`~ctdrill.imaging.plan.types.Plan.drilled`),
the angulation of the axis to the patient's vertical, the implant-to-nerve distance (the
implant body's clearance, :func:`ctdrill.engine.implant.implant_outcome`), the thinnest bone
walls, and the bone height from the crest to the canal along the axis.

**Angulation**: the angle between the implant's axis and the patient's superior-inferior
axis (LPS ``z``), 0 deg upright, whichever way it points.

**Bone height along the axis**: from the **crest**, the first depth (searched from
:data:`CREST_SEARCH_MM` above the entry down to the apex) where the CT number on the axis
rises to the bone edge (:data:`~ctdrill.imaging.misch.BONE_HU`, 150 HU; trilinear samples every
:data:`STEP_MM`, the crossing interpolated linearly between them), to the **canal** along the
same axis: the first depth where the axis line enters the nerve landmark (bisected to
:data:`TOL_MM`), or, when the axis passes beside it, the depth of its closest approach (then
``axis_meets_canal`` is False). The nerve is the nearest canal landmark (the nearest landmark
of any kind when the plan has no canal). Samples outside the CT are unknown, never bone.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ctdrill.engine.implant import ImplantOutcome, implant_outcome
from ctdrill.imaging.misch import BONE_HU
from ctdrill.imaging.plan.distance import DrillSolid
from ctdrill.imaging.plan.implants import implant_placement
from ctdrill.imaging.plan.landmarks import Landmark
from ctdrill.imaging.plan.site import site_text
from ctdrill.imaging.plan.types import Plan
from ctdrill.imaging.teeth import bone_along, edge_steps
from ctdrill.imaging.volume import CTVolume

#: The crest is searched from this far above the entry along the axis, mm.
CREST_SEARCH_MM = 10.0
#: Step of the samples along the axis (crest and canal), mm.
STEP_MM = 0.05
#: The canal's depth along the axis is searched this far beyond the apex, mm.
CANAL_SEARCH_MM = 30.0
#: The axis' entry into the canal is bisected to this, mm.
TOL_MM = 1e-4
#: Radius of the probe standing for the axis line, mm (a line has none; the solid needs one).
_LINE_RADIUS_MM = 1e-6


@dataclass(frozen=True)
class DrilledDrill:
    """One drill of the protocol as it is drilled for the implant (depths from the entry)."""

    diameter_mm: float
    tip_length_mm: float
    drilled_depth_mm: float


@dataclass(frozen=True)
class ImplantFacts:
    """The clinical values of one implant (module docstring); lengths in mm, angles in deg.

    Attributes
    ----------
    plan : the trajectory's name.
    site : the FDI tooth number, or None; ``site_text`` it with what it names.
    implant : the implant's name; ``size_text`` its diameter x length.
    drills : the drills in drilling order, each with its drilled depth.
    apex_depth_mm : the implant's apex (the plan's target) from the entry.
    angulation_deg : the axis against the patient's vertical.
    nerve : the nerve landmark's name (None without landmarks); ``nerve_mm`` the implant
        body's signed clearance to it; ``nerve_margin_mm`` its margin.
    min_wall_mm, buccal_mm, lingual_mm : the thinnest bone walls (None where unknown or
        without an arch).
    crest_depth_mm, canal_depth_mm : along the axis from the entry (None when not found);
        ``bone_height_mm`` the second less the first; ``axis_meets_canal``: the axis enters
        the canal (else the canal depth is its closest approach).
    accuracy_mm : what the CT's sampling lets these claim, +- mm.
    warnings : the implant's warning codes.
    """

    plan: str
    site: int | None
    site_text: str | None
    implant: str
    size_text: str
    drills: tuple[DrilledDrill, ...]
    apex_depth_mm: float
    angulation_deg: float
    nerve: str | None
    nerve_mm: float | None
    nerve_margin_mm: float | None
    min_wall_mm: float | None
    buccal_mm: float | None
    lingual_mm: float | None
    crest_depth_mm: float | None
    canal_depth_mm: float | None
    bone_height_mm: float | None
    axis_meets_canal: bool
    accuracy_mm: float
    warnings: tuple[str, ...]


def angulation_deg(direction_lps: np.ndarray) -> float:
    """Angle between an axis and the patient's vertical (LPS ``z``), deg, 0-90."""
    u = np.asarray(direction_lps, dtype=np.float64)
    cos = abs(float(u[2])) / float(np.linalg.norm(u))
    return math.degrees(math.acos(min(1.0, cos)))


def crest_depth_mm(volume: CTVolume, plan: Plan, to_depth_mm: float) -> float | None:
    """Where the axis first enters bone, from :data:`CREST_SEARCH_MM` above the entry down to
    ``to_depth_mm`` (module docstring), mm from the entry; None when the first known sample is
    already bone or bone is never reached."""
    depth = np.arange(-CREST_SEARCH_MM, to_depth_mm + STEP_MM / 2, STEP_MM)
    pts = plan.entry_lps + depth[:, None] * plan.direction
    hu = volume.sample(pts, outside_hu=np.nan)
    known = np.flatnonzero(np.isfinite(hu))
    bone = bone_along(hu, edge_steps(volume, STEP_MM))  # a crown is not the crest
    if known.size == 0 or bone[known[0]]:
        return None
    for i in known[1:]:
        if bone[i] and not bone[i - 1] and np.isfinite(hu[i - 1]):
            a, b = float(hu[i - 1]), float(hu[i])
            if a >= BONE_HU:  # after a tooth's edge: the bone starts at this sample
                return float(depth[i])
            return float(depth[i - 1] + STEP_MM * (BONE_HU - a) / (b - a))
    return None


def canal_depth_mm(plan: Plan, landmark: Landmark, from_depth_mm: float) -> tuple[float, bool]:
    """Where the axis line reaches ``landmark`` below ``from_depth_mm`` (module docstring):
    ``(depth from the entry, whether the axis enters it)``."""
    line = DrillSolid(plan.entry_lps, plan.direction, _LINE_RADIUS_MM, 0.0)
    end = plan.planned_depth_mm - plan.overdrill_mm + CANAL_SEARCH_MM
    depth = np.arange(from_depth_mm, end + STEP_MM / 2, STEP_MM)
    # the line swept to each depth: its clearance never increases with depth
    c = landmark.clearance_mm(line, depth)
    inside = np.flatnonzero(c <= 0.0)
    if inside.size == 0:
        low = float(np.min(c))
        return float(depth[int(np.flatnonzero(c <= low + TOL_MM)[0])]), False
    k = int(inside[0])
    if k == 0:
        return float(depth[0]), True
    a, b = float(depth[k - 1]), float(depth[k])
    while b - a > TOL_MM:
        mid = 0.5 * (a + b)
        if float(landmark.clearance_mm(line, np.array([mid]))[0]) <= 0.0:
            b = mid
        else:
            a = mid
    return 0.5 * (a + b), True


def _nerve(outcome: ImplantOutcome) -> int | None:
    """Index of the nearest canal landmark (any kind without a canal), or None."""
    c = outcome.clearance
    if c is None:
        return None
    kinds = [lm.kind for lm in outcome.plan.landmarks]
    canals = [i for i, k in enumerate(kinds) if k == "canal"] or list(range(len(kinds)))
    return min(canals, key=lambda i: float(c.clearance_mm[i]))


def implant_facts(
    volume: CTVolume, plan: Plan, outcome: ImplantOutcome | None = None
) -> ImplantFacts | None:
    """The clinical values of ``plan``'s implant on ``volume`` (module docstring); None
    without an implant. ``plan`` is the whole trajectory (all its drills); ``outcome`` its
    :func:`~ctdrill.engine.implant.implant_outcome` when already computed."""
    place = implant_placement(plan)
    if place is None:
        return None
    out = implant_outcome(volume, plan) if outcome is None else outcome
    assert out is not None and plan.implant is not None
    spec = plan.implant
    drills = tuple(
        DrilledDrill(d.diameter_mm, d.tip_length_mm, depth)
        for d, depth in zip(plan.drills, plan.drill_depths_mm(), strict=True)
    )
    nerve = _nerve(out)
    crest = crest_depth_mm(volume, plan, place.apex_depth_mm)
    canal: float | None = None
    meets = False
    if nerve is not None:
        start = place.platform_depth_mm if crest is None else crest
        canal, meets = canal_depth_mm(out.plan, out.plan.landmarks[nerve], start)
    walls = out.walls
    clear = out.clearance
    return ImplantFacts(
        plan=plan.name,
        site=plan.site,
        site_text=None if plan.site is None else site_text(plan.site),
        implant=spec.name,
        size_text=spec.size_text,
        drills=drills,
        apex_depth_mm=place.apex_depth_mm,
        angulation_deg=angulation_deg(place.axis_lps),
        nerve=None if nerve is None else out.plan.landmarks[nerve].name,
        nerve_mm=None if clear is None or nerve is None else float(clear.clearance_mm[nerve]),
        nerve_margin_mm=None if clear is None or nerve is None else float(clear.margins_mm[nerve]),
        min_wall_mm=walls.min_mm,
        buccal_mm=walls.buccal_mm,
        lingual_mm=walls.lingual_mm,
        crest_depth_mm=crest,
        canal_depth_mm=canal,
        bone_height_mm=None if crest is None or canal is None else canal - crest,
        axis_meets_canal=meets,
        accuracy_mm=out.accuracy_mm,
        warnings=out.codes,
    )
