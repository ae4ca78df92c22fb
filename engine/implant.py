"""A trajectory's implant outcome: the implant body and the bone around it, on one CT.

:func:`implant_outcome` is the one headless function every output calls for the implant of a
trajectory: the export's ``summary.json`` (``implant_clearance_mm``,
``implant_binding_landmark``, ``bone_walls``), its warnings (``implant_violates_margin``,
``plan_violates_margin`` for the body, ``thin_wall``, ``cortical_perforation``,
``bone_walls_unknown``), the report's clinical page (:mod:`ctdrill.engine.implant_facts`),
``ctdrill.api.implant_outcome`` and the window. The geometry is imaging's: the body's exact
clearance (:mod:`ctdrill.imaging.plan.implant_safety`) and the walls read from the CT's own
trilinear samples (:mod:`ctdrill.imaging.sampling.walls`).

The implant sits where the plan puts it (apex at the plan's target,
:func:`~ctdrill.imaging.plan.implants.implant_placement`) whichever drill's view of the plan
is given (``plan.drilled(k)`` places the same implant), so every drill of a sequence has the
same outcome.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ctdrill.imaging.plan.clinical import CLINICAL_TOOTH_DISTANCE_MM
from ctdrill.imaging.plan.implant_safety import (
    ImplantClearance,
    broken_margins_text,
    implant_clearance,
    implant_margin_warnings,
)
from ctdrill.imaging.plan.implants import implant_placement
from ctdrill.imaging.plan.landmarks import bind_to_grid
from ctdrill.imaging.plan.types import Plan
from ctdrill.imaging.resolution import volume_clearance_accuracy_mm
from ctdrill.imaging.sampling.wall_warnings import bone_wall_warnings
from ctdrill.imaging.sampling.walls import BoneWalls, start_plan_bone_walls
from ctdrill.imaging.teeth import TOOTH_HU, tooth_distance_mm
from ctdrill.imaging.volume import CTVolume
from ctdrill.warning_codes import LoadWarning

#: Said in ``bone_walls`` of every summary: how the CT's edge is counted.
OUTSIDE_CT_RULE = "outside the CT counts as unknown, never as bone"


@dataclass(frozen=True, eq=False)
class ImplantOutcome:
    """The implant of one trajectory against its landmarks and in its bone.

    Attributes
    ----------
    plan : the plan (landmarks bound to the CT grid).
    clearance : the body's clearance to each landmark, or None without landmarks.
    walls : the bone walls around the body (:class:`~ctdrill.imaging.sampling.walls.BoneWalls`).
    accuracy_mm : what the CT's sampling lets a clearance claim, +- mm
        (:func:`~ctdrill.imaging.resolution.volume_clearance_accuracy_mm`).
    warnings : its warnings (:class:`~ctdrill.warning_codes.LoadWarning`), in the order the
        summary lists them.
    tooth_mm : the distance from the body to the nearest tooth (:mod:`ctdrill.imaging.teeth`;
        negative: it enters one), mm, or None when no tooth is near.
    """

    plan: Plan
    clearance: ImplantClearance | None
    walls: BoneWalls
    accuracy_mm: float
    warnings: tuple[LoadWarning, ...]
    tooth_mm: float | None = None

    @property
    def clearance_mm(self) -> float | None:
        """Signed distance from the body to the binding landmark, mm (< 0 inside; None
        without landmarks)."""
        return None if self.clearance is None else self.clearance.binding_clearance_mm

    @property
    def binding_name(self) -> str | None:
        """The binding landmark's name (least slack ``clearance - margin``), or None."""
        c = self.clearance
        return None if c is None else c.names[c.binding]

    @property
    def binding_margin_mm(self) -> float | None:
        """The binding landmark's margin, mm, or None."""
        c = self.clearance
        return None if c is None else float(c.margins_mm[c.binding])

    @property
    def violates_margin(self) -> bool:
        """The body breaks some landmark's margin."""
        return self.clearance is not None and bool(self.clearance.violated)

    @property
    def codes(self) -> tuple[str, ...]:
        """The warning codes, in order."""
        return tuple(w.code for w in self.warnings)

    def bone_walls_json(self) -> dict[str, Any]:
        """``bone_walls`` as the summary writes it (the walls and the CT-edge rule)."""
        return {**self.walls.to_json(), "outside_ct": OUTSIDE_CT_RULE}


