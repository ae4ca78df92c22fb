"""The margin budget of a computed path: each landmark's budget
(:mod:`ctdrill.imaging.plan.budget`) on this CT, and ``margin_below_budget`` where a clearance
keeps the margin but not the budget.

A landmark's clearance here is the least of the drill's at its planned depth and the implant
body's (when the plan places one): the osteotomy and the implant both must keep the budget.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ctdrill.imaging.plan.budget import MarginBudget, canal_source, margin_budget
from ctdrill.imaging.plan.types import Plan
from ctdrill.imaging.volume import CTVolume
from ctdrill.warning_codes import LoadWarning

__all__ = ["budget_warnings", "plan_budgets", "summary_budget"]


def plan_budgets(volume: CTVolume, plan: Plan) -> tuple[MarginBudget, ...]:
    """Each landmark's margin budget for ``plan`` (its ``placement``) on ``volume`` (its
    coarsest voxel spacing), in the plan's landmark order."""
    voxel = float(max(volume.spacing_mm))
    return tuple(
        margin_budget(plan.placement, canal_source(lm.kind), voxel) for lm in plan.landmarks
    )


def summary_budget(budgets: Sequence[MarginBudget]) -> MarginBudget | None:
    """The budget a summary states: the largest of the landmarks' (None without one)."""
    return max(budgets, key=lambda b: b.budget_mm) if budgets else None


def budget_warnings(
    plan: Plan,
    budgets: Sequence[MarginBudget],
    margins_mm: np.ndarray,
    drill_clearance_mm: np.ndarray,
    implant_clearance_mm: np.ndarray | None,
) -> list[LoadWarning]:
    """``margin_below_budget`` naming each landmark whose clearance (the least of the drill's
    at its planned depth and the implant body's) keeps its margin but is under its budget."""
    low = []
    for j, lm in enumerate(plan.landmarks):
        c = float(drill_clearance_mm[j])
        if implant_clearance_mm is not None:
            c = min(c, float(implant_clearance_mm[j]))
        b = budgets[j]
        if float(margins_mm[j]) <= c < b.budget_mm:
            low.append(
                f"{lm.name!r} {c:.2f} mm (margin {float(margins_mm[j]):g} mm, budget "
                f"{b.budget_mm:.1f} mm: placement {b.placement} {b.placement_mm:g} mm, canal "
                f"{b.canal_source} {b.canal_mm:g} mm, CT {b.ct_mm:.2f} mm at 95 %)"
            )
    if not low:
        return []
    return [
        LoadWarning(
            "margin_below_budget",
            f"plan {plan.name!r}: the clearance keeps the margin but not the margin budget "
            "(the 95th percentile of placement, canal and CT errors combined): "
            + ", ".join(low)
            + "; plan further away or use a more accurate placement",
        )
    ]
