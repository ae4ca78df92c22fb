"""The depth grid of a path: uniform tip depths from the entry (0) to the planned depth.

One formula for every row of a batch and for the single path (its one-row case).
"""

from __future__ import annotations

import math

import numpy as np

#: Default depth step of the profile, mm: trilinear sampling is converged at 0.05 mm on
#: 0.3 mm voxels (DESIGN.md section 6); steps above a third of a voxel add error.
DEFAULT_DEPTH_STEP_MM = 0.05
#: Longest trajectory accepted, mm: far beyond any dental drill, short enough to bound memory.
MAX_PLANNED_DEPTH_MM = 200.0


def depth_count(planned_depth_mm: float, step_mm: float) -> int:
    """Depths in the grid of a path ``planned_depth_mm`` long: the step is at most ``step_mm``
    and there are at least 2."""
    return max(2, math.ceil(planned_depth_mm / step_mm - 1e-9) + 1)


def depth_grids(
    planned_mm: np.ndarray, step_mm: float, rows: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Each row's grid, ``np.linspace(0, planned, n)`` with ``n = depth_count(planned, step)``.

    Parameters
    ----------
    planned_mm : (N,) planned depths, mm.
    step_mm : the largest step, mm (> 0).
    rows : the rows to grid (the others get 0 depths).

    Returns
    -------
    n_depths : (N,) int64 depths per row.
    depth_mm : (N, D) tip depths, ``D = max(n_depths)``, NaN past a row's own count.
    """
    n = planned_mm.shape[0]
    n_dep = np.zeros(n, dtype=np.int64)
    for i in np.asarray(rows, dtype=np.int64).tolist():
        n_dep[i] = depth_count(float(planned_mm[i]), step_mm)
    depth = np.full((n, int(n_dep.max()) if n else 0), np.nan)
    for m in sorted(set(n_dep[rows].tolist())):  # np.unique would import numpy.ma
        same = rows[n_dep[rows] == m]
        step = planned_mm[same] / (m - 1)  # np.linspace(0, planned, m), row by row
        depth[same, :m] = np.arange(m, dtype=np.float64)[None, :] * step[:, None] + 0.0
        depth[same, m - 1] = planned_mm[same]
    return n_dep, depth


def depth_grid_mm(planned_depth_mm: float, step_mm: float) -> np.ndarray:
    """(D,) the grid of one path (:func:`depth_grids` of one row)."""
    n_dep, depth = depth_grids(np.array([float(planned_depth_mm)]), step_mm, np.array([0]))
    return depth[0, : int(n_dep[0])]


def grid_brackets(
    depth_mm: np.ndarray, n_depths: np.ndarray, clearance_mm: np.ndarray, margins: np.ndarray
) -> np.ndarray:
    """(N, 2) the grid step where each row's margin is first broken (NaN: none, or broken at
    the entry already): the bracket the safe-depth search checks first.

    Parameters
    ----------
    depth_mm : (N, D) grids; n_depths (N,) their lengths.
    clearance_mm : (N, D, L) clearance on the grids, mm.
    margins : (L,) margin per landmark, mm.
    """
    n = depth_mm.shape[0]
    out = np.full((n, 2), np.nan)
    if clearance_mm.shape[2] == 0 or n == 0 or depth_mm.shape[1] == 0:
        return out
    with np.errstate(invalid="ignore"):
        bad = np.any(clearance_mm < margins, axis=2)
    bad &= np.arange(depth_mm.shape[1])[None, :] < n_depths[:, None]
    first = np.argmax(bad, axis=1)
    rows = np.flatnonzero(bad.any(axis=1) & (first > 0))
    out[rows, 0] = depth_mm[rows, first[rows] - 1]
    out[rows, 1] = depth_mm[rows, first[rows]]
    return out