def _label(plan: Plan) -> str:
    assert plan.implant is not None
    return f"plan {plan.name!r}: implant {plan.implant.name!r} ({plan.implant.size_text})"


def implant_body_margin_warnings(
    plan: Plan, clearance: ImplantClearance | None
) -> list[LoadWarning]:
    """``implant_violates_margin`` and, for the same break, ``plan_violates_margin`` (the
    plan's margin covers the implant as well as every drill)."""
    out = implant_margin_warnings(plan, clearance)
    if out and plan.implant is not None and clearance is not None:
        out.append(
            LoadWarning(
                "plan_violates_margin",
                f"plan {plan.name!r}: the implant body at its planned place breaks the safety "
                f"margin: clearance of implant {plan.implant.name!r} to "
                + broken_margins_text(clearance),
            )
        )
    return out


def implant_outcome(volume: CTVolume, plan: Plan, **wall_options: Any) -> ImplantOutcome | None:
    """The implant outcome of ``plan`` on ``volume``; None when the plan places no implant.

    Parameters
    ----------
    volume : the CT (LPS); mask landmarks without a grid take its grid.
    plan : the trajectory (any drill's view of it: the implant's placement is the same).
    wall_options : passed to :func:`~ctdrill.imaging.sampling.walls.bone_walls`
        (``depth_step_mm``, ``n_angles``, ``max_wall_mm``, ``ray_step``).
    """
    walls = start_plan_bone_walls(volume, plan, **wall_options)
    return None if walls is None else implant_outcome_with(volume, plan, walls)


def implant_outcome_with(
    volume: CTVolume, plan: Plan, walls: Callable[[], BoneWalls]
) -> ImplantOutcome:
    """:func:`implant_outcome` of ``plan`` (which has an implant) with its bone walls already
    started (:func:`~ctdrill.imaging.sampling.walls.start_plan_bone_walls`: their rays run on
    the worker threads meanwhile); ``walls()`` finishes them once the rest is computed."""
    if plan.landmarks:
        landmarks = bind_to_grid(plan.landmarks, volume.affine_lps, tuple(volume.hu.shape))
        if any(a is not b for a, b in zip(landmarks, plan.landmarks, strict=True)):
            plan = replace(plan, landmarks=landmarks)
    clearance = implant_clearance(plan)
    tooth = implant_tooth_distance_mm(volume, plan)
    bone = walls()
    warnings = implant_body_margin_warnings(plan, clearance)
    warnings += bone_wall_warnings(bone, min_wall_mm=plan.min_wall_mm, label=_label(plan))
    warnings += tooth_warnings(plan, tooth)
    return ImplantOutcome(
        plan=plan,
        clearance=clearance,
        walls=bone,
        accuracy_mm=volume_clearance_accuracy_mm(volume),
        warnings=tuple(warnings),
        tooth_mm=tooth,
    )


def implant_tooth_distance_mm(volume: CTVolume, plan: Plan) -> float | None:
    """The distance from ``plan``'s implant body to the nearest tooth, mm (None: none near)."""
    place = implant_placement(plan)
    if place is None:
        return None
    spec = place.spec
    s = np.linspace(0.0, spec.length_mm, 33)
    radii = np.array([spec.radius_at_mm(float(v)) for v in s])
    return tooth_distance_mm(volume, place.platform_lps, place.axis_lps, spec.length_mm, radii)


def tooth_warnings(plan: Plan, tooth_mm: float | None) -> list[LoadWarning]:
    """``implant_in_tooth`` (the body enters a tooth) or ``implant_near_tooth`` (closer than
    the clinical implant-tooth distance)."""
    if tooth_mm is None:
        return []
    if tooth_mm < 0.0:
        return [
            LoadWarning(
                "implant_in_tooth",
                f"{_label(plan)}: the implant body enters a tooth ({-tooth_mm:.1f} mm into it: "
                f"CT numbers >= {TOOTH_HU:g} HU, enamel, dentin or metal); extract it first or "
                "move the implant",
            )
        ]
    if tooth_mm < CLINICAL_TOOTH_DISTANCE_MM:
        return [
            LoadWarning(
                "implant_near_tooth",
                f"{_label(plan)}: {tooth_mm:.1f} mm from the implant body to the nearest tooth, "
                f"under the clinical {CLINICAL_TOOTH_DISTANCE_MM:g} mm implant-tooth distance",
            )
        ]
    return []
