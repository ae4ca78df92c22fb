"""Plan edits the window offers, as pure functions on the frozen
``ctdrill.imaging.plan.types.Plan``.

Each edit returns a new plan (never mutates) and raises :class:`PlanEditError` with a message
naming the field when the result would not be a usable plan.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from ctdrill.app.errors import AppInputError
from ctdrill.app.gui.results import PathView, binding_index, plan_violation
from ctdrill.app.gui.scene import CandidateLine, LandmarkGeometry, SceneInput
from ctdrill.imaging.plan.drill_spec import sequence_error
from ctdrill.imaging.plan.implants import ImplantSpec
from ctdrill.imaging.plan.landmarks import Landmark
from ctdrill.imaging.plan.protocol import protocol_drills
from ctdrill.imaging.plan.site import site_error
from ctdrill.imaging.plan.types import DrillSpec, Plan
from ctdrill.imaging.sampling.arch import ArchCurve

#: Shortest trajectory the editor accepts, mm.
MIN_DEPTH_MM = 0.5


class PlanEditError(AppInputError):
    """An edit that would make the plan unusable (the message says which field and why)."""


def move_handle(plan: Plan, name: str, point_lps: np.ndarray) -> Plan:
    """Move ``entry`` or ``target`` to ``point_lps`` (3,) LPS mm."""
    pt = np.asarray(point_lps, dtype=np.float64).reshape(3)
    if not np.all(np.isfinite(pt)):
        raise PlanEditError(f"{name}: coordinates must be finite numbers")
    if name == "entry":
        new = replace(plan, entry_lps=pt)
    elif name == "target":
        new = replace(plan, target_lps=pt)
    else:
        raise PlanEditError(f"unknown handle {name!r}: use 'entry' or 'target'")
    if new.planned_depth_mm < MIN_DEPTH_MM:
        raise PlanEditError(
            f"{name}: entry and target would be {new.planned_depth_mm:.2f} mm apart; "
            f"keep them at least {MIN_DEPTH_MM} mm apart"
        )
    return new


def set_landmark_margin(plan: Plan, index: int, margin_mm: float | None) -> Plan:
    """Give landmark ``index`` its own margin (None: use the plan's)."""
    if margin_mm is not None and (not np.isfinite(margin_mm) or margin_mm < 0):
        raise PlanEditError(f"landmarks[{index}].margin_mm: must be >= 0, got {margin_mm}")
    lms = list(plan.landmarks)
    lms[index] = lms[index].with_margin(margin_mm)
    return replace(plan, landmarks=tuple(lms))


def remove_landmark(plan: Plan, index: int) -> Plan:
    """Drop landmark ``index``."""
    lms = list(plan.landmarks)
    del lms[index]
    return replace(plan, landmarks=tuple(lms))


def place_handle(
    plan: Plan | None, draft: dict[str, np.ndarray], name: str, point_lps: np.ndarray
) -> Plan | dict[str, np.ndarray]:
    """Place ``entry`` or ``target`` at ``point_lps`` (3,) LPS mm.

    With a plan, the moved plan (:func:`move_handle`). Without one (a series opened without a
    plan: no trajectory is guessed), the points placed so far (``draft`` plus this one) until
    both exist, then a new plan from them with the default drill, feed and margin.
    """
    if plan is not None:
        return move_handle(plan, name, point_lps)
    if name not in ("entry", "target"):
        raise PlanEditError(f"unknown handle {name!r}: use 'entry' or 'target'")
    pt = np.asarray(point_lps, dtype=np.float64).reshape(3)
    if not np.all(np.isfinite(pt)):
        raise PlanEditError(f"{name}: coordinates must be finite numbers")
    points = {**draft, name: pt}
    if set(points) != {"entry", "target"}:
        return points
    new = Plan(entry_lps=points["entry"], target_lps=points["target"], name=unique_name(()))
    if new.planned_depth_mm < MIN_DEPTH_MM:
        raise PlanEditError(
            f"{name}: entry and target would be {new.planned_depth_mm:.2f} mm apart; "
            f"keep them at least {MIN_DEPTH_MM} mm apart"
        )
    return new


def landmark_points_lps(landmark: Landmark) -> np.ndarray:
    """(N, 3) points that draw a landmark: its polyline, its point(s) or its surface cloud."""
    drawing = landmark.drawing()
    parts = [*drawing.polylines_lps, drawing.points_lps, drawing.surface_lps]
    return np.concatenate([p for p in parts if len(p)] or [np.empty((0, 3))])


def landmark_geometries(
    plan: Plan, clearance_mm: np.ndarray | None = None, *, violated: int | Sequence[int] = ()
) -> tuple[LandmarkGeometry, ...]:
    """What to draw for each landmark, with its minimum clearance along the stopped path.

    ``clearance_mm`` is (L,) per landmark (in plan order) or None when not computed yet or
    not computable (a result for another landmark list is ignored): drawn as unknown.
    ``violated`` are the landmarks whose margin the plan breaks (an index or several),
    marked in every view.
    Mask landmarks are drawn as their boundary points (point cloud), without a tube.
    """
    if clearance_mm is not None and len(clearance_mm) != len(plan.landmarks):
        clearance_mm = None
    marked = {violated} if isinstance(violated, int) else set(violated)
    out = []
    for i, lm in enumerate(plan.landmarks):
        clear = None if clearance_mm is None else float(clearance_mm[i])
        out.append(
            LandmarkGeometry(
                name=lm.name,
                points_lps=landmark_points_lps(lm),
                radius_mm=float(lm.radius_mm),
                margin_mm=plan.landmark_margin_mm(lm),
                clearance_mm=clear,
                kind=lm.kind,
                cloud=len(lm.drawing().surface_lps) > 0,
                violated=i in marked,
            )
        )
    return tuple(out)


def drawn_landmarks(plan: Plan, view: PathView | None) -> tuple[LandmarkGeometry, ...]:
    """The landmarks of ``plan`` as every view draws them: with the clearances of ``view``
    when it was computed for this plan (else unknown), marked where the plan breaks their
    margin: the implant's or the osteotomy's planned clearance below it
    (:class:`~ctdrill.app.gui.problems.PlannedClearance`), else (a bare result) the binding
    landmark when the planned path breaks its margin."""
    if view is None or view.plan is not plan:
        return landmark_geometries(plan)
    planned = view.planned
    if planned is not None and len(planned.margins_mm) == len(plan.landmarks):
        violated: int | Sequence[int] = [int(i) for i in np.flatnonzero(planned.broken())]
    else:
        binding = binding_index(view.result) if plan_violation(view.result) else None
        violated = () if binding is None else binding
    return landmark_geometries(plan, view.min_clearance_mm, violated=violated)


def scene_input(
    plan: Plan | None, view: PathView | None, candidates: tuple[CandidateLine, ...] = ()
) -> SceneInput:
    """The 3D scene of ``plan`` (None: the anatomy alone), with ``view``'s stop when computed
    for it and the suggested axes ``candidates``."""
    if plan is None:
        return SceneInput(entry_lps=None, target_lps=None, diameter_mm=0.0, tip_length_mm=0.0)
    own = view is not None and view.plan is plan
    return SceneInput(
        entry_lps=plan.entry_lps,
        target_lps=plan.target_lps,
        diameter_mm=plan.drill.diameter_mm,
        tip_length_mm=plan.drill.tip_length_mm,
        stop_depth_mm=view.curves.stop_depth_mm if own and view is not None else None,
        landmarks=drawn_landmarks(plan, view),
        candidates=candidates,
    )


def _same(a: object, b: object) -> bool:
    """Equal plan field values (arrays by value, tuples item by item)."""
    if a is b:
        return True
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return (
            isinstance(a, np.ndarray)
            and isinstance(b, np.ndarray)
            and a.shape == b.shape
            and bool(np.array_equal(a, b))
        )
    if isinstance(a, tuple) and isinstance(b, tuple):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    try:
        return bool(a == b)
    except (ValueError, TypeError):  # dataclasses holding arrays: not comparable, say changed
        return False


#: What an edit is called (Edit > Undo NAME) by the first plan field it changes.
_EDIT_NAMES = (
    ("entry_lps", "move entry"),
    ("target_lps", "move target"),
    ("drill", "change drill"),
    ("earlier_drills", "change drill sequence"),
    ("implant", "change implant"),
    ("arch_lps", "edit arch"),
    ("landmarks", "edit landmarks"),
    ("margin_mm", "change safety margin"),
    ("feed_mm_s", "change feed"),
    ("calibration", "change calibration"),
    ("name", "rename trajectory"),
)


def edit_name(before: Plan | None, after: Plan | None) -> str:
    """What changing ``before`` into ``after`` is called in Edit > Undo (``move entry``,
    ``change drill``, ...; ``edit trajectory`` when no listed field differs)."""
    if before is None:
        return "place trajectory" if after is not None else "edit trajectory"
    if after is None:
        return "remove every trajectory"
    changed = [
        label
        for attr, label in _EDIT_NAMES
        if not _same(getattr(before, attr, None), getattr(after, attr, None))
    ]
    if len(changed) == 2 and changed[:2] == ["move entry", "move target"]:
        return "move trajectory"
    return changed[0] if changed else "edit trajectory"


#: How far a new trajectory is placed from the current one, mm (about one implant's width plus
#: the usual 3 mm between neighbouring implants).
NEW_TRAJECTORY_SPACING_MM = 8.0


def unique_name(plans: Sequence[Plan], stem: str = "implant") -> str:
    """``stem N`` with the smallest N >= 1 no trajectory of ``plans`` is called."""
    taken = {p.name for p in plans}
    n = 1
    while f"{stem} {n}" in taken:
        n += 1
    return f"{stem} {n}"


def rename(plans: Sequence[Plan], index: int, name: str) -> Plan:
    """Trajectory ``index`` called ``name`` (stripped; unique among ``plans``, not empty)."""
    name = name.strip()
    if not name:
        raise PlanEditError(f"trajectory {index + 1}: a name cannot be empty")
    if any(p.name == name for i, p in enumerate(plans) if i != index):
        raise PlanEditError(f"trajectory {index + 1}: another trajectory is called {name!r}")
    return replace(plans[index], name=name)


def new_trajectory(
    plans: Sequence[Plan], current: int, *, spacing_mm: float = NEW_TRAJECTORY_SPACING_MM
) -> tuple[Plan, str]:
    """A new trajectory next to ``plans[current]`` and where it was put, in words.

    A copy (drill, implant, landmarks, settings) moved sideways: ``spacing_mm`` along the arch
    (the panorama's arc length, toward the arch's end farther away) when the plan has an arch
    and the target lies beside it, else ``spacing_mm`` toward the patient's left (+x LPS); the
    user drags it into place. Named :func:`unique_name` (the site is not copied: a new
    trajectory is a new site).
    """
    base = plans[current]
    shift = np.array([spacing_mm, 0.0, 0.0])
    where = f"{spacing_mm:g} mm to the patient's left of {base.name!r}"
    arch = base.arch_lps
    if arch is not None:
        try:
            curve = ArchCurve(arch)
            s_mm = float(curve.project(base.target_lps.reshape(1, 3))[0][0])
        except ValueError:  # an arch the panorama refuses: the plain shift, said so
            s_mm = float("nan")
        if np.isfinite(s_mm):
            sign = 1.0 if curve.length_mm - s_mm >= s_mm else -1.0
            to_mm = float(np.clip(s_mm + sign * spacing_mm, 0.0, curve.length_mm))
            step = curve.point_xy(np.array([to_mm, s_mm]))
            shift = np.array([*(step[0] - step[1]), 0.0])
            where = f"{abs(to_mm - s_mm):.1f} mm along the arch from {base.name!r}"
        else:
            where += " (its target is beyond the arch's ends)"
    new = replace(
        base,
        entry_lps=base.entry_lps + shift,
        target_lps=base.target_lps + shift,
        name=unique_name(plans),
        site=None,
    )
    return new, where


def with_shared(plans: Sequence[Plan], index: int, plan: Plan) -> tuple[Plan, ...]:
    """``plans`` with trajectory ``index`` replaced by ``plan``, whose landmarks and arch go to
    every trajectory: a plan file holds one set of each, shared by all its trajectories, so an
    edit of them on one trajectory (a canal point, a landmark's margin, the arch) is an edit of
    the plan's."""
    old = plans[index]
    shared: dict[str, Any] = {}
    if plan.landmarks is not old.landmarks:
        shared["landmarks"] = plan.landmarks
    if not _same(plan.arch_lps, old.arch_lps):
        shared["arch_lps"] = plan.arch_lps
    out = [replace(p, **shared) if shared and i != index else p for i, p in enumerate(plans)]
    out[index] = plan
    return tuple(out)


def drills_text(plan: Plan) -> str:
    """The drill sequence as the window's editor shows it: diameters in drilling order, mm
    (``2 -> 2.8 -> 3.5``)."""
    return " -> ".join(f"{d.diameter_mm:g}" for d in plan.drills)


def with_drill_sequence(plan: Plan, text: str) -> Plan:
    """``plan`` drilled with the diameters written in ``text`` (mm, in drilling order,
    separated by ``->``, commas or spaces; the last is the final drill).

    A diameter already drilled keeps its drill; a new one is the implant protocol's drill of
    that diameter, else a drill with the tip rule's tip
    (:func:`~ctdrill.imaging.plan.drill_spec.tip_length_rule_mm`) and the final drill's blades,
    speed and point angle.

    Raises
    ------
    PlanEditError
        A word that is not a diameter, or a sequence ctdrill refuses (empty, too long, not
        strictly widening).
    """
    words = [w for w in text.replace("->", " ").replace(",", " ").replace(";", " ").split() if w]
    diameters = []
    for word in words:
        try:
            value = float(word.removesuffix("mm"))
        except ValueError:
            raise PlanEditError(
                f"drills: {word!r} is not a diameter; write them in mm in drilling order, "
                "e.g. 2 -> 2.8 -> 3.5"
            ) from None
        if not (np.isfinite(value) and 0.0 < value <= 10.0):
            raise PlanEditError(f"drills: diameter {word} mm must be > 0 and <= 10 mm")
        diameters.append(value)
    protocol = {} if plan.implant is None else {d.diameter_mm: d for d in plan.implant.drills}
    known = {d.diameter_mm: d for d in plan.drills}
    base = plan.drill
    seq = tuple(
        known.get(d)
        or (
            replace(protocol[d], blades=base.blades, rpm=base.rpm)
            if d in protocol
            else DrillSpec(
                diameter_mm=d,
                blades=base.blades,
                rpm=base.rpm,
                point_angle_deg=base.point_angle_deg,
            )
        )
        for d in diameters
    )
    problem = sequence_error(seq)
    if problem is not None:
        raise PlanEditError(f"drills{problem}")
    return plan.with_drills(seq)


def with_implant(plan: Plan, spec: ImplantSpec | None) -> Plan:
    """``plan`` with the implant ``spec`` (None: none) drilled with its protocol (its own
    drills, else the generic protocol for its size,
    :func:`~ctdrill.imaging.plan.protocol.protocol_drills`), keeping the drills' blades and
    speed: picking an implant is one edit (one undo step). Removing the implant keeps the
    drills."""
    if spec is None:
        return replace(plan, implant=None)
    base = plan.drill
    seq = tuple(replace(d, blades=base.blades, rpm=base.rpm) for d in protocol_drills(spec)[0])
    whole = replace(plan, target_lps=plan.planned_target_lps, overdrill_mm=0.0, implant=None)
    return replace(whole, implant=spec, drill=seq[-1], earlier_drills=seq[:-1])


def final_drill_edited(plan: Plan, *, diameter_mm: float, tip_length_mm: float) -> DrillSpec:
    """The final drill after the window's diameter and tip fields read ``diameter_mm`` and
    ``tip_length_mm``: a new diameter with the tip left as it was takes the implant protocol's
    drill of that diameter, else the tip rule's tip; a tip typed that differs from the rule's is
    kept as an override (warning ``drill_tip_override``)."""
    old = plan.drill
    if diameter_mm != old.diameter_mm and abs(tip_length_mm - old.tip_length_mm) < 1e-9:
        protocol = {} if plan.implant is None else {d.diameter_mm: d for d in plan.implant.drills}
        if diameter_mm in protocol:
            return replace(protocol[diameter_mm], blades=old.blades, rpm=old.rpm)
        return replace(old, diameter_mm=diameter_mm, tip_length_mm=math.nan)
    return replace(old, diameter_mm=diameter_mm, tip_length_mm=tip_length_mm)


def with_site(plan: Plan, text: str) -> Plan:
    """``plan`` at the FDI site written in ``text`` ("" removes it).

    Raises
    ------
    PlanEditError
        Not an FDI tooth number 11-48 (the message says what one is).
    """
    words = text.strip()
    if not words:
        return replace(plan, site=None)
    try:
        number = int(words)
    except ValueError:
        number = None
    problem = site_error(number) if number is not None else site_error(words)
    if problem is not None:
        raise PlanEditError(f"site {words!r}: {problem}")
    return replace(plan, site=number)
