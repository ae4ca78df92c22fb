"""The margin budget: how far from a nerve canal a plan must keep so that the 95th percentile
of the errors between the plan and the patient still clears it.

The clinical 2 mm margin (:data:`~ctdrill.imaging.plan.clinical.CLINICAL_MARGIN_MM`) covers
mean errors. Three independent errors stand between a planned clearance and the true one; each
is taken at its 95th percentile from published measurements (docs/margin_budget.md gives the
sources and the arithmetic) and they combine as independent errors do, in quadrature:

    budget = sqrt(placement_p95^2 + canal_p95^2 + ct_p95^2)

- **placement** (:data:`PLACEMENT_P95_MM`): how far the placed implant's apex lies from the
  planned one, by placement mode (``freehand``, ``static`` guide, ``dynamic`` navigation,
  ``robot``);
- **canal** (:data:`CANAL_P95_MM`): how far the canal as given lies from the true canal, by how
  it was found: ``traced`` by hand (a polyline or points) or ``imported`` (a segmentation mask);
- **CT** (:func:`ct_p95_mm`): the CBCT's linear measurement error, which grows with the voxel.

A plan whose clearance keeps the margin but falls under the budget gets the warning
``margin_below_budget``. Standard library only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

#: Placement modes (plan key ``placement``, ``--placement``) and the default.
PLACEMENTS = ("freehand", "static", "dynamic", "robot")
DEFAULT_PLACEMENT = "freehand"
#: z of the one-sided 95th percentile of a normal error.
Z95 = 1.645
#: 95th percentile of the apex's 3D deviation from the plan, mm, by placement mode
#: (docs/margin_budget.md: mean + 1.645 SD of the cited studies).
PLACEMENT_P95_MM = {
    "freehand": round(1.62 + Z95 * 0.87, 2),  # 3D deviation at the shoulder, 1.62 +- 0.87
    "static": round(1.28 + Z95 * 0.46, 2),  # apex, static guide, 1.28 +- 0.46 (RCT)
    "dynamic": round(1.29 + Z95 * 0.50, 2),  # apex, dynamic navigation, 1.29 +- 0.50 (RCT)
    "robot": round(0.67 * (1.0 + Z95 * 0.39), 2),  # apex 0.67 (pooled), SD/mean assumed 0.39
}
#: How a canal landmark was found: by its kind (a mask is an imported segmentation).
CANAL_SOURCES = ("traced", "imported")
#: 95th percentile of the canal's position error, mm, by how it was found.
CANAL_P95_MM = {
    "traced": 1.3,  # inter-observer 95th percentile deviation of hand tracings
    "imported": round(0.275 + Z95 * 0.475, 2),  # segmentation vs semi-automatic, 0.275 +- 0.475
}
#: 95th percentile of the CBCT's linear measurement error at voxels up to
#: :data:`CT_REFERENCE_VOXEL_MM`, mm (absolute error 0.32 +- 0.10 mm).
CT_P95_MM = round(0.32 + Z95 * 0.10, 2)
#: The coarsest voxel of the study behind :data:`CT_P95_MM`, mm.
CT_REFERENCE_VOXEL_MM = 0.25


def ct_p95_mm(voxel_mm: float) -> float:
    """The CT's measurement error at its 95th percentile for voxels of ``voxel_mm`` (the
    coarsest spacing): :data:`CT_P95_MM` up to :data:`CT_REFERENCE_VOXEL_MM`, in proportion to
    the voxel above it, mm."""
    return CT_P95_MM * max(1.0, float(voxel_mm) / CT_REFERENCE_VOXEL_MM)


def canal_source(kind: str) -> str:
    """How a landmark of ``kind`` was found: ``imported`` for a mask (a segmentation file),
    else ``traced``."""
    return "imported" if kind == "mask" else "traced"


def placement_error(value: object) -> str | None:
    """Why ``value`` is not a placement mode, or None."""
    if value in PLACEMENTS:
        return None
    return f"must be one of {', '.join(PLACEMENTS)}, got {value!r}"


@dataclass(frozen=True)
class MarginBudget:
    """One landmark's margin budget and its three terms, mm."""

    placement: str
    canal_source: str
    voxel_mm: float
    placement_mm: float
    canal_mm: float
    ct_mm: float

    @property
    def budget_mm(self) -> float:
        """The three terms in quadrature, mm."""
        return math.sqrt(self.placement_mm**2 + self.canal_mm**2 + self.ct_mm**2)

    def to_json(self) -> dict[str, Any]:
        """The budget as summaries write it (``margin_budget``)."""
        return {
            "budget_mm": round(self.budget_mm, 3),
            "placement": self.placement,
            "canal_source": self.canal_source,
            "voxel_mm": round(self.voxel_mm, 4),
            "placement_mm": self.placement_mm,
            "canal_mm": self.canal_mm,
            "ct_mm": round(self.ct_mm, 3),
        }


def margin_budget(placement: str, canal: str, voxel_mm: float) -> MarginBudget:
    """The budget for a canal found as ``canal`` (``traced`` | ``imported``) on a CT of
    coarsest spacing ``voxel_mm``, placed by ``placement`` (module docstring)."""
    problem = placement_error(placement)
    if problem is not None:
        raise ValueError(f"placement {problem}")
    if canal not in CANAL_SOURCES:
        raise ValueError(f"canal source must be one of {', '.join(CANAL_SOURCES)}")
    return MarginBudget(
        placement=placement,
        canal_source=canal,
        voxel_mm=float(voxel_mm),
        placement_mm=PLACEMENT_P95_MM[placement],
        canal_mm=CANAL_P95_MM[canal],
        ct_mm=ct_p95_mm(voxel_mm),
    )
