"""The objective of ``ctdrill suggest``: bone around the implant body (docs/suggest.md).

Every term is read from the **shell HU** (:mod:`ctdrill.app.search.shell`): trilinear CT
numbers on shells 0.25 and 0.75 mm outside the body's surface (the implant at its placement,
or the final drill's osteotomy without an implant), every 0.5 mm from its top (the platform)
to its apex, in 16 directions around the axis. Outside the CT counts as air. The bone read is
the bone the implant's surface engages, never the bone on its axis: an axis running inside a
cortical plate thinner than the implant has soft tissue on its shell and scores low (and is
not feasible: it perforates the plate).

- ``body_hu``: mean shell HU over the whole body; ``body_term = (body_hu - BONE_HU) /
  (CORTICAL_HU - BONE_HU)``: 0 at the bone threshold (150 HU), 1 at the cortical one
  (1250 HU), linear, not clipped.
- ``crest_cortical``: fraction of the shell samples within ``crest_zone_mm`` below the top
  (the platform) whose HU is cortical (:func:`ctdrill.imaging.misch.is_cortical`, Misch D1,
  ``> 1250 HU``): cortical bone around the neck, where primary stability is made;
- ``apex_cortical``: the same within ``apex_zone_mm`` above the apex;
- ``score = w_body body_term + w_crest crest_cortical + w_apex apex_cortical``.
- **Even walls** (:func:`wall_balance`), read from the exact bone walls of the checked
  candidates: the thinnest wall over the wall opposite it at the same depth (1 for an implant
  centred in the ridge, near 0 for one hugging a plate); the ranking of the checked candidates
  adds ``w_balance * balance`` (:func:`ranked_total`).

By default (:data:`~ctdrill.app.search.defaults.DEFAULT_WEIGHTS`) the crest and apex
cortical-contact terms weigh 0: the score prefers bone all around the implant and even walls,
not an axis pressed against the cortical plate.

The thresholds have one owner, :mod:`ctdrill.imaging.misch`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ctdrill.app.errors import AppInputError
from ctdrill.app.search.defaults import DEFAULT_BALANCE_WEIGHT, DEFAULT_WEIGHTS
from ctdrill.imaging.misch import BONE_HU, CORTICAL_HU, is_cortical
from ctdrill.imaging.sampling.walls import BoneWalls

#: Crest and apex zones along the body, mm: about the thickness of a mandible's cortex.
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
    balance_weight: float = DEFAULT_BALANCE_WEIGHT

    def __post_init__(self) -> None:
        for name in ("body_weight", "crest_weight", "apex_weight", "balance_weight"):
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
                "balance": self.balance_weight,
            },
            "crest_zone_mm": self.crest_zone_mm,
            "apex_zone_mm": self.apex_zone_mm,
            "bone_hu": BONE_HU,
            "cortical_hu": CORTICAL_HU,
            "score": "body_weight * (body_hu - bone_hu) / (cortical_hu - bone_hu) "
            "+ crest_weight * crest_cortical + apex_weight * apex_cortical",
            "ranked": "score + balance_weight * wall_balance (checked candidates; wall_balance: "
            "the thinnest bone wall over the wall opposite it at the same depth)",
        }


@dataclass(frozen=True, eq=False)
class Scores:
    """(N,) score terms per candidate; NaN for rows that were not evaluated."""

    body_hu: np.ndarray
    body_term: np.ndarray
    crest_cortical: np.ndarray
    apex_cortical: np.ndarray
    total: np.ndarray


def score_rows(shell_hu: np.ndarray, s_mm: np.ndarray, objective: Objective) -> Scores:
    """The score terms of candidates sharing one body.

    Parameters
    ----------
    shell_hu : (N, D, S) shell HU per candidate, depth and shell sample; NaN rows were not
        sampled.
    s_mm : (D,) the depths below the body's top (platform), mm.
    objective : weights and zones.
    """
    hu = np.asarray(shell_hu, dtype=np.float64)
    s = np.asarray(s_mm, dtype=np.float64)
    n = hu.shape[0]
    ok = np.all(np.isfinite(hu), axis=(1, 2))
    nan = np.full(n, np.nan)
    body, crest, apex = nan.copy(), nan.copy(), nan.copy()
    if ok.any():
        h = hu[ok]
        cortical = is_cortical(h)
        tol = 1e-9
        length = float(s[-1])
        in_crest = s <= min(objective.crest_zone_mm, length) + tol
        in_apex = s >= max(0.0, length - objective.apex_zone_mm) - tol
        body[ok] = h.mean(axis=(1, 2))
        crest[ok] = cortical[:, in_crest].mean(axis=(1, 2))
        apex[ok] = cortical[:, in_apex].mean(axis=(1, 2))
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


def wall_balance(walls: BoneWalls | None) -> float:
    """How even the walls are: the thinnest known wall over the wall opposite it (the
    direction 180 deg around the axis) at the same depth, in [0, 1]; NaN without walls."""
    if walls is None:
        return math.nan
    w = np.asarray(walls.wall_mm, dtype=np.float64)
    if w.size == 0 or not np.isfinite(w).any() or w.shape[1] % 2:
        return math.nan
    opp = np.roll(w, w.shape[1] // 2, axis=1)
    flat = np.where(np.isfinite(w), w, np.inf)
    d, a = np.unravel_index(int(np.argmin(flat)), flat.shape)
    thin, other = float(w[d, a]), float(opp[d, a])
    if not math.isfinite(other) or other <= 0.0:
        return 0.0 if math.isfinite(other) else math.nan
    return min(1.0, thin / other)


def ranked_total(total: np.ndarray, balance: np.ndarray, objective: Objective) -> np.ndarray:
    """(N,) the ranking score: ``total`` plus ``balance_weight * balance`` where the balance is
    known (checked candidates with an implant)."""
    b = np.where(np.isfinite(balance), balance, 0.0)
    out: np.ndarray = total + objective.balance_weight * b
    return out
