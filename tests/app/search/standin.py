"""A temporary stand-in for ``evaluate_batch`` (plan_path per row), until it lands on main."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ctdrill.app.pipeline import plan_path
from ctdrill.imaging.errors import ImagingInputError
from ctdrill.imaging.plan.types import Plan
from ctdrill.imaging.volume import CTVolume
from ctdrill.model.calibration import Calibration


@dataclass(frozen=True, eq=False)
class StandIn:
    depth_mm: np.ndarray
    disc_hu: np.ndarray
    max_safe_depth_mm: np.ndarray
    max_safe_depth_capped: np.ndarray
    binding_landmark: np.ndarray
    plan_clearance_mm: np.ndarray
    out_of_volume_depth_mm: np.ndarray
    stop_reason: np.ndarray
    refusal: tuple[str | None, ...]


def evaluate_each(
    volume: CTVolume,
    plan: Plan,
    entries_lps: np.ndarray,
    targets_lps: np.ndarray,
    calibration: Calibration,
    **kw: Any,
) -> StandIn:
    n = len(entries_lps)
    rows: list[Any] = []
    refusal: list[str | None] = []
    for e, t in zip(entries_lps, targets_lps, strict=True):
        try:
            rows.append(
                plan_path(volume, replace(plan, entry_lps=e, target_lps=t), calibration, **kw)
            )
            refusal.append(None)
        except ImagingInputError as exc:
            rows.append(None)
            refusal.append(str(exc))
    d = max((len(r.depth_mm) for r in rows if r is not None), default=1)
    depth = np.full((n, d), np.nan)
    disc = np.full((n, d), np.nan)
    msd, clear, oov = np.full(n, np.nan), np.full(n, np.nan), np.full(n, np.nan)
    capped = np.zeros(n, dtype=bool)
    binding = np.full(n, -1)
    stop = np.full(n, "", dtype=object)
    for i, r in enumerate(rows):
        if r is None:
            continue
        k = len(r.depth_mm)
        depth[i, :k] = r.depth_mm
        disc[i, :k] = r.lip.hu.mean(axis=2, dtype=np.float64) @ (
            (2 * np.arange(r.lip.hu.shape[1]) + 1) / r.lip.hu.shape[1] ** 2
        )
        msd[i] = r.max_safe_depth_mm
        capped[i] = r.max_safe_depth_capped
        binding[i] = -1 if r.binding_landmark is None else r.binding_landmark
        clear[i] = np.nan if r.plan_clearance_mm is None else r.plan_clearance_mm
        oov[i] = np.nan if r.out_of_volume_depth_mm is None else r.out_of_volume_depth_mm
        stop[i] = r.stop_reason
    return StandIn(depth, disc, msd, capped, binding, clear, oov, stop, tuple(refusal))
