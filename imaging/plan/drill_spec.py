"""A drill and a drill sequence: the values every plan, protocol and path shares.

:class:`DrillSpec` (re-exported by :mod:`ctdrill.imaging.plan.types`) is one twist drill; a
sequence of them (``Plan.drills``, an implant's protocol) is drilled in order along one axis,
each wider than the one before (:func:`sequence_error`). An implant's drilling protocol as data
(:func:`protocol_error`, :func:`protocol_json`) is checked here too, below the implants that
carry one (:mod:`ctdrill.imaging.plan.implants`) and the generic rule that makes one
(:mod:`ctdrill.imaging.plan.protocol`).

**The tip rule** (:func:`tip_length_rule_mm`, the one rule): a drill's tip is the cone of its
point angle, ``tip = d / (2 tan(point_angle / 2))``, rounded to 0.1 mm (a 120 deg point: 0.6 mm
for a 2.0 mm drill, 0.8 mm for 2.8 mm, 1.0 mm for 3.5 mm). Every drill follows it wherever it
comes from (an implant's protocol, a plan file, a Slicer description, the window): a drill built
without a tip length gets the rule's. A tip given that differs from the rule is an **override**
(:attr:`DrillSpec.tip_override`): it is kept, and named by the ``drill_tip_override`` warning
(:func:`tip_override_warnings`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from ctdrill.warning_codes import LoadWarning

#: Keys of a drill object (plan files, markups, summaries).
_DRILL_KEYS = {"diameter_mm", "tip_length_mm", "blades", "rpm", "point_angle_deg"}
_MAX_BLADES = 100
#: Most drills accepted in a sequence: clinical sequences use 2-5; more is a typo, and each
#: drill costs one full path computation.
MAX_DRILLS = 12
#: Required key of one drill of a protocol.
PROTOCOL_DRILL_KEYS = ("diameter_mm",)
#: Optional keys of one drill of a protocol: its tip (else the tip rule's) and point angle.
PROTOCOL_OPTIONAL_KEYS = ("tip_length_mm", "point_angle_deg")
#: Largest accepted tip length of a protocol drill, mm (beyond: a unit error).
MAX_PROTOCOL_TIP_MM = 5.0
#: Point angle of a drill that gives none, degrees (a twist drill's 118-120 deg point).
POINT_ANGLE_DEG = 120.0
#: Accepted point angles, degrees (open interval): a flat bottom is 180, a needle 0.
POINT_ANGLE_RANGE_DEG = (30.0, 180.0)
#: Tip lengths of the rule are rounded to this, mm.
TIP_ROUND_MM = 0.1
#: A given tip within this of the rule's is the rule's (not an override), mm.
TIP_OVERRIDE_TOLERANCE_MM = 1e-6
#: The warning code of a drill whose given tip differs from the rule's.
TIP_OVERRIDE_CODE = "drill_tip_override"


def tip_length_rule_mm(diameter_mm: float, point_angle_deg: float = POINT_ANGLE_DEG) -> float:
    """The tip (cone) length of a drill of ``diameter_mm`` with a ``point_angle_deg`` point,
    mm: ``d / (2 tan(angle / 2))`` rounded half up to :data:`TIP_ROUND_MM` (module docstring).
    """
    raw = float(diameter_mm) / (2.0 * math.tan(math.radians(float(point_angle_deg) / 2.0)))
    return round(math.floor(raw / TIP_ROUND_MM + 0.5 + 1e-9) * TIP_ROUND_MM, 6)


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
    """The drill: diameter and tip (cone) length in mm, number of blades, speed in rpm, point
    angle in degrees.

    ``tip_length_mm`` left out (NaN) is the tip rule's (:func:`tip_length_rule_mm` of the
    diameter and point angle); a tip given that differs from it is an override
    (:attr:`tip_override`).
    """

    diameter_mm: float = 2.0
    tip_length_mm: float = math.nan
    blades: int = 2
    rpm: float = 900.0
    point_angle_deg: float = POINT_ANGLE_DEG

    def __post_init__(self) -> None:
        tip = self.tip_length_mm
        if isinstance(tip, float) and math.isnan(tip) and positive_finite(self.diameter_mm):
            lo, hi = POINT_ANGLE_RANGE_DEG
            angle = self.point_angle_deg
            if positive_finite(angle) and lo < float(angle) < hi:
                object.__setattr__(
                    self, "tip_length_mm", tip_length_rule_mm(self.diameter_mm, angle)
                )

    @property
    def tip_rule_mm(self) -> float:
        """The tip length the rule gives this drill's diameter and point angle, mm."""
        return tip_length_rule_mm(self.diameter_mm, self.point_angle_deg)

    @property
    def tip_override(self) -> bool:
        """Whether the tip length was given and differs from :attr:`tip_rule_mm`."""
        return not abs(self.tip_length_mm - self.tip_rule_mm) <= TIP_OVERRIDE_TOLERANCE_MM

    @property
    def name(self) -> str:
        """The drill as a surgeon names it: its diameter (``3.5 mm drill``)."""
        return f"{self.diameter_mm:g} mm drill"

    @property
    def radius_mm(self) -> float:
        """Half the diameter, mm."""
        return self.diameter_mm / 2.0

    def to_json(self) -> dict[str, float | int]:
        """The settings by their plan-file keys (plans, markups and summaries use them); the
        point angle only when it is not :data:`POINT_ANGLE_DEG`."""
        return {
            "diameter_mm": self.diameter_mm,
            "tip_length_mm": self.tip_length_mm,
            "blades": self.blades,
            "rpm": self.rpm,
            **(
                {}
                if self.point_angle_deg == POINT_ANGLE_DEG
                else {"point_angle_deg": self.point_angle_deg}
            ),
        }


