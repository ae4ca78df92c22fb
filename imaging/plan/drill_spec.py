"""A drill and a drill sequence: the values every plan, protocol and path shares.

:class:`DrillSpec` (re-exported by :mod:`ctdrill.imaging.plan.types`) is one twist drill; a
sequence of them (``Plan.drills``, an implant's protocol) is drilled in order along one axis,
each wider than the one before (:func:`sequence_error`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

#: Keys of a drill object (plan files, markups, summaries).
_DRILL_KEYS = {"diameter_mm", "tip_length_mm", "blades", "rpm"}
_MAX_BLADES = 100
#: Most drills accepted in a sequence: clinical sequences use 2-5; more is a typo, and each
#: drill costs one full path computation.
MAX_DRILLS = 12


@dataclass(frozen=True)
class DrillSpec:
    """The drill: diameter and tip (cone) length in mm, number of blades, speed in rpm."""

    diameter_mm: float = 2.0
    tip_length_mm: float = 0.6
    blades: int = 2
    rpm: float = 900.0

    @property
    def radius_mm(self) -> float:
        """Half the diameter, mm."""
        return self.diameter_mm / 2.0

    def to_json(self) -> dict[str, float | int]:
        """The four settings by their plan-file keys (plans, markups and summaries use them)."""
        return {
            "diameter_mm": self.diameter_mm,
            "tip_length_mm": self.tip_length_mm,
            "blades": self.blades,
            "rpm": self.rpm,
        }


def sequence_error(drills: Sequence[DrillSpec]) -> str | None:
    """Why ``drills`` is not a drill sequence, or None when it is one.

    A sequence holds 1 to :data:`MAX_DRILLS` drills in drilling order, each wider than the one
    before (a drill no wider than the previous hole would cut nothing). The message names the
    offending entry as ``drills[i]``.
    """
    if len(drills) == 0:
        return " must list at least one drill (or give the one drill as drill)"
    if len(drills) > MAX_DRILLS:
        return f" lists {len(drills)} drills, more than the {MAX_DRILLS} accepted"
    for i in range(1, len(drills)):
        prev, cur = drills[i - 1].diameter_mm, drills[i].diameter_mm
        if not cur > prev:
            return (
                f"[{i}].diameter_mm ({cur:g} mm) must be larger than drills[{i - 1}].diameter_mm "
                f"({prev:g} mm): list the drills in drilling order, each wider than the hole "
                "before it"
            )
    return None
