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

from dataclasses import dataclass, replace
from typing import Any

from ctdrill.imaging.plan.implant_safety import (
    ImplantClearance,
    broken_margins_text,
    implant_clearance,
    implant_margin_warnings,
)
from ctdrill.imaging.plan.landmarks import bind_to_grid
from ctdrill.imaging.plan.types import Plan
from ctdrill.imaging.resolution import volume_clearance_accuracy_mm
from ctdrill.imaging.sampling.walls import BoneWalls, bone_wall_warnings, plan_bone_walls
from ctdrill.imaging.volume import CTVolume

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
    warnings : ``(code, message)`` pairs, in the order the summary lists them.
    """

    plan: Plan
    clearance: ImplantClearance | None
    walls: BoneWalls
    accuracy_mm: float
    warnings: tuple[tuple[str, str], ...]

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
        return tuple(code for code, _ in self.warnings)

    def bone_walls_json(self) -> dict[str, Any]:
        """``bone_walls`` as the summary writes it (the walls and the CT-edge rule)."""
        return {**self.walls.to_json(), "outside_ct": OUTSIDE_CT_RULE}


def _label(plan: Plan) -> str:
    assert plan.implant is not None
    return f"plan {plan.name!r}: implant {plan.implant.name!r} ({plan.implant.size_text})"


def implant_body_margin_warnings(
    plan: Plan, clearance: ImplantClearance | None
) -> list[tuple[str, str]]:
    """``implant_violates_margin`` and, for the same break, ``plan_violates_margin`` (the
    plan's margin covers the implant as well as every drill)."""
    out = implant_margin_warnings(plan, clearance)
    if out and plan.implant is not None and clearance is not None:
        out.append(
            (
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
    if plan.implant is None:
        return None
    if plan.landmarks:
        landmarks = bind_to_grid(plan.landmarks, volume.affine_lps, tuple(volume.hu.shape))
        if any(a is not b for a, b in zip(landmarks, plan.landmarks, strict=True)):
            plan = replace(plan, landmarks=landmarks)
    clearance = implant_clearance(plan)
    walls = plan_bone_walls(volume, plan, **wall_options)
    assert walls is not None  # the plan has an implant
    warnings = implant_body_margin_warnings(plan, clearance)
    warnings += bone_wall_warnings(walls, min_wall_mm=plan.min_wall_mm, label=_label(plan))
    return ImplantOutcome(
        plan=plan,
        clearance=clearance,
        walls=walls,
        accuracy_mm=volume_clearance_accuracy_mm(volume),
        warnings=tuple(warnings),
    )
