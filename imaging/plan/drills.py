"""Reading a trajectory's drills: ``drill`` (one) or ``drills`` (a sequence in drilling order).

Used by the ``ctdrill-plan/1`` reader (:mod:`ctdrill.imaging.plan.read`) and the Slicer Line
reader (:mod:`ctdrill.imaging.plan.slicer`); the rules are in :func:`drills_field`.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

from ctdrill.imaging.plan.drill_spec import (
    _DRILL_KEYS,
    _MAX_BLADES,
    MAX_DRILLS,
    POINT_ANGLE_RANGE_DEG,
    DrillSpec,
    protocol_conflicts,
    sequence_error,
)
from ctdrill.imaging.plan.implants import ImplantSpec
from ctdrill.imaging.plan.protocol import PROTOCOL_NOTE_CODE, protocol_drills, protocol_note
from ctdrill.imaging.plan.read import _Ctx, _is_number
from ctdrill.imaging.plan.types import PlanInputError
from ctdrill.warning_codes import LoadWarning

#: The warning code of a trajectory drill given the tip of its implant's protocol.
RECONCILED_CODE = "drills_reconciled"


def drills_field(
    ctx: _Ctx, doc: dict[str, Any], where: str, implant: ImplantSpec | None = None
) -> tuple[DrillSpec, ...]:
    """The plan's drills from ``drill`` (one object) or ``drills`` (a list in drilling order).

    Giving both is refused, naming ``drills``. Every item of ``drills`` must give its
    ``diameter_mm`` (a sequence is defined by its diameters); its other keys default as
    ``drill``'s do. The list must be non-empty, at most :data:`MAX_DRILLS` long, with strictly
    increasing diameters. Neither given: the ``implant``'s drilling protocol
    (:func:`~ctdrill.imaging.plan.protocol.protocol_drills`) with an ``implant_protocol``
    note, or without an implant the default drill with a ``plan_default`` note.
    """
    fp = f"{where}.drills" if where else "drills"
    if "drills" not in doc and "drill" not in doc and implant is not None:
        label = f"{ctx.path.name}: {where or 'the trajectory'}"
        ctx.warnings.append(LoadWarning(PROTOCOL_NOTE_CODE, protocol_note(label, implant)))
        return protocol_drills(implant)[0]
    if "drills" not in doc:
        if "drill" not in doc:
            ctx.notes.append(no_drill_note(ctx, where))
        drill_raw = doc.get("drill", {})
        fd = f"{where}.drill" if where else "drill"
        if not isinstance(drill_raw, dict):
            raise ctx.fail(fd, "must be an object", drill_raw)
        ctx.keys(drill_raw, _DRILL_KEYS, fd)
        return reconciled(ctx, (drill_from(ctx, drill_raw, fd),), implant, where)
    if "drill" in doc:
        raise ctx.fail(
            fp,
            "and drill are both given; give drill for a single drill or drills for a sequence "
            "(its last entry is the final drill), not both",
        )
    raw = doc["drills"]
    if not isinstance(raw, list):
        raise ctx.fail(fp, "must be a list of drill objects in drilling order", raw)
    if len(raw) > MAX_DRILLS:
        raise ctx.fail(fp, f"lists {len(raw)} drills, more than the {MAX_DRILLS} accepted")
    out = []
    for i, item in enumerate(raw):
        fi = f"{fp}[{i}]"
        if not isinstance(item, dict):
            raise ctx.fail(fi, "must be a drill object", item)
        ctx.keys(item, _DRILL_KEYS, fi)
        if "diameter_mm" not in item:
            raise ctx.fail(f"{fi}.diameter_mm", "is missing; every drill of a sequence needs it")
        out.append(drill_from(ctx, item, fi))
    problem = sequence_error(out)
    if problem is not None:
        raise PlanInputError(f"{ctx.path.name}: {fp}{problem}")
    return reconciled(ctx, tuple(out), implant, where)


def reconciled(
    ctx: _Ctx, drills: tuple[DrillSpec, ...], implant: ImplantSpec | None, where: str
) -> tuple[DrillSpec, ...]:
    """``drills`` with each drill that contradicts the ``implant``'s protocol (the same
    diameter with another tip or point angle,
    :func:`~ctdrill.imaging.plan.drill_spec.protocol_conflicts`) given the protocol's tip and
    point angle, one ``drills_reconciled`` warning naming each: a plan read is never one that
    contradicts itself."""
    if implant is None or not implant.drills:
        return drills
    out = list(drills)
    label = f"{ctx.path.name}: {where or 'the trajectory'}"
    for i, d, p in protocol_conflicts(drills, implant.drills):
        out[i] = replace(d, tip_length_mm=p.tip_length_mm, point_angle_deg=p.point_angle_deg)
        ctx.warnings.append(
            LoadWarning(
                RECONCILED_CODE,
                f"{label}: drills[{i}] (the {d.name}) gave a {d.tip_length_mm:g} mm tip, but "
                f"implant {implant.name!r}'s protocol drills it with {p.tip_length_mm:g} mm: "
                "using the protocol's tip (edit the implant's drills to change it)",
            )
        )
    return tuple(out)


def no_drill_note(ctx: _Ctx, where: str) -> str:
    """The ``plan_default`` note of a trajectory that names no drill (the default drill)."""
    d = DrillSpec()
    at = f" {where}" if where else ""
    return (
        f"{ctx.path.name}:{at} gives no drill; using the default {d.diameter_mm:g} mm drill "
        f"({d.tip_length_mm:g} mm tip, {d.blades} blades, {d.rpm:g} rpm)"
    )


def drill_from(ctx: _Ctx, raw: dict[str, Any], where: str) -> DrillSpec:
    d = DrillSpec()
    diameter = ctx.number(raw, "diameter_mm", where, default=d.diameter_mm, positive=True)
    # no tip given: NaN, and DrillSpec gives the tip rule's for the diameter and point angle
    tip = ctx.number(raw, "tip_length_mm", where, default=math.nan, positive=True)
    angle = ctx.number(raw, "point_angle_deg", where, default=d.point_angle_deg, positive=True)
    lo, hi = POINT_ANGLE_RANGE_DEG
    if not lo < angle < hi:
        raise ctx.fail(f"{where}.point_angle_deg", f"must be between {lo:g} and {hi:g} deg", angle)
    blades_raw = raw.get("blades", d.blades)
    if not _is_number(blades_raw) or blades_raw != int(blades_raw) or blades_raw < 1:
        raise ctx.fail(f"{where}.blades", "must be a positive whole number", blades_raw)
    if blades_raw > _MAX_BLADES:
        raise ctx.fail(f"{where}.blades", f"must be at most {_MAX_BLADES}", blades_raw)
    rpm = ctx.number(raw, "rpm", where, default=d.rpm, positive=True)
    return DrillSpec(
        diameter_mm=diameter,
        tip_length_mm=tip,
        blades=int(blades_raw),
        rpm=rpm,
        point_angle_deg=angle,
    )
