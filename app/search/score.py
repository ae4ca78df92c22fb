"""The bone-engagement objective of ``ctdrill suggest`` (docs/suggest.md has the reasoning).

Every term is read from the **disc HU** of the batch evaluation: at tip depth ``x`` the
area-weighted mean HU over the drill's cutting lip (the disc of radius ``R``, the cone of
length ``l_t`` behind the tip). As ``x`` runs from 0 to the planned depth ``D`` the lip sweeps
the bone the drill removes exactly once, so the mean of the disc HU over ``[0, D]`` is the mean
HU of the implant bed. On the uniform depth grid (step <= 0.05 mm) the means are sample means.

- ``body_hu``: mean disc HU over ``[0, D]``; ``body_term = (body_hu - BONE_HU) /
  (CORTICAL_HU - BONE_HU)``: 0 at the bone threshold (150 HU), 1 at the cortical one
  (1250 HU), linear, not clipped.
- ``crest_cortical``: fraction of the crest zone ``[0, min(crest_zone_mm, D)]`` whose disc
  HU is cortical (:func:`ctdrill.imaging.misch.is_cortical`, Misch D1, ``> 1250 HU``);
- ``apex_cortical``: the same over the apex zone ``[max(0, D - apex_zone_mm), D]``;
- ``score = w_body body_term + w_crest crest_cortical + w_apex apex_cortical``.

The thresholds have one owner, :mod:`ctdrill.imaging.misch`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ctdrill.app.errors import AppInputError
from ctdrill.app.search.defaults import DEFAULT_WEIGHTS
from ctdrill.imaging.misch import BONE_HU, CORTICAL_HU, is_cortical

#: Crest and apex zones, mm: about the thickness of the crestal cortex of a mandible.
CREST_ZONE_MM = 2.0
APEX_ZONE_MM = 2.0


@dataclass(frozen=True)
class Objective:
    """Weights and zones of the score (module docstring)."""

    body_weight: float = DEFAULT_WEIGHTS[0]
    crest_weight: float = DEFAULT_WEIGHTS[1]
    apex_weight: float = DEFAULT_WEIGHTS[2]
    crest_zone_mm: float = CREST_ZONE_MM
    apex_zone_mm: float = APEX_ZONE_MM

    def __post_init__(self) -> None:
        for name in ("body_weight", "crest_weight", "apex_weight"):
            value = getattr(self, name)
            if not (math.isfinite(value) and 0.0 <= value <= 1e6):
                raise AppInputError(
                    f"--weights: {name.removesuffix('_weight')} weight must be a number from "
                    f"0 to 1e6, got {value!r}"
                )
        for name in ("crest_zone_mm", "apex_zone_mm"):
            value = getattr(self, name)
            if not (math.isfinite(value) and 0.0 < value <= 100.0):
                raise AppInputError(f"{name} must be in (0, 100] mm, got {value!r}")

    def to_json(self) -> dict[str, object]:
        """The objective as ``suggest.json`` records it."""
        return {
            "weights": {
                "body": self.body_weight,
                "crest": self.crest_weight,
                "apex": self.apex_weight,
            },
            "crest_zone_mm": self.crest_zone_mm,
            "apex_zone_mm": self.apex_zone_mm,
            "bone_hu": BONE_HU,
            "cortical_hu": CORTICAL_HU,
            "score": "body_weight * (body_hu - bone_hu) / (cortical_hu - bone_hu) "
            "+ crest_weight * crest_cortical + apex_weight * apex_cortical",
        }


@dataclass(frozen=True, eq=False)
class Scores:
    """(N,) score terms per candidate; NaN for rows that were not evaluated."""

    body_hu: np.ndarray
    body_term: np.ndarray
    crest_cortical: np.ndarray
    apex_cortical: np.ndarray
    total: np.ndarray


def score_rows(
    depth_mm: np.ndarray, disc_hu: np.ndarray, planned_depth_mm: float, objective: Objective
) -> Scores:
    """The score terms of rows sharing one planned depth.

    Parameters
    ----------
    depth_mm : (N, D) tip depths (the same uniform grid on every evaluated row), mm; NaN rows
        were not evaluated.
    disc_hu : (N, D) disc HU at those depths.
    planned_depth_mm : ``D``, mm.
    objective : weights and zones.
    """
    depth = np.asarray(depth_mm, dtype=np.float64)
    hu = np.asarray(disc_hu, dtype=np.float64)
    n = depth.shape[0]
    ok = np.all(np.isfinite(depth), axis=1) & np.all(np.isfinite(hu), axis=1)
    nan = np.full(n, np.nan)
    body, crest, apex = nan.copy(), nan.copy(), nan.copy()
    if ok.any():
        d, h = depth[ok], hu[ok]
        cortical = is_cortical(h)
        tol = 1e-9
        in_crest = d <= min(objective.crest_zone_mm, planned_depth_mm) + tol
        in_apex = d >= max(0.0, planned_depth_mm - objective.apex_zone_mm) - tol
        body[ok] = h.mean(axis=1)
        crest[ok] = (cortical & in_crest).sum(axis=1) / in_crest.sum(axis=1)
        apex[ok] = (cortical & in_apex).sum(axis=1) / in_apex.sum(axis=1)
    return combine(body, crest, apex, objective)


def combine(
    body_hu: np.ndarray, crest_cortical: np.ndarray, apex_cortical: np.ndarray, objective: Objective
) -> Scores:
    """The score of the three measured terms (module docstring)."""
    body, crest, apex = body_hu, crest_cortical, apex_cortical
    body_term = (body - BONE_HU) / (CORTICAL_HU - BONE_HU)
    total = (
        objective.body_weight * body_term
        + objective.crest_weight * crest
        + objective.apex_weight * apex
    )
    return Scores(
        body_hu=body, body_term=body_term, crest_cortical=crest, apex_cortical=apex, total=total
    )
