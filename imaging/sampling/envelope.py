"""The jaw's outer envelope along rays: the rule the bone walls are measured with.

The rule (a morphological closing along each ray; :mod:`ctdrill.imaging.sampling.walls` and
docs/plan.md, "Bone walls"): along a ray the jaw ends at the first of a non-bone run of
:data:`ENVELOPE_GAP_MM` after bone, a sample below :data:`AIR_HU`, or the CT's edge met in such
a run; the distance to the envelope is that of the last bone/non-bone crossing before the end
(bisected to :data:`BISECT_TOL_MM`). A ray meeting no bone within :data:`ENVELOPE_REACH_MM` is
*open* (its caller decides: along the jaw it goes on, across it the origin is outside).
Bone is :func:`~ctdrill.imaging.teeth.is_bone_hu`: a tooth is not bone (a crown on the crest
is not wall) but no gap either (a root inside the jaw does not end it).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from ctdrill.imaging.sampling.envelope_march import kernel_fits, start_envelope_rays
from ctdrill.imaging.teeth import bone_along, edge_steps, is_bone_hu, is_tooth_hu
from ctdrill.imaging.volume import CTVolume

#: A non-bone run this long after bone ends the jaw along a ray (the envelope rule), mm: longer
#: than a nerve canal (2-4 mm) or a marrow space, shorter than the soft tissue outside the jaw.
ENVELOPE_GAP_MM = 3.0
#: A ray that meets no bone within this is open, mm.
ENVELOPE_REACH_MM = 8.0
#: A sample below this is air: never inside the jaw, HU.
AIR_HU = -400.0
#: The crossing of the bone edge is bisected to this, mm.
BISECT_TOL_MM = 1e-4
#: Walls are followed this far from the surface by default, mm.
MAX_ENVELOPE_MM = 10.0


def envelope_walls(
    volume: CTVolume,
    origins_lps: np.ndarray,
    dirs_lps: np.ndarray,
    *,
    step: float,
    max_wall_mm: float = MAX_ENVELOPE_MM,
    gap_mm: float = ENVELOPE_GAP_MM,
    reach_mm: float = ENVELOPE_REACH_MM,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The distance from each origin along its direction to the jaw's envelope (module
    docstring: 0 outside it, ``max_wall_mm`` where the jaw goes on), whether it is unknown
    (the ray leaves the CT first), and whether it is open (no bone within
    :data:`ENVELOPE_REACH_MM` and no air: outside the jaw across its width, inside it along
    the arch; the caller decides).

    Parameters
    ----------
    origins_lps, dirs_lps : (N, 3) ray origins (LPS mm) and unit directions.
    step : march step, mm; ``max_wall_mm``, ``gap_mm``, ``reach_mm`` as in the module.

    Returns
    -------
    wall : (N,) mm; unknown, open : (N,) bool.

    The compiled kernel (:mod:`~ctdrill.imaging.sampling.envelope_kernel`) computes it when
    it is loaded and the volume has no padding; else the NumPy path below (the reference).
    """
    return start_envelope_walls(
        volume,
        origins_lps,
        dirs_lps,
        step=step,
        max_wall_mm=max_wall_mm,
        gap_mm=gap_mm,
        reach_mm=reach_mm,
    )()


