"""Linear grey-value -> HU map of a volume (CBCT grey values are not HU), with its uncertainty.

``HU = slope x grey + intercept``, either given (with the standard errors of slope and intercept
when known) or fitted through two or more regions of known HU (e.g. air at -1000 and a
reference insert of known HU): the line through the regions' mean grey values (least squares
for more than two). The uncertainty of a region's grey level is its voxels' grey SD (not the
standard error of its mean: on CBCT the grey value of one material drifts with position, cupping
and scatter, so the spread is the honest measure of how well one number stands for it), and is
propagated to the slope and intercept. :meth:`GreyToHu.hu_error_cov` turns it into the HU error
model of the force band (``dHU = e0 + e1 HU``). :func:`apply_grey_map` is the one place the map
is applied to a volume.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ctdrill.hu import AIR_HU
from ctdrill.imaging.errors import ImagingInputError
from ctdrill.imaging.volume import CTVolume, LoadWarning
from ctdrill.numtext import number_text

Cov2 = tuple[tuple[float, float], tuple[float, float]]
#: Most voxels a sphere region may hold (a typo in the radius must not allocate the scan twice).
MAX_REGION_VOXELS = 2_000_000
#: Largest magnitude of a mapped CT number, HU: beyond any material (metal on an extended CT
#: scale reaches a few 10 000 HU; a CBCT's 16-bit grey values under a unit slope stay below);
#: a map sending a series past it is a typo (``1e300,0``), refused before anything is
#: computed (float32 would hold inf, and the force law NaN).
MAX_MAPPED_HU = 100_000.0


@dataclass(frozen=True)
class GreyRegion:
    """A region of known HU and what the volume holds there (grey values)."""

    center_lps: tuple[float, float, float]
    radius_mm: float
    known_hu: float
    mean_grey: float
    sd_grey: float
    n_voxels: int

    def to_json(self) -> dict[str, Any]:
        return {
            "center_lps_mm": list(self.center_lps),
            "radius_mm": self.radius_mm,
            "known_hu": self.known_hu,
            "mean_grey": round(self.mean_grey, 4),
            "sd_grey": round(self.sd_grey, 4),
            "voxels": self.n_voxels,
        }


@dataclass(frozen=True)
class GreyToHu:
    """``HU = slope x grey + intercept`` and the covariance of ``(slope, intercept)``.

    ``cov`` None: the uncertainty is not known (a map given without standard errors).
    """

    slope: float
    intercept: float
    cov: Cov2 | None
    method: str
    regions: tuple[GreyRegion, ...] = ()

    def __post_init__(self) -> None:
        if not (math.isfinite(self.slope) and math.isfinite(self.intercept)) or self.slope == 0:
            raise ImagingInputError(
                f"grey-to-HU map: slope and intercept must be finite and the slope non-zero, "
                f"got {self.slope!r}, {self.intercept!r}"
            )

    def hu_error_cov(self) -> Cov2 | None:
        """Covariance of ``(e0, e1)`` in ``dHU = e0 + e1 HU`` (None when not known).

        ``dHU = grey ds + dc`` with ``grey = (HU - c) / s``: ``e0 = dc - (c / s) ds``,
        ``e1 = ds / s``.
        """
        if self.cov is None:
            return None
        s, c = self.slope, self.intercept
        a = np.array([[-c / s, 1.0], [1.0 / s, 0.0]])
        m = a @ np.array(self.cov) @ a.T
        m = (m + m.T) / 2.0
        return ((float(m[0, 0]), float(m[0, 1])), (float(m[1, 0]), float(m[1, 1])))

    def to_json(self) -> dict[str, Any]:
        """What outputs record: the map, how it was obtained, its standard errors."""
        se = None if self.cov is None else [math.sqrt(self.cov[0][0]), math.sqrt(self.cov[1][1])]
        return {
            "slope": self.slope,
            "intercept": self.intercept,
            "slope_se": None if se is None else se[0],
            "intercept_se": None if se is None else se[1],
            "slope_intercept_cov": None if self.cov is None else self.cov[0][1],
            "method": self.method,
            "regions": [r.to_json() for r in self.regions],
        }


def given_grey_map(
    slope: float, intercept: float, slope_se: float | None = None, intercept_se: float | None = None
) -> GreyToHu:
    """A map given as numbers; with both standard errors its uncertainty (uncorrelated)."""
    if (slope_se is None) != (intercept_se is None):
        raise ImagingInputError("grey-to-HU map: give both standard errors or neither")
    cov: Cov2 | None = None
    if slope_se is not None and intercept_se is not None:
        if not all(math.isfinite(v) and v >= 0 for v in (slope_se, intercept_se)):
            raise ImagingInputError("grey-to-HU map: standard errors must be finite and >= 0")
        cov = ((slope_se**2, 0.0), (0.0, intercept_se**2))
    what = "given" + ("" if cov else " without standard errors (uncertainty not known)")
    return GreyToHu(slope, intercept, cov, f"{what}: HU = {slope:g} x grey + {intercept:g}")


def sphere_region(
    volume: CTVolume, center_lps: Sequence[float], radius_mm: float, known_hu: float
) -> GreyRegion:
    """Mean and SD of the grey values whose voxel centres lie within ``radius_mm`` of
    ``center_lps`` (valid voxels only)."""
    c = np.asarray(center_lps, dtype=np.float64)
    where = f"region at {[round(float(v), 3) for v in c]} mm, radius {radius_mm:g} mm"
    if c.shape != (3,) or not np.all(np.isfinite(c)) or not (0.0 < radius_mm < 1e3):
        raise ImagingInputError(f"{where}: give a finite LPS point and 0 < radius < 1000 mm")
    n_slices, n_rows, n_cols = volume.hu.shape
    corners = np.array([[dx, dy, dz] for dx in (-1, 1) for dy in (-1, 1) for dz in (-1, 1)])
    idx = volume.lps_to_index(c + radius_mm * corners)
    lo = np.maximum(np.floor(idx.min(axis=0)).astype(int), 0)
    hi = np.minimum(np.ceil(idx.max(axis=0)).astype(int), [n_cols - 1, n_rows - 1, n_slices - 1])
    if np.any(hi < lo):
        raise ImagingInputError(f"{where}: lies outside the volume; choose a point inside it")
    if int(np.prod(hi - lo + 1)) > MAX_REGION_VOXELS:
        raise ImagingInputError(f"{where}: holds too many voxels; give a smaller radius")
    ii, jj, kk = np.meshgrid(
        *(np.arange(a, b + 1) for a, b in zip(lo, hi, strict=True)), indexing="ij"
    )
    ijk = np.stack([ii, jj, kk], axis=-1).reshape(-1, 3)
    inside = np.linalg.norm(volume.index_to_lps(ijk) - c, axis=1) <= radius_mm
    ijk = ijk[inside]
    if volume.valid is not None and ijk.size:
        ijk = ijk[volume.valid[ijk[:, 2], ijk[:, 1], ijk[:, 0]]]
    if ijk.shape[0] < 2:
        raise ImagingInputError(f"{where}: holds fewer than 2 valid voxels; give a larger radius")
    grey = volume.hu[ijk[:, 2], ijk[:, 1], ijk[:, 0]].astype(np.float64)
    return GreyRegion(
        center_lps=(float(c[0]), float(c[1]), float(c[2])),
        radius_mm=float(radius_mm),
        known_hu=float(known_hu),
        mean_grey=float(grey.mean()),
        sd_grey=float(grey.std(ddof=1)),
        n_voxels=int(grey.size),
    )


def _line(grey: np.ndarray, hu: np.ndarray) -> tuple[float, float]:
    slope, intercept = np.polyfit(grey, hu, 1)
    return float(slope), float(intercept)


def grey_map_from_regions(regions: Sequence[GreyRegion]) -> GreyToHu:
    """The line through two or more regions' (mean grey, known HU); its covariance from the
    regions' grey SDs (module docstring), propagated by the exact Jacobian of the fit."""
    if len(regions) < 2:
        raise ImagingInputError("grey-to-HU map: give at least two regions of known HU")
    g = np.array([r.mean_grey for r in regions])
    h = np.array([r.known_hu for r in regions])
    if np.ptp(g) < 1e-9 or np.ptp(h) <= 0.0:
        raise ImagingInputError(
            "grey-to-HU map: the regions' mean grey values (or known HU) are all equal; "
            "choose regions of different material"
        )
    slope, intercept = _line(g, h)
    jac = np.zeros((2, g.size))
    for i in range(g.size):
        step = 1e-6 * max(1.0, abs(g[i]))
        up, dn = g.copy(), g.copy()
        up[i] += step
        dn[i] -= step
        jac[:, i] = (np.array(_line(up, h)) - np.array(_line(dn, h))) / (2.0 * step)
    m = jac @ np.diag([r.sd_grey**2 for r in regions]) @ jac.T
    cov: Cov2 = ((float(m[0, 0]), float(m[0, 1])), (float(m[0, 1]), float(m[1, 1])))
    return GreyToHu(
        slope,
        intercept,
        cov,
        f"fitted through {len(regions)} regions of known HU (uncertainty from their grey SDs)",
        tuple(regions),
    )


