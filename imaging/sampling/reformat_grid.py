"""Grid choices of a reformat: default pixel size, slab samples, the volume's z range, checks.

One owner for the rules :mod:`ctdrill.imaging.sampling.reformat` documents: the default pixel
is the volume's smallest voxel spacing, slab samples are at most half of it apart with both
slab faces included.
"""

from __future__ import annotations

import math
from itertools import product

import numpy as np

from ctdrill.imaging.errors import ImagingInputError
from ctdrill.imaging.volume import CTVolume

#: Slab samples are at most this fraction of the smallest voxel spacing apart.
SLAB_STEP_FRACTION = 0.5
#: Thickest slab accepted (mm): a whole head is about 200 mm.
MAX_SLAB_MM = 200.0


def smallest_spacing_mm(volume: CTVolume) -> float:
    """Smallest of the column spacing, the row spacing and the smallest real slice step."""
    col, row, _ = volume.spacing_mm
    steps = np.abs(np.diff(volume.slice_positions_mm))
    candidates = [col, row] + ([float(np.min(steps))] if steps.size else [])
    return float(min(candidates))


def default_pixel_mm(volume: CTVolume) -> float:
    """Default reformat pixel size (mm): :func:`smallest_spacing_mm`."""
    return smallest_spacing_mm(volume)


def slab_offsets_mm(volume: CTVolume, slab_mm: float) -> np.ndarray:
    """Sample offsets across a slab (mm): ``[0]`` for 0 mm, else ``-slab/2 .. +slab/2``
    inclusive, at most ``SLAB_STEP_FRACTION`` x the smallest voxel spacing apart."""
    if slab_mm <= 0.0:
        return np.zeros(1)
    step = SLAB_STEP_FRACTION * smallest_spacing_mm(volume)
    n = math.ceil(slab_mm / step - 1e-9) + 1
    return np.linspace(-0.5 * slab_mm, 0.5 * slab_mm, n)


def volume_z_range_mm(volume: CTVolume) -> tuple[float, float]:
    """(lowest, highest) LPS z of the volume's voxel-centre hull (its eight corners), mm."""
    cols, rows, slices = volume.dims
    corners = np.array(
        list(product((0, cols - 1), (0, rows - 1), (0, slices - 1))), dtype=np.float64
    )
    z = volume.index_to_lps(corners)[:, 2]
    return float(np.min(z)), float(np.max(z))


def check_options(
    pixel_mm: float, slab_mm: float, slab_mode: str, size_mm: float | None, size_name: str
) -> None:
    """Refuse a bad pixel size, slab, mode or image size with one clear message."""
    if not (math.isfinite(pixel_mm) and pixel_mm > 0.0):
        raise ImagingInputError(f"reformat: pixel_mm {pixel_mm!r} must be a positive number")
    if not (math.isfinite(slab_mm) and 0.0 <= slab_mm <= MAX_SLAB_MM):
        raise ImagingInputError(
            f"reformat: slab_mm {slab_mm!r} must be between 0 and {MAX_SLAB_MM:g} mm"
        )
    if slab_mode not in ("mean", "mip"):
        raise ImagingInputError(f"reformat: slab mode {slab_mode!r} must be 'mean' or 'mip'")
    if size_mm is not None and not (math.isfinite(size_mm) and size_mm > 0.0):
        raise ImagingInputError(f"reformat: {size_name} {size_mm!r} must be a positive number")


def inside_fraction(volume: CTVolume, lps: np.ndarray, what: str) -> float:
    """Fraction of the image's pixel centres (the slab's middle) inside the CT's voxel-centre
    hull; an image wholly outside is refused (an arch or axis in the wrong frame or series).
    """
    h, w = lps.shape[:2]
    top = np.array([volume.dims[0], volume.dims[1], volume.dims[2]], dtype=np.float64) - 1.0
    count = 0
    rows = max(1, 262_144 // max(w, 1))
    for r0 in range(0, h, rows):
        idx = volume.lps_to_index(lps[r0 : r0 + rows])
        count += int(np.count_nonzero(np.all((idx >= -1e-6) & (idx <= top + 1e-6), axis=-1)))
    if count == 0:
        lo, hi = np.min(lps, axis=(0, 1)), np.max(lps, axis=(0, 1))
        z_lo, z_hi = volume_z_range_mm(volume)
        raise ImagingInputError(
            f"{what}: the whole image (LPS x {lo[0]:.1f}..{hi[0]:.1f}, y {lo[1]:.1f}..{hi[1]:.1f}, "
            f"z {lo[2]:.1f}..{hi[2]:.1f} mm) lies outside the CT (z {z_lo:.1f}..{z_hi:.1f} mm); "
            "check the plan's coordinate_system (LPS or RAS) and that the plan was made on this "
            "series"
        )
    return count / float(h * w)