def start_envelope_walls(
    volume: CTVolume,
    origins_lps: np.ndarray,
    dirs_lps: np.ndarray,
    *,
    step: float,
    max_wall_mm: float = MAX_ENVELOPE_MM,
    gap_mm: float = ENVELOPE_GAP_MM,
    reach_mm: float = ENVELOPE_REACH_MM,
) -> Callable[[], tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """:func:`envelope_walls` started: the compiled kernel's rays begin on the worker threads
    and this returns at once a function giving ``(wall, unknown, open)`` when called (the
    NumPy path computes them here)."""
    n_steps = math.ceil((max_wall_mm + gap_mm) / step) + 1
    gap_steps = math.ceil(gap_mm / step - 1e-9)
    tooth_edge = edge_steps(volume, step)
    if kernel_fits(volume):
        return start_envelope_rays(
            volume,
            origins_lps,
            dirs_lps,
            step=step,
            n_steps=n_steps,
            gap_steps=gap_steps,
            tooth_edge=tooth_edge,
            max_wall_mm=max_wall_mm,
            reach_mm=reach_mm,
            air_hu=AIR_HU,
            bisect_tol_mm=BISECT_TOL_MM,
        )
    done = _envelope_numpy(
        volume, origins_lps, dirs_lps, step, n_steps, gap_steps, tooth_edge, max_wall_mm, reach_mm
    )
    return lambda: done


def _envelope_numpy(
    volume: CTVolume,
    origins_lps: np.ndarray,
    dirs_lps: np.ndarray,
    step: float,
    n_steps: int,
    gap_steps: int,
    tooth_edge: int,
    max_wall_mm: float,
    reach_mm: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`envelope_walls` by NumPy (the reference)."""
    n = len(origins_lps)
    wall = np.zeros(n)
    unknown = np.zeros(n, dtype=bool)
    cross = np.zeros(n, dtype=bool)
    open_ = np.zeros(n, dtype=bool)
    t = np.arange(n_steps) * step
    chunk = max(1, 200_000 // n_steps)
    for lo_i in range(0, n, chunk):
        sl = slice(lo_i, min(n, lo_i + chunk))
        o, v = origins_lps[sl], dirs_lps[sl]
        hu = volume.sample(o[:, None, :] + t[None, :, None] * v[:, None, :], outside_hu=np.nan)
        wall[sl], unknown[sl], cross[sl], open_[sl] = _envelope_rows(
            hu, t, gap_steps, max_wall_mm, reach_mm, tooth_edge
        )
    # bisect each exit crossing between its last bone sample and the next
    exits = np.flatnonzero(~unknown & cross)
    if exits.size:
        k = np.rint(wall[exits] / step).astype(np.int64)
        a, b = t[k], t[np.minimum(k + 1, n_steps - 1)]
        oo, vv = origins_lps[exits], dirs_lps[exits]
        # each ray halves its own bracket until it is within the tolerance (the compiled
        # kernel's loop, ray by ray: the same midpoints, the same bits)
        live = np.flatnonzero(b - a > BISECT_TOL_MM)
        while live.size:
            mid = 0.5 * (a[live] + b[live])
            pts = oo[live] + mid[:, None] * vv[live]
            bone = is_bone_hu(volume.sample(pts, outside_hu=np.nan))
            a[live] = np.where(bone, mid, a[live])
            b[live] = np.where(bone, b[live], mid)
            live = live[b[live] - a[live] > BISECT_TOL_MM]
        wall[exits] = np.minimum(0.5 * (a + b), max_wall_mm)
    return wall, unknown, open_


def _envelope_rows(
    hu: np.ndarray,
    t: np.ndarray,
    gap_steps: int,
    max_wall_mm: float,
    reach_mm: float,
    tooth_edge: int = 0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The envelope rule on sampled rays ``hu`` (N, K) at distances ``t`` (K,): each ray's
    wall (the last bone sample's distance, refined by the caller; 0 outside the jaw;
    ``max_wall_mm`` capped), whether it is unknown, whether it ends at a bone crossing (to
    refine), and whether it is *open*: no bone within the reach and no air."""
    n, k_all = hu.shape
    gone = np.isnan(hu)
    bone = bone_along(hu, tooth_edge)  # a tooth (and its trilinear edge) is not bone ...
    solid = bone | is_tooth_hu(hu)  # ... but no gap either: a root inside the jaw is closed over
    air = hu < AIR_HU
    idx = np.arange(k_all)
    last_bone = np.maximum.accumulate(np.where(bone, idx, -1), axis=1)  # (N, K)
    last_solid = np.maximum.accumulate(np.where(solid, idx, -1), axis=1)
    seen = last_bone >= 0
    # where the jaw ends: air, or a run of gap_steps of neither bone nor tooth after bone
    end = air | (seen & ~solid & (idx - last_solid >= gap_steps))
    end |= ~seen & (t[None, :] > reach_mm)
    # the CT's edge met in a gap after bone ends the jaw (outside the CT is never bone)
    in_gap = np.zeros_like(bone)
    in_gap[:, 1:] = seen[:, :-1] & ~solid[:, :-1] & ~gone[:, :-1]
    edge_end = gone & in_gap
    end |= edge_end
    has_end = end.any(axis=1)
    k_end = np.where(has_end, np.argmax(end, axis=1), k_all - 1)
    # unknown when the CT ends before the end is decided (or at it, but inside bone)
    first_gone = np.where(gone.any(axis=1), np.argmax(gone, axis=1), k_all)
    rows = np.arange(n)
    unknown = (first_gone < k_end) | ((first_gone == k_end) & ~edge_end[rows, k_end])
    lb = last_bone[np.arange(n), k_end]
    wall = np.where(lb >= 0, t[np.maximum(lb, 0)], 0.0)
    # the jaw goes on past max_wall_mm (bone there, or no end within the samples)
    capped = (lb >= 0) & ((t[np.maximum(lb, 0)] >= max_wall_mm) | ~has_end)
    # bone met at or past max_wall_mm before the CT and the jaw end: "at least", known
    k_cap = int(np.searchsorted(t, max_wall_mm - 1e-12))
    far = bone[:, k_cap:]
    k_far = k_cap + np.argmax(far, axis=1)
    far_first = far.any(axis=1) & (k_far < first_gone) & (~has_end | (k_end > k_far))
    capped |= far_first
    unknown &= ~far_first
    wall = np.where(capped, max_wall_mm, wall)
    # open: no bone met before the reach or before the CT ends (the surface itself inside it)
    k_stop = np.minimum(k_end, first_gone - 1)
    open_ = (lb < 0) & (first_gone > 0) & ~air[np.arange(n), np.maximum(k_stop, 0)]
    open_ &= ~air.any(axis=1) | (np.argmax(air, axis=1) > k_stop)
    return wall, unknown, (lb >= 0) & ~capped, open_


def ring_walls(
    volume: CTVolume,
    origin: np.ndarray,
    dirs: np.ndarray,
    step: float,
    max_wall_mm: float,
    buccal_perp: np.ndarray | None,
) -> tuple[np.ndarray, np.ndarray]:
    """Each ray's wall (D, A) to the jaw's envelope and whether it is unknown (D, A):
    :func:`start_ring_walls` (same arguments) computed at once."""
    return start_ring_walls(volume, origin, dirs, step, max_wall_mm, buccal_perp)()


def start_ring_walls(
    volume: CTVolume,
    origin: np.ndarray,
    dirs: np.ndarray,
    step: float,
    max_wall_mm: float,
    buccal_perp: np.ndarray | None,
) -> Callable[[], tuple[np.ndarray, np.ndarray]]:
    """Each ray's wall (D, A) to the jaw's envelope and whether it is unknown (D, A): rays from
    ``origin`` (D, A, 3), the implant's surface at D depths, along ``dirs`` (A, 3).

    An open ray (no bone within the reach, no air) runs along the jaw or out of it: within
    45 deg of the jaw's long direction at its depth (perpendicular to ``buccal_perp``, the
    arch's buccal direction; without an arch, perpendicular to the mean axis of the rays
    that cross the jaw's surface, by doubled angles) the jaw goes on (capped); across it the
    surface point is outside the jaw (0).

    The rays start on the worker threads (:func:`start_envelope_walls`); the function returned
    finishes them and gives ``(wall, unknown)``."""
    shape = origin.shape[:2]
    o = origin.reshape(-1, 3)
    v = np.broadcast_to(dirs[None, :, :], origin.shape).reshape(-1, 3)
    rays = start_envelope_walls(volume, o, v, step=step, max_wall_mm=max_wall_mm)
    return lambda: _ring_rule(rays(), shape, dirs, max_wall_mm, buccal_perp)


def _ring_rule(
    rays: tuple[np.ndarray, np.ndarray, np.ndarray],
    shape: tuple[int, ...],
    dirs: np.ndarray,
    max_wall_mm: float,
    buccal_perp: np.ndarray | None,
) -> tuple[np.ndarray, np.ndarray]:
    """The open rays of :func:`start_ring_walls` judged along or across the jaw."""
    wall, unknown, open_ = (a.reshape(shape) for a in rays)
    if open_.any():
        # (D, A) rays that cross the jaw's surface (an exit short of the cap: across it)
        met = ~unknown & ~open_ & (wall > 0.0) & (wall < max_wall_mm)
        if buccal_perp is not None:
            across = np.broadcast_to(buccal_perp, (shape[0], 3))
        else:
            # the mean axis of the rays meeting bone, by doubled angles (a line, not a ray)
            e1 = dirs[0]
            e2 = dirs[len(dirs) // 4] - (dirs[len(dirs) // 4] @ e1) * e1
            e2 = e2 / np.linalg.norm(e2)
            ang = np.arctan2(dirs @ e2, dirs @ e1)
            c2 = (met * np.cos(2 * ang)).sum(axis=1)
            s2 = (met * np.sin(2 * ang)).sum(axis=1)
            half = 0.5 * np.arctan2(s2, c2)
            across = np.cos(half)[:, None] * e1 + np.sin(half)[:, None] * e2
        along = np.abs(across @ dirs.T) < math.cos(math.radians(45.0))  # (D, A)
        jaw = (~unknown & ~open_ & (wall > 0.0)).any(axis=1)[:, None]
        # along the jaw it goes on (where the CT lets the ray run to the reach); across it
        # (or at a depth where no ray meets bone) the surface point is outside: wall 0
        wall = np.where(open_ & along & jaw & ~unknown, max_wall_mm, wall)
        out = open_ & ~(along & jaw)
        wall = np.where(out, 0.0, wall)
        unknown = unknown & ~out
    return wall, unknown