def mapped_range_error(volume: CTVolume, grey_map: GreyToHu) -> str | None:
    """Why ``grey_map`` cannot be applied to ``volume``, or None: the HU it gives the
    volume's values (valid voxels) must lie within :data:`MAX_MAPPED_HU` of 0."""
    values = volume.hu if volume.valid is None else volume.hu[volume.valid]
    if values.size == 0:
        return None
    ends = np.array([float(values.min()), float(values.max())])
    with np.errstate(over="ignore", invalid="ignore"):
        mapped = ends * grey_map.slope + grey_map.intercept
    if np.all(np.isfinite(mapped)) and np.all(np.abs(mapped) <= MAX_MAPPED_HU):
        return None
    lo, hi = sorted(float(v) for v in mapped)
    return (
        f"HU = {number_text(grey_map.slope)} x grey + {number_text(grey_map.intercept)} sends "
        f"the series' values {number_text(ends[0])}..{number_text(ends[1])} to "
        f"{number_text(lo, 3)}..{number_text(hi, 3)} HU, beyond the +/-"
        f"{number_text(MAX_MAPPED_HU)} HU any material has; check the slope and intercept"
    )


def _rescale(volume: CTVolume) -> str:
    info = volume.info
    if info.source_format != "DICOM":  # a volume file: no unit, its values read as HU
        return f" (a {info.source_format} file whose values read as HU: they reach air)"
    return f" (RescaleType {info.rescale_type})" if info.rescale_type else ""


