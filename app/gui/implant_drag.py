"""Moving an implant with the mouse, headless: what a drag on a view does to the trajectory.

A drag starts on a grip of the current trajectory and ends where the mouse is released; the
views report the grip, the modifier keys and two LPS points (where the grip was taken and
where the mouse is now, on the view's plane). The new plan is always computed from the plan
at the press, so a long drag accumulates no error and going back gives the plan back.

Grips and what a drag does (:func:`drag_mode`):

- the **target** (the implant's apex) or the **body** (the implant or the drill between its
  ends): the implant moves whole (entry and target by the same displacement);
- the **platform** (the implant's top): the implant tilts about its apex, keeping its depth;
- the **entry**: the entry moves alone (the axis tilts about the apex);
- **Shift** on the target, the body or the platform: the implant slides along its axis (the
  apex moves along the axis, the entry stays: the osteotomy gets deeper or shallower);
- **Ctrl** on the target: the apex moves alone (the axis tilts about the entry).
"""

from __future__ import annotations

from dataclasses import replace
from typing import Literal

import numpy as np

from ctdrill.app.gui.planning import MIN_DEPTH_MM, PlanEditError
from ctdrill.imaging.plan.implants import implant_placement
from ctdrill.imaging.plan.types import Plan

Grip = Literal["entry", "target", "platform", "body"]
DragMode = Literal["move", "slide", "tilt", "apex", "entry"]

#: What each drag is called in Edit > Undo.
EDIT_NAMES: dict[str, str] = {
    "move": "move implant",
    "slide": "slide implant along its axis",
    "tilt": "tilt implant",
    "apex": "move target",
    "entry": "move entry",
}
#: Closest the tilt grip may come to the apex (the axis is undefined there), mm.
MIN_TILT_ARM_MM = 0.5


def drag_mode(grip: str, *, shift: bool = False, ctrl: bool = False) -> DragMode:
    """The drag a press on ``grip`` starts, given the modifier keys held."""
    if grip == "entry":
        return "entry"
    if shift:
        return "slide"
    if grip == "platform":
        return "tilt"
    if grip == "target" and ctrl:
        return "apex"
    return "move"


def platform_lps(plan: Plan) -> np.ndarray | None:
    """(3,) the implant's platform (the tilt grip), LPS mm; None without an implant."""
    place = implant_placement(plan)
    return None if place is None else np.array(place.platform_lps, dtype=np.float64)


def grips_lps(plan: Plan) -> dict[str, np.ndarray]:
    """Every point grip of ``plan`` (``entry``, ``target``, ``platform`` with an implant)."""
    out = {"entry": plan.entry_lps, "target": plan.target_lps}
    top = platform_lps(plan)
    if top is not None:
        out["platform"] = top
    return out


def dragged_plan(plan: Plan, mode: str, start_lps: np.ndarray, now_lps: np.ndarray) -> Plan:
    """``plan`` after a drag of ``mode`` from ``start_lps`` (where the grip was taken, (3,)
    LPS mm) to ``now_lps`` (where the mouse is).

    Raises
    ------
    PlanEditError
        A point that is not finite, an unknown mode, or a drag that would leave entry and
        target closer than :data:`~ctdrill.app.gui.planning.MIN_DEPTH_MM` (or the tilt grip
        on the apex).
    """
    start = np.asarray(start_lps, dtype=np.float64).reshape(3)
    now = np.asarray(now_lps, dtype=np.float64).reshape(3)
    if not (np.all(np.isfinite(start)) and np.all(np.isfinite(now))):
        raise PlanEditError(f"{mode}: the drag's points must be finite numbers")
    delta = now - start
    entry, target = plan.entry_lps, plan.target_lps
    if mode == "move":
        new = replace(plan, entry_lps=entry + delta, target_lps=target + delta)
    elif mode == "slide":
        along = float(delta @ plan.direction)
        along = max(along, MIN_DEPTH_MM + 1e-6 - plan.planned_depth_mm)  # never past the entry
        new = replace(plan, target_lps=target + along * plan.direction)
    elif mode == "tilt":
        arm = target - now  # from the grip (the platform, moved) to the apex
        length = float(np.linalg.norm(arm))
        if length < MIN_TILT_ARM_MM:
            raise PlanEditError("tilt: keep the platform away from the apex")
        new = replace(plan, entry_lps=target - plan.planned_depth_mm * arm / length)
    elif mode == "apex":
        new = replace(plan, target_lps=target + delta)
    elif mode == "entry":
        new = replace(plan, entry_lps=entry + delta)
    else:
        raise PlanEditError(f"unknown drag {mode!r}: use one of {', '.join(EDIT_NAMES)}")
    if new.planned_depth_mm < MIN_DEPTH_MM:
        raise PlanEditError(
            f"{EDIT_NAMES[mode]}: entry and target would be {new.planned_depth_mm:.2f} mm "
            f"apart; keep them at least {MIN_DEPTH_MM} mm apart"
        )
    return new


def site_lps(plan: Plan) -> np.ndarray:
    """(3,) where a trajectory's site is viewed from: its implant's middle (platform to
    apex), else its axis' middle, LPS mm."""
    place = implant_placement(plan)
    if place is None:
        return np.asarray((plan.entry_lps + plan.target_lps) / 2.0)
    return np.asarray((place.platform_lps + place.apex_lps) / 2.0)


def body_hit(plan: Plan, point_lps: np.ndarray, *, reach_mm: float) -> bool:
    """True when ``point_lps`` lies within ``reach_mm`` of the implant body's axis segment
    (platform to apex) or, without an implant, of the drill's axis (entry to target): a press
    there grabs the body."""
    top = platform_lps(plan)
    a = plan.entry_lps if top is None else top
    b = plan.target_lps
    length = float(np.linalg.norm(b - a))
    axis = (b - a) / length
    rel = np.asarray(point_lps, dtype=np.float64).reshape(3) - a
    along = float(rel @ axis)
    radial = float(np.linalg.norm(rel - along * axis))
    radius = plan.drill.radius_mm if plan.implant is None else 0.5 * plan.implant.diameter_mm
    return -reach_mm <= along <= length + reach_mm and radial <= radius + reach_mm
