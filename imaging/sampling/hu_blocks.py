"""Blocks of a CT whose trilinear field lies in one class of CT numbers, for skipping along rays.

A ray marched through the CT (the bone walls' envelope rays,
:mod:`~ctdrill.imaging.sampling.envelope_kernel`) only needs the *class* of each sample (air,
soft tissue, bone, tooth; the thresholds of the envelope rule), not its CT number. The volume
is cut into blocks of :data:`BLOCK` x :data:`BLOCK` x :data:`BLOCK` trilinear cells; a block
whose voxels (the cells' corners, :data:`BLOCK` + 1 a side) all lie strictly inside one class
has every trilinear sample inside it in that class too (a trilinear sample is a convex
combination of its cell's corners), so a ray's samples within the block are classed without
being read, and the march steps over the whole block at once.

The blocks' classes are a per-volume cache (:func:`block_classes`, kept with the volume and
dropped with it), filled lazily inside the kernels as rays reach each block (a block is
classed once by reading its corners: the first call costs about one full read of the blocks
it meets, later calls almost none). The test is conservative: a corner within
:func:`margin_hu` of a class's edge, a NaN, or a block at an irregular stack's remapped slice
positions is never uniform, so a ray skips a block only where no crossing of any threshold of
the trilinear field can lie.
"""

from __future__ import annotations

import math
import threading
import weakref

import numpy as np

from ctdrill.imaging.volume import CTVolume
from ctdrill.jit import helper

#: Trilinear cells a side of a block (0.4 mm voxels: 1.6 mm, 8 ray samples of 0.2 mm).
BLOCK = 4
#: Codes of a block (int8): not classed yet, mixed (a threshold may be crossed inside), ...
UNKNOWN = -1
MIXED = 0
#: ... every sample soft (``air_hu <= hu < bone_hu``) or every sample bone-range
#: (``bone_hu <= hu < tooth_hu``; a tooth nearby still makes it not bone, the caller's rule).
SOFT = 1
BONE = 2
#: A sample's own class as the kernels code it (int8): outside the CT (NaN), air, soft,
#: bone-range, tooth.
GONE = 3
AIR = 4
TOOTH = 5
#: Index-space margin kept from a block's faces: the kernels' own index arithmetic of a
#: sample may differ from the run's extrapolation by rounding (~1e-13 voxel).
MARGIN_VOX = 1e-6

_CACHE: weakref.WeakKeyDictionary[CTVolume, dict[tuple[float, float, float], np.ndarray]] = (
    weakref.WeakKeyDictionary()
)
_BOUND: weakref.WeakKeyDictionary[CTVolume, float] = weakref.WeakKeyDictionary()
_LOCK = threading.Lock()


def block_classes(volume: CTVolume, air_hu: float, bone_hu: float, tooth_hu: float) -> np.ndarray:
    """The volume's (writable, shared) int8 block codes for these thresholds, all
    :data:`UNKNOWN` at first; (0, 0, 0) for an irregular stack (no blocks: its index
    coordinates are not linear along a ray)."""
    key = (float(air_hu), float(bone_hu), float(tooth_hu))
    with _LOCK:
        per = _CACHE.setdefault(volume, {})
        out = per.get(key)
        if out is None:
            if volume._remap_k:
                out = np.zeros((0, 0, 0), dtype=np.int8)
            else:
                shape = tuple(math.ceil(max(n - 1, 1) / BLOCK) for n in volume.hu.shape)
                out = np.full(shape, UNKNOWN, dtype=np.int8)
            per[key] = out
        return out


def hu_bound(volume: CTVolume) -> float:
    """A bound on the volume's absolute CT numbers, HU (int16: its range; float32: read once
    and kept with the volume)."""
    if volume.hu.dtype == np.int16:
        return 32768.0
    with _LOCK:
        found = _BOUND.get(volume)
    if found is None:
        found = float(np.nanmax(np.abs(volume.hu), initial=0.0))
        with _LOCK:
            _BOUND[volume] = found
    return found


