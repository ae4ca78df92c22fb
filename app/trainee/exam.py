"""Exam mode and what a session is measured against (docs/rehearse.md).

In exam mode the device's stop is not at the margin: the table runs
:data:`EXAM_REACH_MM` beyond the planned depth (or to where the drill leaves the CT, whichever
comes first) and its stop is there, so the virtual drill can go past the planned depth into the
margin zone and the canal, as a real drill can, and the session shows whether the student
stopped in time. The device still enforces that stop: it is never disabled. When the path
beyond the planned depth cannot carry a force table (padding or a slice gap there), the stop is
the planned depth (or the volume's end) and :attr:`ExamSetup.note` says why.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ctdrill.app.errors import AppInputError
from ctdrill.engine.grid import MAX_PLANNED_DEPTH_MM
from ctdrill.engine.path import PathInputError, PathResult, plan_path
from ctdrill.haptics.assessment import AssessmentContext
from ctdrill.haptics.profile_table import ProfileTable
from ctdrill.haptics.spec import DeviceSpec
from ctdrill.imaging.plan.types import Plan
from ctdrill.imaging.plan.write import plan_to_dict
from ctdrill.imaging.sampling.annulus import Hole
from ctdrill.imaging.volume import CTVolume

#: How far beyond the planned depth an exam's table (and its stop) reaches, mm: past a canal
#: at the margin (2 mm) and its whole diameter (2-4 mm) with room to spare; a hundred more
#: table rows at the 0.05 mm step.
EXAM_REACH_MM = 10.0
#: Exam stop bases: beyond the plan (the simulator), the planned depth (the path beyond it
#: cannot carry a table) or the surface of the nearest landmark (the robot).
EXAM_BASES = ("beyond_plan", "planned_depth", "canal_surface")


class ExamInputError(AppInputError):
    """Exam mode asked where it cannot run (a hardware device; a drill sequence's plan where
    one drill's exam table is asked for)."""


def exam_at_surface(device: DeviceSpec) -> bool:
    """Whether the exam's wall stands at the canal's surface: on hardware (the robot) it
    does, so a real hand can never drive the drill into the canal; the simulator's stands
    :data:`EXAM_REACH_MM` beyond the plan (module docstring)."""
    return not device.simulated


def surface_depth_mm(depth_mm: np.ndarray, clearance_mm: np.ndarray) -> float | None:
    """The deepest grid depth before the clearance first falls below 0 (the drill touches a
    landmark's surface there and never crosses it); None when it never does.

    Parameters
    ----------
    depth_mm : (D,) increasing depth grid, mm.
    clearance_mm : (D,) the drill's signed clearance at each depth, mm.
    """
    below = np.nonzero(np.asarray(clearance_mm) < 0.0)[0]
    if below.size == 0:
        return None
    return float(depth_mm[below[0] - 1]) if below[0] > 0 else 0.0


def refuse_exam_sequence(plan: Plan) -> None:
    """An exam table is one drill's (:func:`exam_setup`): a drill sequence's are its drills'
    (``ctdrill rehearse --exam`` runs each drill in exam mode).

    Raises
    ------
    ExamInputError
        For a plan with a drill sequence.
    """
    if len(plan.drills) > 1:
        drills = ", ".join(f"{d.diameter_mm:g}" for d in plan.drills)
        raise ExamInputError(
            f"exam mode: plan {plan.name!r} drills a sequence of {len(plan.drills)} drills "
            f"({drills} mm) and this exam rehearses one drill; rehearse the whole sequence in "
            "exam mode with 'ctdrill rehearse --exam', or give a plan with its final drill "
            "alone"
        )


@dataclass(frozen=True, eq=False)
class ExamSetup:
    """The exam's table and the path it was computed on.

    Attributes
    ----------
    table : the uploaded table; its stop is the exam's stop.
    path : the path the table comes from (beyond the plan, or the plan's own).
    basis : ``beyond_plan`` or ``planned_depth`` (:data:`EXAM_BASES`).
    note : why the stop is where it is, in words.
    """

    table: ProfileTable
    path: PathResult
    basis: str
    note: str

    def to_json(self) -> dict[str, Any]:
        """``summary.json`` ``exam``."""
        return {
            "enabled": True,
            "stop_depth_mm": round(float(self.table.stop_depth_mm), 4),
            "stop_basis": self.basis,
            "note": self.note,
        }


def _free_stop_mm(path: PathResult) -> float:
    """The path's stop without the margin: its planned depth or where it leaves the CT."""
    oov = path.out_of_volume_depth_mm
    return float(path.planned_depth_mm if oov is None else min(oov, path.planned_depth_mm))


def exam_setup(
    volume: CTVolume,
    plan: Plan,
    guarded: PathResult,
    *,
    interpolate_gaps: bool = False,
    inner_holes: Sequence[Hole] = (),
    at_surface: bool = False,
) -> ExamSetup:
    """The exam table of the one-drill ``plan`` (whose guarded path is ``guarded``): module
    docstring. ``inner_holes``: the holes of the drills before it in a sequence (the table is
    cut around them, as ``guarded`` is). ``at_surface`` (the robot, :func:`exam_at_surface`):
    the stop moves from the margin to the surface of the nearest landmark, not beyond."""
    refuse_exam_sequence(plan)
    reach = min(plan.planned_depth_mm + EXAM_REACH_MM, MAX_PLANNED_DEPTH_MM)
    extended = replace(
        plan, target_lps=plan.point_at_depth_lps(reach), implant=None, overdrill_mm=0.0
    )
    try:
        path = plan_path(
            volume,
            extended,
            guarded.calibration,
            interpolate_gaps=interpolate_gaps,
            inner_holes=inner_holes,
        )
    except PathInputError as exc:
        stop = _free_stop_mm(guarded)
        note = (
            f"the stop is at {stop:.2f} mm, the planned depth (or the CT's end): the path "
            f"beyond it cannot carry a force table ({exc})"
        )
        table = ProfileTable.from_profile(
            guarded.profile, stop, goal_depth_mm=float(guarded.stop_depth_mm)
        )
        return ExamSetup(table, guarded, "planned_depth", note)
    stop = _free_stop_mm(path)
    surface = (
        surface_depth_mm(path.depth_mm, path.min_clearance_per_depth_mm)
        if at_surface and path.landmarks
        else None
    )
    if surface is not None and surface < stop:
        note = (
            f"the wall moved from the margin to the landmark's surface: the stop is at "
            f"{surface:.2f} mm, where the drill touches it (the device never lets it in); past "
            f"the max safe depth {guarded.max_safe_depth_mm:.2f} mm the drill enters the "
            "margin zone"
        )
        table = ProfileTable.from_profile(
            path.profile, surface, goal_depth_mm=float(guarded.stop_depth_mm)
        )
        return ExamSetup(table, path, "canal_surface", note)
    where = (
        f"{EXAM_REACH_MM:g} mm beyond the planned depth"
        if path.out_of_volume_depth_mm is None
        else "where the drill leaves the CT"
    )
    note = (
        f"no wall at the margin: the stop is at {stop:.2f} mm, {where}; past the max safe "
        f"depth {guarded.max_safe_depth_mm:.2f} mm the drill enters the margin zone"
    )
    table = ProfileTable.from_profile(
        path.profile, stop, goal_depth_mm=float(guarded.stop_depth_mm)
    )
    return ExamSetup(table, path, "beyond_plan", note)


def assessment_context(
    guarded: PathResult, clearance: PathResult | None = None
) -> AssessmentContext:
    """What a session on ``guarded``'s plan is measured against; ``clearance`` is the path
    whose clearance profile reaches as deep as the session's table (the exam's), default
    ``guarded``. A max safe depth the search only bounded (no margin binds within it) is
    taken as beyond reach."""
    deep = guarded if clearance is None else clearance
    max_safe = math.inf
    for path in (guarded, deep):
        if path.landmarks and not path.max_safe_depth_capped:
            max_safe = float(path.max_safe_depth_mm)
            break
    curve = deep.min_clearance_per_depth_mm if deep.landmarks else np.empty(0)
    return AssessmentContext(
        planned_depth_mm=float(guarded.planned_depth_mm),
        max_safe_depth_mm=max_safe,
        goal_depth_mm=float(guarded.stop_depth_mm),
        clearance_depth_mm=np.asarray(deep.depth_mm, dtype=float) if deep.landmarks else curve,
        clearance_mm=np.asarray(curve, dtype=float),
    )


def plan_hash(plan: Plan) -> str:
    """SHA-256 (hex) of the plan's ``ctdrill-plan/1`` document without its name: the same
    trajectory, drill, settings and landmarks give the same hash, whatever the file is called.
    """
    try:
        doc = plan_to_dict(plan)
    except ValueError:  # a mask landmark without a file: its geometry stands in
        doc = {
            "entry_mm": plan.entry_lps.tolist(),
            "target_mm": plan.target_lps.tolist(),
            "drill": plan.drill.to_json(),
            "margin_mm": plan.margin_mm,
            "landmarks": [lm.name for lm in plan.landmarks],
        }
    doc.pop("name", None)
    text = json.dumps(doc, sort_keys=True, separators=(",", ":"), allow_nan=False)
    return hashlib.sha256(f"ctdrill-plan-hash/1:{text}".encode()).hexdigest()
