"""Implant drilling protocols: the drills that prepare an implant's osteotomy.

A protocol (``ImplantSpec.drills``) lists the drills in drilling order, the last one sized for
the implant, each with its tip length. The plan's target stays the implant's apex: each drill's
full diameter reaches it, so the drill's tip goes beyond by its own tip length, and that tip
depth is the drill's planned depth (``Plan.drilled(k)``), checked against every margin.

**The generic rule** (:func:`generic_protocol`, the protocols of the generic library): manufacturers
publish sequences that start with a pilot drill of about 2 mm and widen in steps of 0.5-0.8 mm
to a final drill 0.3-0.8 mm narrower than the implant (the implant's threads cut the rest; a
smaller final drill for tapered bodies and dense bone); their drills cut 0.4-1.5 mm beyond the
implant's length (DESIGN.md section 5). Generic, no brand:

- pilot :data:`PILOT_DIAMETER_MM` (2.0 mm);
- final drill :data:`FINAL_UNDERSIZE_MM` (0.6 mm) narrower than the implant's diameter;
- between them equal steps of at most :data:`MAX_STEP_MM` (0.8 mm), every diameter rounded to
  0.1 mm;
- each drill's tip the project's one tip rule
  (:func:`~ctdrill.imaging.plan.drill_spec.tip_length_rule_mm`): a cone of
  :data:`POINT_ANGLE_DEG` (120 deg, a twist drill's point), ``tip = d / (2 tan 60 deg)``,
  rounded to 0.1 mm (0.6 mm for the 2.0 mm pilot, as the default drill; 1.3 mm for a 4.4 mm
  final drill).

**Checks** (:func:`final_drill_warnings`, code ``final_drill_mismatch``): a final drill wider
than the implant (no thread engages: no primary stability), or narrower than both the
implant's apex diameter and the implant's diameter less :data:`MAX_UNDERSIZE_MM` (0.8 mm, the
most the published sequences under-prepare; a parallel-walled body's apex is as wide as the
body, and its final drill is normally 0.3-0.8 mm narrower).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from ctdrill.imaging.plan.drill_spec import POINT_ANGLE_DEG as POINT_ANGLE_DEG
from ctdrill.imaging.plan.drill_spec import DrillSpec, tip_length_rule_mm
from ctdrill.imaging.plan.implants import ImplantSpec
from ctdrill.warning_codes import LoadWarning

if TYPE_CHECKING:
    from ctdrill.imaging.plan.types import Plan

#: The generic pilot drill's diameter, mm.
PILOT_DIAMETER_MM = 2.0
#: Largest diameter step between consecutive drills of the generic rule, mm.
MAX_STEP_MM = 0.8
#: The generic final drill is this much narrower than the implant's diameter, mm.
FINAL_UNDERSIZE_MM = 0.6
#: Most a final drill may be narrower than the implant's diameter before it is reported
#: (unless it still reaches the apex diameter), mm.
MAX_UNDERSIZE_MM = 0.8
#: Generic diameters and tip lengths are rounded to this, mm.
ROUND_MM = 0.1
#: The warning code of a plan whose final drill does not suit its implant.
MISMATCH_CODE = "final_drill_mismatch"
#: The code of the note saying a plan drills its implant's protocol.
PROTOCOL_NOTE_CODE = "implant_protocol"


def _tenths(value_mm: float) -> int:
    """``value_mm`` in whole :data:`ROUND_MM` steps, rounded half up."""
    return math.floor(value_mm / ROUND_MM + 0.5 + 1e-9)


def _mm(steps: int) -> float:
    """Whole :data:`ROUND_MM` steps back to mm, as the shortest decimal (2.8, not 2.8000...3)."""
    return round(steps * ROUND_MM, 6)


def generic_tip_length_mm(diameter_mm: float) -> float:
    """The generic drill's tip (cone) length for ``diameter_mm``, mm (module docstring)."""
    return tip_length_rule_mm(diameter_mm, POINT_ANGLE_DEG)


def generic_protocol(diameter_mm: float) -> tuple[DrillSpec, ...]:
    """The generic protocol for an implant of ``diameter_mm`` (module docstring), in drilling
    order; one drill when the final drill is no wider than the pilot."""
    final = _tenths(diameter_mm - FINAL_UNDERSIZE_MM)
    pilot = _tenths(PILOT_DIAMETER_MM)
    if final <= pilot:
        sizes = [final]
    else:
        steps = math.ceil((final - pilot) / _tenths(MAX_STEP_MM))
        sizes = [pilot + math.floor((final - pilot) * k / steps + 0.5) for k in range(steps + 1)]
    return tuple(DrillSpec(_mm(t), generic_tip_length_mm(_mm(t))) for t in sizes)


def protocol_drills(spec: ImplantSpec) -> tuple[tuple[DrillSpec, ...], bool]:
    """The implant's protocol (its own, else :func:`generic_protocol`) and whether it is the
    generic one."""
    if spec.drills:
        return spec.drills, False
    return generic_protocol(spec.diameter_mm), True


def protocol_note(label: str, spec: ImplantSpec) -> str:
    """The ``implant_protocol`` note of a trajectory (``label``) that drills its implant's
    protocol because it names no drill."""
    drills, generic = protocol_drills(spec)
    sizes = " -> ".join(f"{d.diameter_mm:g}" for d in drills)
    whose = "the generic protocol for its size" if generic else "its protocol"
    return (
        f"{label} gives no drill; drilling {whose} for implant {spec.name!r} "
        f"({spec.size_text}): {sizes} mm (tips {_tips(drills)} mm)"
    )


def _tips(drills: tuple[DrillSpec, ...]) -> str:
    return "/".join(f"{d.tip_length_mm:g}" for d in drills)


def with_implant_protocol(plan: Plan) -> Plan:
    """``plan`` drilled with its implant's protocol (:func:`protocol_drills`); unchanged
    without an implant."""
    if plan.implant is None:
        return plan
    return plan.with_drills(protocol_drills(plan.implant)[0])


def final_drill_warnings(plan: Plan) -> list[LoadWarning]:
    """``final_drill_mismatch`` when ``plan``'s final drill is wider than its implant, or
    narrower than both its apex diameter and its diameter less :data:`MAX_UNDERSIZE_MM`.

    Call it on the whole plan (its :attr:`~ctdrill.imaging.plan.types.Plan.drills`), not on
    one drill's plan (``for_drill(k)``, ``drilled(k)``); a drilled view (``overdrill_mm >
    0``) reports nothing."""
    spec = plan.implant
    if spec is None or plan.overdrill_mm > 0.0:
        return []
    final = plan.drills[-1].diameter_mm
    floor = min(spec.apex_diameter_mm, spec.diameter_mm - MAX_UNDERSIZE_MM)
    head = f"plan {plan.name!r}: the final drill ({final:g} mm) "
    if final > spec.diameter_mm:
        what = (
            f"is wider than implant {spec.name!r} ({spec.diameter_mm:g} mm): its threads would "
            "not engage the bone (no primary stability); end the sequence with a narrower drill"
        )
    elif final < floor - 1e-9:
        what = (
            f"is narrower than implant {spec.name!r} allows (apex {spec.apex_diameter_mm:g} mm, "
            f"body {spec.diameter_mm:g} mm: at least {floor:g} mm): the implant could not be "
            "seated; add the drills of its protocol"
        )
    else:
        return []
    return [LoadWarning(MISMATCH_CODE, head + what)]
