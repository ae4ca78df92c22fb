"""Drill sequences: every drill of a plan along its axis, each cutting around the holes before it.

A plan's ``drills`` (pilot 2.0 mm, then 2.8, 3.5 ...) are drilled in order along the same axis.
Drill ``k`` is :func:`ctdrill.engine.path.plan_path` of the single-drill plan
``plan.drilled(k)``: its own lip, clearance (its own radius), max safe depth and stop, with
``inner_holes`` the holes of drills ``0..k-1``. Each hole reaches the depth that drill
**actually reached**, not its planned depth: in the export the drill's stop depth (it stops
there: the margin, the volume's end, or the planned depth); in a rehearsal the deepest tip
position of its session (:mod:`ctdrill.app.rehearse_sequence`). The final drill's stop rules the
plan. A single-drill plan is exactly :func:`plan_path` of ``plan.drilled(0)``.

**The osteotomy follows the implant.** With an implant, the plan's target is its apex and
every drill's full diameter reaches it, so each drill's planned depth is the apex's plus its
own tip length (:meth:`~ctdrill.imaging.plan.types.Plan.drilled`): its profile, clearance,
margin check and stop are computed to that depth. Without an implant ``drilled(k)`` is
``for_drill(k)``. The implant's outcome (:func:`ctdrill.engine.implant.implant_outcome`) is
computed once and shared by every drill.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from ctdrill.engine.grid import DEFAULT_DEPTH_STEP_MM
from ctdrill.engine.implant import ImplantOutcome
from ctdrill.engine.path import PathResult, plan_path
from ctdrill.engine.path_warnings import dedupe_warnings
from ctdrill.imaging.plan.types import Plan
from ctdrill.imaging.sampling.annulus import Hole
from ctdrill.imaging.sampling.lip import DEFAULT_N_ANGLES, DEFAULT_N_RINGS
from ctdrill.imaging.volume import CTVolume, LoadWarning
from ctdrill.model.calibration import Calibration

#: Folder of drill ``k`` (1-based) of a sequence inside an export or rehearsal folder.
DRILL_FOLDER = "drill_{}"


def drill_folder(index: int) -> str:
    """``drill_1``, ``drill_2`` ... for the 0-based ``index``."""
    return DRILL_FOLDER.format(index + 1)


@dataclass(frozen=True, eq=False)
class SequenceResult:
    """Every drill of a plan, in drilling order.

    Attributes
    ----------
    plan : the whole plan (all its drills).
    steps : one :class:`PathResult` per drill; ``steps[k].plan`` is ``plan.drilled(k)`` and
        ``steps[k].inner_holes`` the holes of the drills before it.
    """

    plan: Plan
    steps: tuple[PathResult, ...]

    @property
    def final(self) -> PathResult:
        """The final drill's path: its stop rules the plan."""
        return self.steps[-1]

    @property
    def warnings(self) -> tuple[LoadWarning, ...]:
        """Every drill's warnings, each code + message once."""
        return dedupe_warnings([w for step in self.steps for w in step.warnings])


def holes_before(plan: Plan, reached_mm: Sequence[float]) -> tuple[Hole, ...]:
    """The holes the first ``len(reached_mm)`` drills of ``plan`` left, each at its reached
    depth, mm."""
    return tuple(Hole.of(plan.drills[j], d) for j, d in enumerate(reached_mm))


def drill_path(
    volume: CTVolume,
    plan: Plan,
    index: int,
    calibration: Calibration,
    reached_mm: Sequence[float],
    **options: Any,
) -> PathResult:
    """Drill ``index`` of ``plan`` as it is drilled (``plan.drilled(index)``: with an implant,
    to the apex plus its tip) after the drills before it reached ``reached_mm`` (one depth per
    earlier drill, mm); ``options`` go to :func:`plan_path`."""
    if len(reached_mm) != index:
        raise ValueError(f"drill {index + 1}: give the reached depth of the {index} drills before")
    holes = holes_before(plan, reached_mm)
    return plan_path(volume, plan.drilled(index), calibration, inner_holes=holes, **options)


def plan_sequence(
    volume: CTVolume,
    plan: Plan,
    calibration: Calibration,
    *,
    depth_step_mm: float = DEFAULT_DEPTH_STEP_MM,
    n_rings: int = DEFAULT_N_RINGS,
    n_angles: int = DEFAULT_N_ANGLES,
    interpolate_gaps: bool = False,
    implant: ImplantOutcome | None = None,
) -> SequenceResult:
    """Every drill of ``plan`` in order, each stopping at its own stop depth and leaving its
    hole there for the next (see the module docstring). Options as :func:`plan_path`'s
    (``implant``: the plan's implant outcome when computed already, else the first drill's)."""
    steps: list[PathResult] = []
    for k in range(len(plan.drills)):
        if k == 1 and implant is None:
            implant = steps[0].implant  # the same body for every drill
        steps.append(
            drill_path(
                volume,
                plan,
                k,
                calibration,
                [s.stop_depth_mm for s in steps],
                depth_step_mm=depth_step_mm,
                n_rings=n_rings,
                n_angles=n_angles,
                interpolate_gaps=interpolate_gaps,
                implant=implant,
            )
        )
    return SequenceResult(plan, tuple(steps))