@helper
def margin_hu(lo: float, hi: float) -> float:  # pragma: no cover - compiled
    """How far inside a class's edges a block's corners must lie, HU: far beyond the rounding
    of a trilinear sum of eight corners (~1e-12 HU)."""
    return 1e-6 + 1e-9 * max(abs(lo), abs(hi))


@helper
def block_code(
    vol: np.ndarray,
    blocks: np.ndarray,
    bk: int,
    bj: int,
    bi: int,
    air_hu: float,
    bone_hu: float,
    tooth_hu: float,
) -> int:  # pragma: no cover - compiled; tested against the full march
    """The code of block (bk, bj, bi), classed now from its corners when still unknown."""
    code = blocks[bk, bj, bi]
    if code != UNKNOWN:
        return int(code)
    n_k, n_j, n_i = vol.shape
    lo = math.inf
    hi = -math.inf
    nan = False
    for k in range(bk * BLOCK, min(bk * BLOCK + BLOCK, n_k - 1) + 1):
        for j in range(bj * BLOCK, min(bj * BLOCK + BLOCK, n_j - 1) + 1):
            for i in range(bi * BLOCK, min(bi * BLOCK + BLOCK, n_i - 1) + 1):
                v = float(vol[k, j, i])
                if v != v:
                    nan = True
                if v < lo:
                    lo = v
                if v > hi:
                    hi = v
    out = MIXED
    if not nan:
        eps = margin_hu(lo, hi)
        if lo >= bone_hu + eps and hi < tooth_hu - eps:
            out = BONE
        elif lo >= air_hu + eps and hi < bone_hu - eps:
            out = SOFT
    blocks[bk, bj, bi] = out  # one byte: threads racing here write the same value
    return out


@helper
def _axis_run(c: float, inv_d: float, top: float) -> tuple[int, int]:  # pragma: no cover
    """``(block, more)``: the block index of coordinate ``c`` along one axis and how many more
    steps of ``1 / inv_d`` stay :data:`MARGIN_VOX` inside it and the hull (``block`` -1: ``c``
    is not that far inside one)."""
    if not (c >= MARGIN_VOX and c <= top - MARGIN_VOX):
        return -1, 0
    b = int(c * (1.0 / BLOCK))  # c > 0: truncation is the floor
    lo = b * BLOCK + MARGIN_VOX
    hi = min((b + 1) * BLOCK, top) - MARGIN_VOX
    if c < lo or c > hi:
        return -1, 0
    more = 1e9
    if inv_d > 0.0:
        more = min(more, (hi - c) * inv_d)
    elif inv_d < 0.0:
        more = min(more, (lo - c) * inv_d)
    return b, int(more)


@helper
def block_run(
    vol: np.ndarray,
    blocks: np.ndarray,
    top: np.ndarray,
    ci: float,
    cj: float,
    ck: float,
    inv_di: float,
    inv_dj: float,
    inv_dk: float,
    air_hu: float,
    bone_hu: float,
    tooth_hu: float,
) -> tuple[int, int]:  # pragma: no cover - compiled; tested against the full march
    """``(count, code)``: a ray's sample at index coordinates (ci, cj, ck) and the
    ``count - 1`` samples after it lie in one block (kept :data:`MARGIN_VOX` inside its faces
    and the CT's hull) whose code is ``code``; ``(0, MIXED)`` when the sample itself is not
    that far inside a block. The ray steps by (1 / inv_di, 1 / inv_dj, 1 / inv_dk) voxels a
    sample (an inverse 0: a step below 1e-12 voxel along that axis, which a ray's few hundred
    samples never move by the margin)."""
    bi, mi = _axis_run(ci, inv_di, top[0])
    if bi < 0:
        return 0, MIXED
    bj, mj = _axis_run(cj, inv_dj, top[1])
    if bj < 0:
        return 0, MIXED
    bk, mk = _axis_run(ck, inv_dk, top[2])
    if bk < 0:
        return 0, MIXED
    code = block_code(vol, blocks, bk, bj, bi, air_hu, bone_hu, tooth_hu)
    return min(mi, mj, mk) + 1, code
