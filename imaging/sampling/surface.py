"""Where lines first meet bone: the entry points of ``ctdrill suggest``'s candidate axes.

Along each line ``p(t) = origin + t * direction`` (``direction`` a unit vector, ``t`` in mm)
the CT is sampled trilinearly every :data:`SURFACE_STEP_MM` from ``start_mm`` to ``stop_mm``.
The bone surface on that line is its **first crossing into bone**: the first sample that is
bone (:func:`ctdrill.imaging.misch.is_bone`, the one owner of the threshold: Misch D4 or
denser, ``HU >= 150``) whose previous sample was measured and below the threshold. The
crossing is then located on the trilinear field between those two samples by bisection to
:data:`SURFACE_TOL_MM`.

Exact or refused: samples outside the CT or touching padding are unknown, never air. A line
whose first measured sample is already bone (it starts inside bone, or enters the scanned
region inside bone), that never reaches bone, or whose first bone follows an unknown sample,
has no surface on it: NaN, and the caller says so.

The compiled kernel of :mod:`ctdrill.imaging.sampling.surface_kernel` does this on an
unpadded volume when its cache is present (the same samples and rules; this NumPy path is
its reference).
"""

from __future__ import annotations

import math

import numpy as np

from ctdrill.imaging.errors import ImagingInputError
from ctdrill.imaging.misch import BONE_HU
from ctdrill.imaging.sampling.kernel_args import fits, volume_args
from ctdrill.imaging.sampling.surface_kernel import SURFACE_KERNEL
from ctdrill.imaging.volume import CTVolume

#: Sampling step along the lines, mm: a third of the finest voxel of dental CT (0.3 mm).
SURFACE_STEP_MM = 0.1
#: Bisection tolerance of the crossing on the trilinear field, mm.
SURFACE_TOL_MM = 1e-6
#: Samples looked up at once (memory: about 50 bytes each); longer searches go in chunks.
_CHUNK_SAMPLES = 1_000_000


def first_bone_crossing_mm(
    volume: CTVolume,
    origins_lps: np.ndarray,
    directions: np.ndarray,
    *,
    start_mm: float,
    stop_mm: float,
) -> np.ndarray:
    """Parameter ``t`` (mm) of each line's first crossing into bone, or NaN.

    Parameters
    ----------
    volume : the CT (LPS).
    origins_lps : (N, 3) a point of each line, LPS mm.
    directions : (N, 3) unit direction of each line (the way "into" the patient).
    start_mm, stop_mm : the searched part of each line, ``start_mm < stop_mm``.

    Returns
    -------
    (N,) ``t`` with ``origin + t * direction`` on the bone threshold, mm; NaN where the line
    has no surface in ``[start_mm, stop_mm]`` (see the module docstring).
    """
    origins = np.asarray(origins_lps, dtype=np.float64).reshape(-1, 3)
    dirs = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
    if origins.shape != dirs.shape:
        raise ImagingInputError(
            f"first_bone_crossing_mm: {origins.shape[0]} origins but {dirs.shape[0]} directions"
        )
    if not (math.isfinite(start_mm) and math.isfinite(stop_mm) and start_mm < stop_mm):
        raise ImagingInputError(
            f"first_bone_crossing_mm: need finite start_mm < stop_mm, got {start_mm}, {stop_mm}"
        )
    n_t = math.ceil((stop_mm - start_mm) / SURFACE_STEP_MM - 1e-9) + 1
    ts = np.linspace(start_mm, stop_mm, n_t)
    out = np.full(origins.shape[0], np.nan)
    lines = max(1, _CHUNK_SAMPLES // n_t)
    compiled = fits(volume) and SURFACE_KERNEL.ready()
    args = volume_args(volume) if compiled else ()
    for lo in range(0, origins.shape[0], lines):
        part = slice(lo, lo + lines)
        if compiled:
            got = np.empty(origins[part].shape[0])
            SURFACE_KERNEL(
                *args,
                np.ascontiguousarray(origins[part]),
                np.ascontiguousarray(dirs[part]),
                ts,
                float(BONE_HU),
                SURFACE_TOL_MM,
                got,
            )
            out[part] = got
        else:
            out[part] = _crossings(volume, origins[part], dirs[part], ts)
    return out


def _crossings(
    volume: CTVolume, origins: np.ndarray, dirs: np.ndarray, ts: np.ndarray
) -> np.ndarray:
    """:func:`first_bone_crossing_mm` of a few lines sampled at ``ts``."""
    out = np.full(origins.shape[0], np.nan)
    pts = origins[:, None, :] + ts[None, :, None] * dirs[:, None, :]
    hu = volume.sample(pts, outside_hu=np.nan)  # (N, T); NaN: outside or padding
    bone = hu >= BONE_HU  # NaN compares False
    has = bone.any(axis=1)
    first = np.argmax(bone, axis=1)
    prev = np.maximum(first - 1, 0)
    rows = np.arange(origins.shape[0])
    ok = has & (first >= 1) & np.isfinite(hu[rows, prev])
    idx = np.flatnonzero(ok)
    if idx.size == 0:
        return out
    lo = ts[prev[idx]].copy()  # below the threshold
    hi = ts[first[idx]].copy()  # at or above it
    o, d = origins[idx], dirs[idx]
    while float(np.max(hi - lo)) > SURFACE_TOL_MM:
        mid = 0.5 * (lo + hi)
        v = volume.sample(o + mid[:, None] * d, outside_hu=np.nan)
        up = v >= BONE_HU  # both ends are inside the grid, so the midpoint is measured
        hi = np.where(up, mid, hi)
        lo = np.where(up, lo, mid)
    out[idx] = hi
    return out