def tip_override_warnings(drills: Sequence[DrillSpec], label: str) -> list[LoadWarning]:
    """One ``drill_tip_override`` warning per drill of ``drills`` whose tip differs from the
    rule's, naming the drill by its diameter; ``label`` names the trajectory."""
    return [
        LoadWarning(
            TIP_OVERRIDE_CODE,
            f"{label}: the {d.name}'s tip is {d.tip_length_mm:g} mm, an override of the tip "
            f"rule's {d.tip_rule_mm:g} mm ({d.point_angle_deg:g} deg point): its depth, stop "
            "and clearance use the override",
        )
        for d in drills
        if d.tip_override
    ]


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
    """A protocol as implant objects write it: ``diameter_mm`` and ``tip_length_mm`` each, and
    ``point_angle_deg`` when it is not the default's."""
    return [
        {
            "diameter_mm": d.diameter_mm,
            "tip_length_mm": d.tip_length_mm,
            **(
                {}
                if d.point_angle_deg == POINT_ANGLE_DEG
                else {"point_angle_deg": d.point_angle_deg}
            ),
        }
        for d in drills
    ]


def protocol_conflicts(
    drills: Sequence[DrillSpec], protocol: Sequence[DrillSpec]
) -> list[tuple[int, DrillSpec, DrillSpec]]:
    """Where a trajectory's ``drills`` contradict its implant's ``protocol``: ``(index, drill,
    protocol drill)`` for each drill of a diameter the protocol lists with another tip length or
    point angle (a plan is never saved contradicting itself)."""
    by_diameter = {round(p.diameter_mm, 6): p for p in protocol}
    out = []
    for i, d in enumerate(drills):
        p = by_diameter.get(round(d.diameter_mm, 6))
        if p is not None and (
            abs(p.tip_length_mm - d.tip_length_mm) > TIP_OVERRIDE_TOLERANCE_MM
            or p.point_angle_deg != d.point_angle_deg
        ):
            out.append((i, d, p))
    return out
