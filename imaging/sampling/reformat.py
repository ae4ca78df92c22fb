"""Panoramic (curved planar) reformat and cross-sections of a CT along the dental arch.

Pure numerics on :class:`~ctdrill.imaging.volume.CTVolume`; shared by ``ctdrill panorama``, the
GUI views and the report (docs/panorama.md). Conventions:

- **Pixels.** ``Reformat.hu[i, j]`` is row ``i`` (top first), column ``j``; ``Reformat.lps[i, j]``
  is the exact LPS position (mm) of that pixel's centre sample, the middle of its slab. Pixels
  are square, ``pixel_mm`` apart; by default the volume's smallest voxel spacing (the smallest
  of the column spacing, the row spacing and the smallest real slice step).
- **Panorama.** A vertical curtain on the arch (:mod:`ctdrill.imaging.sampling.arch`): column
  ``j`` stands at arc length ``j * pixel_mm`` along the arch's axial projection, from its first
  point (exact positions on the polyline); row ``i`` is at LPS height
  ``z_top - i * pixel_mm`` (rows run down patient superior -> inferior, so the image is
  upright). The slab runs across the arch along the column's bucco-lingual normal (horizontal),
  whose tangent is averaged over an arc window (``tangent_window_mm``) so normals turn smoothly
  through the polyline's vertices. Without ``height_mm`` the rows span the volume's whole LPS
  z range; with it they are centred on ``centre_z_mm`` (default the arch's mean height).
- **Cross-section.** The plane perpendicular to the arch at an arc position: columns along the
  arch's horizontal bucco-lingual normal there, rows down an "up" direction. Through an implant
  axis (``axis=(entry, target)``) the plane is tilted to contain the axis (it is spanned by the
  normal and the axis direction), centred on the axis midpoint; scrolling (``at_arc_mm``) carries
  the same tilt and offset, in the arch's local frame, along the arch. An axis along the
  bucco-lingual normal spans no plane with it and is refused.
- **Slab.** ``slab_mm`` thick, centred on the pixel, sampled at most half the smallest voxel
  spacing apart with both faces included (one sample when 0); ``mean`` averages the trilinear
  samples, ``mip`` keeps the largest.
- **Outside.** Samples outside the volume's voxel-centre hull (and padding) are ``outside_hu``,
  -1000 HU by default, via :meth:`CTVolume.sample` (which knows every slice's real position).
- **Memory and time.** Sampling runs in chunks of at most 262 144 points, so memory stays
  bounded (a 10 mm mean slab along a 120 mm arch through a 512 x 512 x 600 CT at 0.3 mm: 600 x
  400 pixels, 68 slab samples each, about 30 MB above the volume and 2.6 s on one core here;
  a cross-section takes a few tens of ms). Images larger than ``MAX_PIXELS`` are refused
  (raise ``pixel_mm``).
"""

from __future__ import annotations

import math

import numpy as np

from ctdrill.hu import AIR_HU
from ctdrill.imaging.sampling.arch import (
    TANGENT_WINDOW_MM,
    ArchCurve,
    ArchInputError,
    arc_position_mm,
)
from ctdrill.imaging.sampling.reformat_cross import cross_section
from ctdrill.imaging.sampling.reformat_grid import (
    check_options,
    default_pixel_mm,
    inside_fraction,
    slab_offsets_mm,
    volume_z_range_mm,
)
from ctdrill.imaging.sampling.reformat_types import (
    MAX_PIXELS,
    Reformat,
    ReformatKind,
    SlabMode,
    count_check,
    readonly,
    sample_slab,
)
from ctdrill.imaging.volume import CTVolume

__all__ = [
    "MAX_PIXELS",
    "TANGENT_WINDOW_MM",
    "ArchInputError",
    "Reformat",
    "ReformatKind",
    "SlabMode",
    "arc_position_mm",
    "cross_section",
    "panorama",
]


