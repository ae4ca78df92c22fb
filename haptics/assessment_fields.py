"""The fields of a rehearsal's ``assessment`` (a contract: docs/rehearse.md), what a session is
measured against, and a drill sequence's assessment combined from its drills'.

The assessor that measures them on a trace is :class:`ctdrill.haptics.assessment.Assessor`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from ctdrill.haptics.score import score_of

#: The fields of ``summary.json`` ``assessment``, in order (a contract: docs/rehearse.md).
ASSESSMENT_FIELDS = (
    "depth_error_mm",
    "overshoot_mm",
    "breach",
    "time_in_margin_s",
    "canal_entered",
    "peak_hand_force_n",
    "mean_hand_force_n",
    "time_to_planned_s",
    "feed_cv",
    "reaction_ms",
    "wall_contacts",
    "peak_wall_force_n",
    "goal_depth_mm",
    "attempted",
    "hand_force_cv",
    "plunge_mm",
    "wall_press_s",
    "wall_overrun_mm",
    "display_lag_ms",
    "display_lagged",
    "score",
)
#: The fields that are booleans, whole numbers, and may be null (the others are finite numbers).
BOOL_FIELDS = ("breach", "canal_entered", "attempted", "display_lagged")
INT_FIELDS = ("wall_contacts",)
NULLABLE_FIELDS = ("time_to_planned_s", "feed_cv", "reaction_ms", "hand_force_cv", "display_lag_ms")


@dataclass(frozen=True)
class AssessmentContext:
    """What the plan says a session is measured against.

    Attributes
    ----------
    planned_depth_mm : ``|target - entry|`` (the drilled depth with an implant), mm.
    max_safe_depth_mm : the deepest depth keeping every margin, mm (inf: none binds).
    goal_depth_mm : the planned osteotomy's end as the plan allows it: ``min(planned depth,
        max safe depth)`` (the guarded stop, where the volume's end may come first), mm.
    clearance_depth_mm, clearance_mm : (D,) the depths and the smallest signed clearance to a
        landmark there (negative inside one), mm; empty without landmarks.
    """

    planned_depth_mm: float
    max_safe_depth_mm: float
    goal_depth_mm: float
    clearance_depth_mm: np.ndarray
    clearance_mm: np.ndarray

    def clearance_at_mm(self, depth_mm: float) -> float | None:
        """Smallest clearance with the tip at ``depth_mm`` (linear, clamped), mm; None without
        landmarks."""
        if self.clearance_mm.size == 0:
            return None
        return float(np.interp(depth_mm, self.clearance_depth_mm, self.clearance_mm))


@dataclass(frozen=True)
class Assessment:
    """The ``assessment`` of a session (docs/rehearse.md; :data:`ASSESSMENT_FIELDS`)."""

    depth_error_mm: float
    overshoot_mm: float
    breach: bool
    time_in_margin_s: float
    canal_entered: bool
    peak_hand_force_n: float
    mean_hand_force_n: float
    time_to_planned_s: float | None
    feed_cv: float | None
    reaction_ms: float | None
    wall_contacts: int
    peak_wall_force_n: float
    goal_depth_mm: float
    attempted: bool
    hand_force_cv: float | None
    plunge_mm: float
    wall_press_s: float
    wall_overrun_mm: float
    display_lag_ms: float | None
    display_lagged: bool
    score: float

    def to_json(self) -> dict[str, Any]:
        """The fields in :data:`ASSESSMENT_FIELDS` order (JSON-ready, finite or null)."""
        return asdict(self)


def _worst(values: Sequence[float | None]) -> float | None:
    known = [v for v in values if v is not None]
    return max(known) if known else None


def combine_assessments(
    drills: Sequence[dict[str, Any]], *, drills_planned: int, planned_depth_mm: float
) -> Assessment:
    """The assessment of a drill sequence from its drills' (each a session's
    ``assessment``, in drilling order; the drills run, ``drills_planned`` in all), with the
    same fields (docs/rehearse.md, "Drill sequences"):

    * ``depth_error_mm``, ``goal_depth_mm``, ``attempted``: the final drill's (it drills the
      implant's bed); a final drill that never ran reached 0 mm: the error is minus its goal
      (the last run drill's, else ``planned_depth_mm``) and the sequence is not attempted;
    * ``overshoot_mm``, ``peak_hand_force_n``, ``peak_wall_force_n``, ``plunge_mm``,
      ``wall_press_s``, ``wall_overrun_mm``: the largest; ``wall_contacts``: the most of any
      drill (each drill meets its own stop once when it is done well);
      ``feed_cv``, ``hand_force_cv``, ``reaction_ms``, ``display_lag_ms``: the largest known;
    * ``breach``, ``canal_entered``, ``display_lagged``: any drill's;
    * ``time_in_margin_s``: summed; ``mean_hand_force_n``: the drills' means averaged;
    * ``time_to_planned_s``: the drills' times to their goals summed, null unless every
      planned drill ran and reached its goal;
    * ``score``: :func:`score_of` of these fields.
    """
    if not drills or drills_planned < len(drills):
        raise ValueError("give the assessments of the drills run, at most the drills planned")
    final_ran = len(drills) == drills_planned
    last = drills[-1]
    goal = float(last.get("goal_depth_mm", planned_depth_mm)) if final_ran else planned_depth_mm
    times = [d["time_to_planned_s"] for d in drills]
    fields: dict[str, Any] = {
        "depth_error_mm": last["depth_error_mm"] if final_ran else round(-goal, 4),
        "overshoot_mm": max(float(d["overshoot_mm"]) for d in drills),
        "breach": any(bool(d["breach"]) for d in drills),
        "time_in_margin_s": round(sum(float(d["time_in_margin_s"]) for d in drills), 4),
        "canal_entered": any(bool(d["canal_entered"]) for d in drills),
        "peak_hand_force_n": max(float(d["peak_hand_force_n"]) for d in drills),
        "mean_hand_force_n": round(
            sum(float(d["mean_hand_force_n"]) for d in drills) / len(drills), 3
        ),
        "time_to_planned_s": round(sum(times), 4)
        if final_ran and all(t is not None for t in times)
        else None,
        "feed_cv": _worst([d["feed_cv"] for d in drills]),
        "reaction_ms": _worst([d["reaction_ms"] for d in drills]),
        "wall_contacts": max(int(d["wall_contacts"]) for d in drills),
        "peak_wall_force_n": max(float(d["peak_wall_force_n"]) for d in drills),
        "goal_depth_mm": round(goal, 4),
        "attempted": bool(final_ran and last.get("attempted", True)),
        "hand_force_cv": _worst([d.get("hand_force_cv") for d in drills]),
        "plunge_mm": max(float(d.get("plunge_mm", 0.0)) for d in drills),
        "wall_press_s": max(float(d.get("wall_press_s", 0.0)) for d in drills),
        "wall_overrun_mm": max(float(d.get("wall_overrun_mm", 0.0)) for d in drills),
        "display_lag_ms": _worst([d.get("display_lag_ms") for d in drills]),
        "display_lagged": any(bool(d.get("display_lagged")) for d in drills),
    }
    return Assessment(**fields, score=score_of(fields))
