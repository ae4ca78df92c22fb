"""Cross-sections perpendicular to the arch, tilted to contain an implant axis.

See :mod:`ctdrill.imaging.sampling.reformat` for the conventions.
"""

from __future__ import annotations

import math

import numpy as np

from ctdrill.hu import AIR_HU
from ctdrill.imaging.errors import ImagingInputError
from ctdrill.imaging.sampling.arch import TANGENT_WINDOW_MM, ArchCurve, ArchInputError
from ctdrill.imaging.sampling.reformat_grid import (
    check_options,
    default_pixel_mm,
    inside_fraction,
    slab_offsets_mm,
)
from ctdrill.imaging.sampling.reformat_types import (
    Reformat,
    SlabMode,
    count_check,
    readonly,
    sample_slab,
)
from ctdrill.imaging.volume import CTVolume

#: |axis component across the bucco-lingual normal| below which the cross-section is refused.
_DEGENERATE_AXIS = 1e-3
_EZ = np.array([0.0, 0.0, 1.0])


def cross_section(
    volume: CTVolume,
    arch_lps: np.ndarray,
    *,
    at_arc_mm: float | None = None,
    axis: tuple[np.ndarray, np.ndarray] | None = None,
    width_mm: float = 40.0,
    height_mm: float = 40.0,
    pixel_mm: float | None = None,
    slab_mm: float = 1.0,
    slab_mode: SlabMode = "mean",
    outside_hu: float = AIR_HU,
    tangent_window_mm: float = TANGENT_WINDOW_MM,
) -> Reformat:
    """A cross-section perpendicular to the arch (module docstring for the conventions).

    Parameters
    ----------
    volume : CTVolume
        The CT.
    arch_lps : np.ndarray
        (K, 3) arch polyline, LPS mm.
    at_arc_mm : float | None
        Arc position (mm from the arch's first point); None: the axis' own position (its
        midpoint projected on the arch), required when ``axis`` is None.
    axis : tuple[np.ndarray, np.ndarray] | None
        (entry_lps, target_lps) of an implant/drill axis: the plane is tilted to contain it and
        centred on its midpoint. None: an upright plane centred on the arch's height there.
    width_mm, height_mm : float
        Image size (mm), centred on the plane's centre.
    pixel_mm : float | None
        Pixel size (mm); None: the volume's smallest voxel spacing.
    slab_mm : float
        Slab thickness along the plane normal (mm).
    slab_mode : {"mean", "mip"}
        Slab average or maximum.
    outside_hu : float
        HU of samples outside the volume.
    tangent_window_mm : float
        Arc window (mm) of the tangent smoothing.

    Returns
    -------
    Reformat
        ``kind="cross_section"``.
    """
    curve = ArchCurve(np.asarray(arch_lps), tangent_window_mm)
    pixel = default_pixel_mm(volume) if pixel_mm is None else float(pixel_mm)
    check_options(pixel, slab_mm, slab_mode, width_mm, "width_mm")
    check_options(pixel, slab_mm, slab_mode, height_mm, "height_mm")
    centre, up, s = _plane_centre_up(curve, at_arc_mm, axis)
    _org, _tan, col = (v[0] for v in curve.frame(np.array([s])))
    up_in = up - (up @ col) * col
    if np.linalg.norm(up_in) < _DEGENERATE_AXIS:
        raise ImagingInputError(
            "cross-section: the axis runs along the arch's bucco-lingual normal (horizontal), "
            "so it spans no plane with it; a cross-section through a horizontal bucco-lingual "
            "axis is not defined, check the plan's entry and target"
        )
    row_up = up_in / np.linalg.norm(up_in)
    if row_up[2] < 0.0 or (row_up[2] == 0.0 and up[2] < 0.0):
        row_up = -row_up
    row = -row_up  # rows run down the image
    normal = np.cross(col, row_up)
    n_cols = 2 * math.ceil(0.5 * float(width_mm) / pixel - 1e-9) + 1
    n_rows = 2 * math.ceil(0.5 * float(height_mm) / pixel - 1e-9) + 1
    count_check(n_rows, n_cols, pixel)
    u = (np.arange(n_cols) - 0.5 * (n_cols - 1)) * pixel
    v = (np.arange(n_rows) - 0.5 * (n_rows - 1)) * pixel
    lps = centre + u[None, :, None] * col + v[:, None, None] * row
    inside = inside_fraction(volume, lps, "cross-section")
    offsets = slab_offsets_mm(volume, slab_mm)
    hu = sample_slab(volume, lps, normal[None, None, :], offsets, slab_mode, float(outside_hu))
    letters = _column_letters(curve, s, col)
    return Reformat(
        hu=readonly(hu),
        lps=readonly(np.ascontiguousarray(lps)),
        pixel_mm=pixel,
        kind="cross_section",
        slab_mm=float(slab_mm),
        slab_mode=slab_mode,
        slab_samples=int(offsets.size),
        arch_lps=curve.arch_lps,
        tangent_window_mm=curve.window_mm,
        outside_hu=float(outside_hu),
        at_arc_mm=float(s),
        plane_lps=readonly(np.stack([centre, col, row, normal])),
        column_letters=letters,
        inside_fraction=inside,
        _curve=curve,
    )