def _fold_notes(curve: ArchCurve, slab_mm: float) -> tuple[str, ...]:
    radius = curve.min_radius_mm()
    if 0.5 * slab_mm > radius:
        return (
            f"the slab's half thickness {0.5 * slab_mm:g} mm exceeds the arch's smallest "
            f"radius of curvature {radius:.1f} mm: neighbouring columns' slabs cross there",
        )
    return ()


def panorama(
    volume: CTVolume,
    arch_lps: np.ndarray,
    *,
    pixel_mm: float | None = None,
    slab_mm: float = 10.0,
    slab_mode: SlabMode = "mean",
    height_mm: float | None = None,
    centre_z_mm: float | None = None,
    outside_hu: float = AIR_HU,
    tangent_window_mm: float = TANGENT_WINDOW_MM,
) -> Reformat:
    """The panoramic reformat along the arch (module docstring for the conventions).

    Parameters
    ----------
    volume : CTVolume
        The CT.
    arch_lps : np.ndarray
        (K, 3) arch polyline, LPS mm, K >= 2.
    pixel_mm : float | None
        Pixel size (mm); None: the volume's smallest voxel spacing.
    slab_mm : float
        Slab thickness across the arch (mm); 0 samples the curtain only.
    slab_mode : {"mean", "mip"}
        Slab average or maximum intensity.
    height_mm : float | None
        Image height (mm), centred on ``centre_z_mm``; None: the volume's whole z range.
    centre_z_mm : float | None
        LPS height of the middle row with ``height_mm`` (mm); None: the arch's mean z.
    outside_hu : float
        HU of samples outside the volume.
    tangent_window_mm : float
        Arc window (mm) of the tangent smoothing.

    Returns
    -------
    Reformat
        ``kind="panorama"``.
    """
    curve = ArchCurve(np.asarray(arch_lps), tangent_window_mm)
    pixel = default_pixel_mm(volume) if pixel_mm is None else float(pixel_mm)
    check_options(pixel, slab_mm, slab_mode, height_mm, "height_mm")
    n_cols = math.floor(curve.length_mm / pixel + 1e-9) + 1
    if height_mm is None:
        z_lo, z_hi = volume_z_range_mm(volume)
        n_rows = math.floor((z_hi - z_lo) / pixel + 1e-9) + 1
        z_top = z_hi
    else:
        n_rows = 2 * math.ceil(0.5 * float(height_mm) / pixel - 1e-9) + 1
        mid_z = curve.mean_z_mm if centre_z_mm is None else float(centre_z_mm)
        if not math.isfinite(mid_z):
            raise ArchInputError(f"panorama: centre_z_mm {centre_z_mm!r} is not a finite height")
        z_top = mid_z + 0.5 * (n_rows - 1) * pixel
    count_check(n_rows, n_cols, pixel)
    s = np.arange(n_cols, dtype=np.float64) * pixel
    origin, _tangent, normal = curve.frame(s)
    z = z_top - np.arange(n_rows, dtype=np.float64) * pixel
    lps = np.empty((n_rows, n_cols, 3), dtype=np.float64)
    lps[:, :, :2] = origin[None, :, :2]
    lps[:, :, 2] = z[:, None]
    inside = inside_fraction(volume, lps, "panorama")
    offsets = slab_offsets_mm(volume, slab_mm)
    hu = sample_slab(volume, lps, normal[None], offsets, slab_mode, float(outside_hu))
    first_x, last_x = float(origin[0, 0]), float(origin[-1, 0])
    letters = ("R", "L") if first_x <= last_x else ("L", "R")
    return Reformat(
        hu=readonly(hu),
        lps=readonly(lps),
        pixel_mm=pixel,
        kind="panorama",
        slab_mm=float(slab_mm),
        slab_mode=slab_mode,
        slab_samples=int(offsets.size),
        arch_lps=curve.arch_lps,
        tangent_window_mm=curve.window_mm,
        outside_hu=float(outside_hu),
        column_letters=letters,
        notes=_fold_notes(curve, float(slab_mm)),
        inside_fraction=inside,
        _curve=curve,
    )
