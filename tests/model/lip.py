"""Analytic lip samples for layered material, shared by the model tests and benchmarks."""

from __future__ import annotations

import numpy as np


def layered_lip_hu(
    boundaries_mm: np.ndarray | list[float],
    hu_layers: np.ndarray | list[float],
    depth_mm: np.ndarray,
    *,
    tip_length_mm: float,
    n_rings: int,
    n_angles: int = 1,
    outside_hu: float = -1000.0,
) -> tuple[np.ndarray, np.ndarray]:
    """Exact HU on midpoint rings for layers along the axis: (lip_hu (D, R, A), weights (R,)).

    Ring ``r`` at radius fraction ``(r + 0.5) / R`` sits at depth ``x - l_t (r + 0.5) / R``.
    """
    b = np.asarray(boundaries_mm, dtype=np.float64)
    hu_all = np.concatenate(([outside_hu], np.asarray(hu_layers, dtype=np.float64), [outside_hu]))
    frac = (np.arange(n_rings) + 0.5) / n_rings
    xi = depth_mm[:, None] - tip_length_mm * frac[None, :]
    hu = hu_all[np.searchsorted(b, xi, side="right")]
    return np.repeat(hu[:, :, None], n_angles, axis=2), np.full(n_rings, 1.0 / n_rings)
