"""Teeth are not bone: where the CT shows a tooth, and how far an implant keeps from it.

**The rule** (one threshold, :data:`TOOTH_HU`): a sample at or above 2000 HU is tooth (enamel
and the dense dentin of crowns and root trunks) or metal (restorations, posts, a scan
template's markers), never bone. Cortical bone in CT reads up to about 1800-1900 HU (the demo
phantom's cortex 1500-1800), enamel about 2500-3000, metal beyond the scale. So:

- bone is :data:`~ctdrill.imaging.misch.BONE_HU` <= HU < :data:`TOOTH_HU`
  (:func:`is_bone_hu`): the walls' envelope and the crest read bone only, a crown standing on
  the crest is not counted as wall and the crest is the bone's, not the crown's;
- the implant's distance to the neighbouring teeth is the distance from its body to the
  nearest tooth voxel (:func:`tooth_distance_mm`; negative: the body enters a tooth).

What it does not find: root dentin below about 2000 HU (apical roots, the thin roots of
incisors, everything on coarse voxels where partial volume averages a root with the bone around
it) reads as bone, so the distance to a root is an upper bound where the root is faint
(docs/plan.md, "Teeth"). Standard NumPy only.
"""

from __future__ import annotations

import weakref

import numpy as np

from ctdrill.imaging.misch import BONE_HU
from ctdrill.imaging.volume import CTVolume

#: At or above this a sample is tooth or metal, never bone, HU.
TOOTH_HU = 2000.0
#: Teeth farther than this from an implant's axis are not its neighbours, mm.
NEIGHBOUR_MM = 25.0

_POINTS: weakref.WeakKeyDictionary[CTVolume, np.ndarray] = weakref.WeakKeyDictionary()


def is_bone_hu(hu: np.ndarray) -> np.ndarray:
    """Bone, not tooth: ``BONE_HU <= hu < TOOTH_HU`` (NaN: False)."""
    h = np.asarray(hu, dtype=np.float64)
    with np.errstate(invalid="ignore"):
        out: np.ndarray = (h >= BONE_HU) & (h < TOOTH_HU)
    return out


def bone_along(hu: np.ndarray, edge_steps: int) -> np.ndarray:
    """Bone along sampled lines (the last axis of ``hu``): :func:`is_bone_hu`, less the samples
    within ``edge_steps`` of a tooth sample (the trilinear edge of a tooth passes through the
    bone band: a crown's surface against air or soft tissue is not a layer of bone)."""
    bone = is_bone_hu(hu)
    tooth = is_tooth_hu(hu)
    near = tooth.copy()
    for k in range(1, max(0, int(edge_steps)) + 1):
        near[..., k:] |= tooth[..., :-k]
        near[..., :-k] |= tooth[..., k:]
    out: np.ndarray = bone & ~near
    return out


def edge_steps(volume: CTVolume, step_mm: float) -> int:
    """How many samples ``step_mm`` apart a tooth's trilinear edge spans: one voxel (the
    volume's coarsest spacing)."""
    return int(np.ceil(max(volume.spacing_mm) / step_mm - 1e-9))


def is_tooth_hu(hu: np.ndarray) -> np.ndarray:
    """Tooth or metal: ``hu >= TOOTH_HU`` (NaN: False)."""
    with np.errstate(invalid="ignore"):
        out: np.ndarray = np.asarray(hu, dtype=np.float64) >= TOOTH_HU
    return out


#: Slices of the CT compared with :data:`TOOTH_HU` at a time (no full-size mask).
TOOTH_SLAB = 16


def tooth_points_lps(volume: CTVolume) -> np.ndarray:
    """(N, 3) LPS centres of the volume's tooth voxels (padding excluded), computed once per
    volume, :data:`TOOTH_SLAB` slices at a time (a 640 x 640 x 480 CT: 0.2 s instead of
    1 s and a 197 MB mask; int16 voxels are compared as int16, float32 ones as float32,
    which classes every voxel as the float64 comparison does: the threshold is exact in
    both)."""
    cached = _POINTS.get(volume)
    if cached is not None:
        return cached
    hu = np.asarray(volume.hu)
    valid = None if volume.valid is None else np.asarray(volume.valid)
    threshold = hu.dtype.type(TOOTH_HU) if hu.dtype in (np.int16, np.float32) else TOOTH_HU
    found: list[tuple[np.ndarray, ...]] = []
    for k0 in range(0, hu.shape[0], TOOTH_SLAB):
        mask = hu[k0 : k0 + TOOTH_SLAB] >= threshold
        if valid is not None:
            mask &= valid[k0 : k0 + TOOTH_SLAB]
        if mask.any():
            k, j, i = np.nonzero(mask)
            found.append((i, j, k + k0))
    if found:
        i, j, k = (np.concatenate(axis) for axis in zip(*found, strict=True))
    else:
        i = j = k = np.zeros(0, dtype=np.intp)
    ijk1 = np.stack([i, j, k, np.ones_like(i)]).astype(np.float64)
    pts = (np.asarray(volume.affine_lps) @ ijk1)[:3].T.copy()
    pts.flags.writeable = False
    _POINTS[volume] = pts
    return pts


def tooth_distance_mm(
    volume: CTVolume,
    platform_lps: np.ndarray,
    axis_lps: np.ndarray,
    length_mm: float,
    radius_at_mm: np.ndarray,
) -> float | None:
    """The distance from an implant body (platform, unit axis, length; ``radius_at_mm`` (D,)
    its radius at D equal steps from the platform to the apex) to the nearest tooth voxel
    centre within :data:`NEIGHBOUR_MM` of its axis, mm (negative: a tooth voxel inside the
    body); None when there is none."""
    pts = tooth_points_lps(volume)
    if len(pts) == 0:
        return None
    rel = pts - np.asarray(platform_lps)
    s = rel @ np.asarray(axis_lps)
    s_clip = np.clip(s, 0.0, length_mm)
    radial = np.linalg.norm(rel - s[:, None] * np.asarray(axis_lps), axis=1)
    near = np.flatnonzero((radial <= NEIGHBOUR_MM) & (np.abs(s - s_clip) <= NEIGHBOUR_MM))
    if near.size == 0:
        return None
    r = np.asarray(radius_at_mm, dtype=np.float64)
    grid = np.linspace(0.0, length_mm, len(r))
    radius = np.interp(s_clip[near], grid, r)
    along = s[near] - s_clip[near]
    out = np.sqrt(np.maximum(radial[near] - radius, 0.0) ** 2 + along**2)
    inside = (along == 0.0) & (radial[near] < radius)
    out = np.where(inside, radial[near] - radius, out)
    return float(out.min())