def _plane_centre_up(
    curve: ArchCurve,
    at_arc_mm: float | None,
    axis: tuple[np.ndarray, np.ndarray] | None,
) -> tuple[np.ndarray, np.ndarray, float]:
    """Plane centre (3,), axis "up" direction (3,) and arc position for a cross-section."""
    if axis is None:
        if at_arc_mm is None:
            raise ImagingInputError("cross-section: give at_arc_mm or an implant axis")
        s = _check_arc(curve, float(at_arc_mm))
        org, _t, _n = (v[0] for v in curve.frame(np.array([s])))
        return org + float(curve.point_z(np.array(s))) * _EZ, _EZ.copy(), s
    entry = np.asarray(axis[0], dtype=np.float64).reshape(3)
    target = np.asarray(axis[1], dtype=np.float64).reshape(3)
    direction = entry - target  # points out of the bone, towards the entry
    if not (np.all(np.isfinite(direction)) and np.linalg.norm(direction) > 1e-9):
        raise ImagingInputError("cross-section: the axis' entry and target must differ")
    mid = 0.5 * (entry + target)
    s_site, _ = curve.project(mid[None])
    if not np.isfinite(s_site[0]):
        raise ArchInputError(
            f"cross-section: the implant axis (midpoint {np.round(mid, 2).tolist()} LPS mm) "
            "lies beyond the arch's ends; extend the arch past the implant site"
        )
    site = float(s_site[0])
    s = site if at_arc_mm is None else _check_arc(curve, float(at_arc_mm))
    o0, t0, n0 = (v[0] for v in curve.frame(np.array([site])))
    local_dir = np.array([direction @ t0, direction @ n0, direction[2]])
    d_mid = mid - o0
    local_mid = np.array([d_mid @ t0, d_mid @ n0, mid[2]])
    o1, t1, n1 = (v[0] for v in curve.frame(np.array([s])))
    up = local_dir[0] * t1 + local_dir[1] * n1 + local_dir[2] * _EZ
    centre = o1 + local_mid[0] * t1 + local_mid[1] * n1 + local_mid[2] * _EZ
    return centre, up / np.linalg.norm(up), s


def _check_arc(curve: ArchCurve, s: float) -> float:
    if not (math.isfinite(s) and -1e-9 <= s <= curve.length_mm + 1e-9):
        raise ImagingInputError(
            f"cross-section: at_arc_mm {s!r} lies outside the arch (0 to {curve.length_mm:.1f} mm)"
        )
    return min(max(s, 0.0), curve.length_mm)


def _lps_letter(direction: np.ndarray) -> str:
    """The patient direction (``R L A P I S``) a vector points to most."""
    axis = int(np.argmax(np.abs(direction)))
    return ("RL", "AP", "IS")[axis][int(direction[axis] > 0.0)]


def _column_letters(curve: ArchCurve, s: float, col: np.ndarray) -> tuple[str, str]:
    """Buccal (away from the arch's centroid) and lingual sides of the image; a straight arch
    has no inside, so its sides get the patient directions (``R L A P``) instead."""
    buccal = curve.buccal_normal_xy(s)
    if buccal is None:
        return (_lps_letter(-col), _lps_letter(col))
    return ("B", "Li") if float(buccal @ col[:2]) < 0.0 else ("Li", "B")