def apply_grey_map(volume: CTVolume, grey_map: GreyToHu) -> CTVolume:
    """The volume in HU: ``float32(slope x value + intercept)`` of the values as loaded;
    ``info.is_hu`` True, ``rescale_type`` naming the map, the ``not_hu`` warning removed.

    A series already in HU (``info.is_hu``) is mapped as asked, with the warning
    ``grey_map_on_hu`` (a map for grey values applied to HU is usually a mistake).

    Raises
    ------
    ImagingInputError
        The map sends the volume's values beyond :data:`MAX_MAPPED_HU`
        (:func:`mapped_range_error`).
    """
    problem = mapped_range_error(volume, grey_map)
    if problem is not None:
        raise ImagingInputError(f"grey-to-HU map: {problem}")
    hu = (volume.hu.astype(np.float64) * grey_map.slope + grey_map.intercept).astype(np.float32)
    warnings = tuple(w for w in volume.warnings if w.code != "not_hu")
    if volume.info.is_hu:
        warnings += (
            LoadWarning(
                "grey_map_on_hu",
                f"the series is already in HU{_rescale(volume)} and the "
                f"grey-to-HU map HU = {number_text(grey_map.slope)} x value + "
                f"{number_text(grey_map.intercept)} was applied to it as asked; a map for "
                "grey values (CBCT) changes HU that were right: drop --grey-to-hu/--grey-ref "
                "unless this is meant",
            ),
        )
    info = replace(
        volume.info,
        is_hu=True,
        rescale_type=f"HU (calibrated: {grey_map.slope:.6g} x grey + {grey_map.intercept:.6g})",
    )
    return CTVolume(
        hu=hu,
        affine_lps=volume.affine_lps,
        valid=volume.valid,
        info=info,
        warnings=warnings,
        slice_positions_mm=volume.slice_positions_mm,
    )


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
    """Linear grey -> HU calibration from two index regions of known HU.

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
        :func:`apply_grey_map` of the line through both region means.
    """
    g_air = _region_mean(volume, air_region, "air_region")
    g_ref = _region_mean(volume, bone_or_water_region, "bone_or_water_region")
    if abs(g_ref - g_air) < 1e-9:
        raise ImagingInputError(
            f"bone_or_water_region: mean grey {g_ref:g} equals the air region's; "
            "choose regions of different material"
        )
    slope = (reference_hu - air_hu) / (g_ref - g_air)
    return apply_grey_map(
        volume, GreyToHu(slope, air_hu - slope * g_air, None, "two index regions")
    )
