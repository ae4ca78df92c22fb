"""A drill and a drill sequence: the values every plan, protocol and path shares.

:class:`DrillSpec` (re-exported by :mod:`ctdrill.imaging.plan.types`) is one twist drill; a
sequence of them (``Plan.drills``, an implant's protocol) is drilled in order along one axis,
each wider than the one before (:func:`sequence_error`). An implant's drilling protocol as data
(:func:`protocol_error`, :func:`protocol_json`) is checked here too, below the implants that
carry one (:mod:`ctdrill.imaging.plan.implants`) and the generic rule that makes one
(:mod:`ctdrill.imaging.plan.protocol`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

#: Keys of a drill object (plan files, markups, summaries).
_DRILL_KEYS = {"diameter_mm", "tip_length_mm", "blades", "rpm"}
_MAX_BLADES = 100
#: Most drills accepted in a sequence: clinical sequences use 2-5; more is a typo, and each
#: drill costs one full path computation.
MAX_DRILLS = 12
#: Keys of one drill of a protocol, both required.
PROTOCOL_DRILL_KEYS = ("diameter_mm", "tip_length_mm")
#: Largest accepted tip length of a protocol drill, mm (beyond: a unit error).
MAX_PROTOCOL_TIP_MM = 5.0


def positive_finite(value: object) -> bool:
    """A finite number > 0 (not a bool; an integer beyond the float range is not finite)."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return False
    try:
        return math.isfinite(float(value)) and float(value) > 0.0
    except OverflowError:
        return False


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


def protocol_error(drills: Sequence[DrillSpec], *, max_diameter_mm: float) -> str | None:
    """What is wrong with a drilling protocol (an implant's ``drills``), starting with the field
    (``drills[1].diameter_mm must ...``), or None; an empty protocol is valid (none given).
    Diameters are bounded by ``max_diameter_mm`` (the implants' own bound), tips by
    :data:`MAX_PROTOCOL_TIP_MM`."""
    for i, d in enumerate(drills):
        for key, value, top in (
            ("diameter_mm", d.diameter_mm, max_diameter_mm),
            ("tip_length_mm", d.tip_length_mm, MAX_PROTOCOL_TIP_MM),
        ):
            if not positive_finite(value):
                return f"drills[{i}].{key} must be a positive number (mm)"
            if not float(value) <= top:
                return f"drills[{i}].{key} must be at most {top:g} mm (check the units)"
    problem = sequence_error(drills) if drills else None
    return None if problem is None else "drills" + problem


def protocol_json(drills: Sequence[DrillSpec]) -> list[dict[str, float]]:
    """A protocol as implant objects write it: ``diameter_mm`` and ``tip_length_mm`` each."""
    return [{"diameter_mm": d.diameter_mm, "tip_length_mm": d.tip_length_mm} for d in drills]
