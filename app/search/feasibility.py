"""Whether one candidate axis is safe enough to suggest: the rule, defined once.

A candidate (the plan with the candidate's entry and target) is **feasible** when

- every drill of the osteotomy, each drilled as it is for the implant
  (:meth:`~ctdrill.imaging.plan.types.Plan.drilled`: full diameter to the apex, its tip
  beyond by its own tip length), keeps every landmark's margin at its planned depth
  (:func:`~ctdrill.imaging.plan.safety.margin_warnings`, ``plan_violates_margin``);
- the implant body at its placement keeps every landmark's margin
  (``implant_violates_margin``) and its bone walls show no
  ``cortical_perforation`` and no ``thin_wall`` (``min_mm`` at least the plan's
  ``min_wall_mm``, :func:`~ctdrill.imaging.sampling.wall_warnings.bone_wall_warnings`); walls with
  no known direction at all (``min_mm`` None: the CT ends around the implant) are not a
  known wall, so the candidate is not feasible (``bone_walls_unknown``).

The findings are the plan's verdict (:mod:`ctdrill.engine.verdict`, which the window's banner
reads too); which codes block is the warning registry's ``blocks_suggest``. The implant's part
is :func:`ctdrill.engine.implant.implant_outcome`, the same function whose warnings
``ctdrill export`` writes, so a suggested axis and its export agree. Without an
implant only the drills are checked (there is no body, hence no wall). The rules and their
thresholds are the imaging package's; this module only combines them.
"""

from __future__ import annotations

from dataclasses import dataclass

from ctdrill.engine.verdict import plan_verdict
from ctdrill.imaging.plan.types import Plan
from ctdrill.imaging.sampling.walls import BoneWalls
from ctdrill.imaging.volume import CTVolume
from ctdrill.warning_codes import LoadWarning, blocking_codes

#: The warning codes that make a candidate infeasible (the registry's ``blocks_suggest``).
BLOCKING_CODES = blocking_codes()


@dataclass(frozen=True)
class Feasibility:
    """One candidate's verdict.

    Attributes
    ----------
    problems : the warnings of every rule it breaks (codes of :data:`BLOCKING_CODES`);
        empty when feasible.
    implant_clearance_mm : the implant body's signed clearance to the binding landmark, mm
        (None without an implant or landmark).
    min_wall_mm : the thinnest known bone wall around the implant, mm (None without an
        implant, or when no wall is known).
    drill_clearance_mm : the least clearance of any drill at its drilled depth to any
        landmark, mm (None without landmarks).
    walls : the implant's bone walls (None without an implant).
    """

    problems: tuple[LoadWarning, ...]
    implant_clearance_mm: float | None
    min_wall_mm: float | None
    drill_clearance_mm: float | None = None
    walls: BoneWalls | None = None

    @property
    def feasible(self) -> bool:
        """No rule broken."""
        return not self.problems

    @property
    def codes(self) -> tuple[str, ...]:
        """The codes of :attr:`problems`, in order, each once."""
        return tuple(dict.fromkeys(w.code for w in self.problems))


def check_candidate(volume: CTVolume, plan: Plan) -> Feasibility:
    """The feasibility of ``plan`` (a candidate's axis, its drills and implant) on ``volume``:
    the blocking findings of its verdict (:func:`ctdrill.engine.verdict.plan_verdict`)."""
    verdict = plan_verdict(volume, plan)
    problems: list[LoadWarning] = []
    for k, w in verdict.blocking():
        if k is None:
            problems.append(w)
        else:
            drill = verdict.plan.drills[k]
            problems.append(
                LoadWarning(w.code, f"drill {k + 1} ({drill.diameter_mm:g} mm): {w.message}")
            )
    outcome = verdict.implant
    clear = verdict.drill_clearance_mm
    return Feasibility(
        problems=tuple(problems),
        implant_clearance_mm=None if outcome is None else outcome.clearance_mm,
        min_wall_mm=None if outcome is None else outcome.walls.min_mm,
        drill_clearance_mm=float(clear.min()) if clear.size else None,
        walls=None if outcome is None else outcome.walls,
    )
