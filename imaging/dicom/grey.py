"""Linear grey-value -> HU calibration of a volume from two regions of known HU."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ctdrill.hu import AIR_HU
from ctdrill.imaging.errors import ImagingInputError
from ctdrill.imaging.volume import CTVolume


def _region_mean(volume: CTVolume, region: np.ndarray | tuple[slice, ...], name: str) -> float:
    mask = np.zeros(volume.hu.shape, dtype=bool)
    if isinstance(region, np.ndarray) and region.dtype == bool:
        if region.shape != volume.hu.shape:
            raise ImagingInputError(
                f"{name}: mask shape {region.shape} differs from the volume {volume.hu.shape}"
            )
        mask |= region
    else:
        mask[region] = True
    if volume.valid is not None:
        mask &= volume.valid
    if not mask.any():
        raise ImagingInputError(f"{name}: the region holds no valid voxel; choose another one")
    return float(volume.hu[mask].astype(np.float64).mean())


def calibrate_grey_to_hu(
    volume: CTVolume,
    *,
    air_region: np.ndarray | tuple[slice, ...],
    bone_or_water_region: np.ndarray | tuple[slice, ...],
    air_hu: float = AIR_HU,
    reference_hu: float = 0.0,
) -> CTVolume:
    """Linear grey -> HU calibration from two regions of known HU.

    Parameters
    ----------
    volume : CTVolume
        Grey values (e.g. CBCT without rescale).
    air_region, bone_or_water_region : np.ndarray | tuple[slice, ...]
        Boolean masks (slices, rows, cols) or index expressions (``np.s_[...]``) over ``hu``.
    air_hu : float
        HU of the first region (air, -1000).
    reference_hu : float
        HU of the second region (water 0, or a known bone/insert value).

    Returns
    -------
    CTVolume
        float32 HU = slope * grey + intercept through both region means; ``info.is_hu`` True,
        the ``not_hu`` warning removed.
    """
    g_air = _region_mean(volume, air_region, "air_region")
    g_ref = _region_mean(volume, bone_or_water_region, "bone_or_water_region")
    if abs(g_ref - g_air) < 1e-9:
        raise ImagingInputError(
            f"bone_or_water_region: mean grey {g_ref:g} equals the air region's; "
            "choose regions of different material"
        )
    slope = (reference_hu - air_hu) / (g_ref - g_air)
    intercept = air_hu - slope * g_air
    hu = (volume.hu.astype(np.float64) * slope + intercept).astype(np.float32)
    info = replace(
        volume.info,
        is_hu=True,
        rescale_type=f"HU (calibrated: {slope:.6g} x grey + {intercept:.6g})",
    )
    return CTVolume(
        hu=hu,
        affine_lps=volume.affine_lps,
        valid=volume.valid,
        info=info,
        warnings=tuple(w for w in volume.warnings if w.code != "not_hu"),
        slice_positions_mm=volume.slice_positions_mm,
    )
