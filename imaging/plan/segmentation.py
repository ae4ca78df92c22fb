"""Segmentations and labelmaps as landmarks (filled in by the next step)."""

from __future__ import annotations

from pathlib import Path

from ctdrill.imaging.plan.read import PlanParts
from ctdrill.imaging.plan.types import PlanInputError


def segmentation_parts(path: Path) -> PlanParts:
    """The landmarks of a segmentation file given as a plan input."""
    raise PlanInputError(
        f"{path}: segmentation files cannot be given as plans yet; refer to the mask from a "
        "ctdrill-plan/1 landmark"
    )
