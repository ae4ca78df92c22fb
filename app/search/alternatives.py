"""What would be feasible when no axis is: shorter or narrower implants at the same site.

When ``ctdrill suggest`` finds no feasible axis, :func:`alternatives` tries every implant of
the library that is shorter or narrower than the planned one (neither longer nor wider) on the
planned axis with its platform kept where it was (a shorter implant's apex moves up), drilled
with its own protocol (:func:`~ctdrill.imaging.plan.protocol.protocol_drills`), and checks each
with the one feasibility rule (:func:`~ctdrill.app.search.feasibility.check_candidate`).
``alternatives.csv`` lists them, feasible first, then the longest and widest, with their
clearances, walls and the rules each keeps (docs/suggest.md).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

from ctdrill.app.csv_cells import csv_text, text_cell
from ctdrill.app.search.feasibility import Feasibility, check_candidate
from ctdrill.imaging.plan.implants import ImplantSpec, implant_placement
from ctdrill.imaging.plan.protocol import protocol_drills
from ctdrill.imaging.plan.types import Plan
from ctdrill.imaging.volume import CTVolume

#: ``alternatives.csv``'s columns.
ALTERNATIVE_COLUMNS = (
    "implant",
    "diameter_mm",
    "length_mm",
    "change",
    "feasible",
    "implant_clearance_mm",
    "drill_clearance_mm",
    "min_wall_mm",
    "buccal_mm",
    "lingual_mm",
    "keeps",
    "problems",
)
#: Most alternatives checked (each is one exact check).
MAX_ALTERNATIVES = 24


@dataclass(frozen=True)
class Alternative:
    """One implant tried at the planned site: its plan and its verdict."""

    spec: ImplantSpec
    change: str
    plan: Plan
    verdict: Feasibility


def alternative_plan(plan: Plan, spec: ImplantSpec) -> Plan:
    """``plan`` with ``spec`` on the same axis, its platform where the planned implant's was,
    drilled with its protocol (the final drill's blades and speed kept)."""
    place = implant_placement(plan)
    if place is None:
        raise ValueError(f"plan {plan.name!r} places no implant")
    target = place.platform_lps + spec.length_mm * place.axis_lps
    base = plan.drill
    drills = tuple(replace(d, blades=base.blades, rpm=base.rpm) for d in protocol_drills(spec)[0])
    whole = replace(plan, target_lps=target, overdrill_mm=0.0, implant=None)
    return replace(whole, implant=spec, drill=drills[-1], earlier_drills=drills[:-1])


def _change(planned: ImplantSpec, spec: ImplantSpec) -> str | None:
    shorter = spec.length_mm < planned.length_mm - 1e-9
    narrower = spec.diameter_mm < planned.diameter_mm - 1e-9
    if spec.length_mm > planned.length_mm + 1e-9 or spec.diameter_mm > planned.diameter_mm + 1e-9:
        return None
    if shorter and narrower:
        return "shorter and narrower"
    return "shorter" if shorter else "narrower" if narrower else None


def alternatives(
    volume: CTVolume, plan: Plan, library: Sequence[ImplantSpec]
) -> tuple[Alternative, ...]:
    """The library's shorter or narrower implants at ``plan``'s site, checked (module
    docstring); empty without an implant. Feasible first, then longest, then widest."""
    planned = plan.implant
    if planned is None:
        return ()
    tried = [(s, c) for s in library if (c := _change(planned, s)) is not None]
    tried.sort(key=lambda sc: (-sc[0].length_mm, -sc[0].diameter_mm, sc[0].name))
    out = []
    for spec, change in tried[:MAX_ALTERNATIVES]:
        alt = alternative_plan(plan, spec)
        out.append(Alternative(spec, change, alt, check_candidate(volume, alt)))
    out.sort(key=lambda a: (not a.verdict.feasible, -a.spec.length_mm, -a.spec.diameter_mm))
    return tuple(out)


def _num(value: float | None) -> str:
    return "" if value is None or not math.isfinite(value) else f"{value:.3f}"


def keeps_text(a: Alternative) -> str:
    """The rules ``a`` keeps, in words with their numbers ("" when it keeps none checked)."""
    plan, v = a.plan, a.verdict
    codes = set(v.codes)
    kept = []
    margin = plan.margin_mm
    if plan.landmarks:
        if "plan_violates_margin" not in codes and v.drill_clearance_mm is not None:
            kept.append(
                f"every drill keeps the {margin:g} mm margin ({v.drill_clearance_mm:.2f} mm)"
            )
        if "implant_violates_margin" not in codes and v.implant_clearance_mm is not None:
            kept.append(
                f"the implant keeps the {margin:g} mm margin ({v.implant_clearance_mm:.2f} mm)"
            )
    if v.min_wall_mm is not None and "thin_wall" not in codes:
        kept.append(f"bone walls >= {plan.min_wall_mm:g} mm ({v.min_wall_mm:.2f} mm)")
    if v.walls is not None and "cortical_perforation" not in codes:
        kept.append("no perforation")
    return "; ".join(kept)


def alternatives_csv(alts: Sequence[Alternative]) -> str:
    """``alternatives.csv``: one row per implant tried (module docstring)."""
    rows = []
    for a in alts:
        v = a.verdict
        walls = v.walls
        rows.append(
            [
                text_cell(a.spec.name),
                f"{a.spec.diameter_mm:g}",
                f"{a.spec.length_mm:g}",
                a.change,
                "true" if v.feasible else "false",
                _num(v.implant_clearance_mm),
                _num(v.drill_clearance_mm),
                _num(v.min_wall_mm),
                _num(None if walls is None else walls.buccal_mm),
                _num(None if walls is None else walls.lingual_mm),
                text_cell(keeps_text(a)),
                text_cell(";".join(v.codes)),
            ]
        )
    return csv_text(ALTERNATIVE_COLUMNS, rows)
