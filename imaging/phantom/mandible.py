"""The synthetic mandible phantom: voxels, canal truth and a drilling plan.

The anatomy is the analytic field of :mod:`ctdrill.imaging.phantom.field` (signed distances, so
tests know exact answers), sampled at the voxel centres of an isotropic grid, plus the optional
metal streak artefact and Gaussian noise, rounded and clipped to the 12-bit CT range [-1024, 3071].
The plan enters on the alveolar crest straight above the canal and drills straight down deeper
than the 2 mm margin allows (``Phantom.max_safe_depth_mm``), so the export stops on the margin.
It places a generic tapered implant (4.1 x 11.5 mm, apex at the target) and gives the dental
arch: the body's mid-line at mid-height, along which a panoramic reformat shows the mandible
and the canal.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ctdrill.imaging.errors import ImagingInputError
from ctdrill.imaging.phantom.field import (
    AIR_HU,
    CANAL_HU,
    HU_MAX,
    HU_MIN,
    LABELS,
    METAL_HU,
    MISCH_CLASSES,
    SOFT_TISSUE_HU,
    MandibleGeometry,
    body_coords,
    bone_sdf_mm,
    canal_distance_mm,
    label_hu,
    mandible_hu,
    mandible_labels,
    streak_hu,
    voxel_centres_lps,
)
from ctdrill.imaging.plan.clinical import CLINICAL_MARGIN_MM
from ctdrill.imaging.plan.implants import load_implant_library

__all__ = [
    "AIR_HU",
    "CANAL_HU",
    "FOV_CENTRE_LPS",
    "FOV_MM",
    "HU_MAX",
    "HU_MIN",
    "LABELS",
    "MAX_VOXELS",
    "METAL_HU",
    "MISCH_CLASSES",
    "SOFT_TISSUE_HU",
    "MandibleGeometry",
    "Phantom",
    "PhantomInputError",
    "body_coords",
    "bone_sdf_mm",
    "canal_distance_mm",
    "default_shape",
    "label_hu",
    "make_mandible_phantom",
    "mandible_hu",
    "mandible_labels",
    "streak_hu",
    "voxel_centres_lps",
]


#: Default field of view, mm, as (slices: S-I, rows: A-P, cols: R-L).
FOV_MM = (32.0, 40.0, 32.0)
#: LPS centre of the field of view, mm (a left posterior mandible segment).
FOV_CENTRE_LPS = (30.0, 10.0, -40.0)


class PhantomInputError(ImagingInputError):
    """Bad phantom parameter."""


@dataclass(frozen=True, eq=False)
class Phantom:
    """A generated phantom: voxels, geometry, truth and the drilling plan.

    Attributes
    ----------
    hu : np.ndarray
        (slices, rows, cols) int16 HU.
    affine_lps : np.ndarray
        (4, 4) float64 ``(i=col, j=row, k=slice, 1)`` -> LPS mm.
    canal_centerline_lps : np.ndarray
        (N, 3) LPS mm, the canal centreline polyline inside the field of view.
    canal_radius_mm : float
        Canal radius, mm.
    cortical_thickness_mm : float
        Cortical shell thickness, mm.
    misch : str
        Misch class of the trabecular bone (D1..D5).
    geometry : MandibleGeometry
        The analytic description (:func:`mandible_hu` evaluates it).
    plan : dict
        ``ctdrill-plan/1`` plan (JSON-ready, LPS).
    max_safe_depth_mm : float
        Exact deepest tip depth keeping 2 mm between the drill tip and the canal surface.
    noise_hu, seed, metal_streak, partial_volume : float, int, bool, int
        Generation parameters.
    """

    hu: np.ndarray
    affine_lps: np.ndarray
    canal_centerline_lps: np.ndarray
    canal_radius_mm: float
    cortical_thickness_mm: float
    misch: str
    geometry: MandibleGeometry
    plan: dict[str, Any] = field(repr=False)
    max_safe_depth_mm: float
    noise_hu: float = 0.0
    seed: int = 0
    metal_streak: bool = False
    partial_volume: int = 1

    @property
    def spacing_mm(self) -> tuple[float, float, float]:
        """(col, row, slice) voxel spacing, mm."""
        n = np.linalg.norm(self.affine_lps[:3, :3], axis=0)
        return (float(n[0]), float(n[1]), float(n[2]))

    def voxel_centres_lps(self) -> np.ndarray:
        """(slices, rows, cols, 3) LPS mm of every voxel centre."""
        return voxel_centres_lps(self.hu.shape, self.affine_lps)


# ---------------------------------------------------------------------------- generation
#: Largest grid :func:`make_mandible_phantom` builds (~200 x 200 x 200 voxels).
MAX_VOXELS = 8_000_000


def _voxelise(
    dims: tuple[int, ...],
    affine_lps: np.ndarray,
    geom: MandibleGeometry,
    sub: int,
    *,
    chunk_voxels: int = 2_000_000,
) -> np.ndarray:
    """(slices, rows, cols) float64 HU: field + streaks averaged over ``sub``^3 points a voxel.

    Computed a few slices at a time to bound memory.
    """
    n_s = dims[0]
    out = np.empty(dims, dtype=np.float64)
    offs = (np.arange(sub, dtype=np.float64) + 0.5) / sub - 0.5  # voxel units
    shifts = np.stack(np.meshgrid(offs, offs, offs, indexing="ij"), -1).reshape(-1, 3)
    lin = np.asarray(affine_lps, dtype=np.float64)[:3, :3]
    chunk = max(1, chunk_voxels // (dims[1] * dims[2]))
    for k0 in range(0, n_s, chunk):
        k1 = min(n_s, k0 + chunk)
        centres = voxel_centres_lps(dims, affine_lps, slices=(k0, k1))
        acc = np.zeros(centres.shape[:-1])
        for shift in shifts:
            pts = centres + lin @ shift
            acc += mandible_hu(pts, geom) + streak_hu(pts, geom)
        out[k0:k1] = acc / len(shifts)
    return out


def default_shape(spacing_mm: float) -> tuple[int, int, int]:
    """(slices, rows, cols) covering :data:`FOV_MM` at ``spacing_mm``."""
    return tuple(max(2, round(f / spacing_mm)) for f in FOV_MM)  # type: ignore[return-value]


def make_mandible_phantom(
    *,
    misch: str = "D2",
    spacing_mm: float = 0.4,
    shape: tuple[int, int, int] | None = None,
    noise_hu: float = 0.0,
    metal_streak: bool = False,
    seed: int = 0,
    partial_volume: int = 1,
) -> Phantom:
    """Generate the mandible phantom.

    Parameters
    ----------
    misch : str
        Trabecular bone class, ``D1`` .. ``D5`` (:data:`MISCH_CLASSES`).
    spacing_mm : float
        Isotropic voxel spacing, mm (0.1 .. 2.0).
    shape : tuple[int, int, int] | None
        (slices, rows, cols); None covers :data:`FOV_MM`. The anatomy stays centred on
        :data:`FOV_CENTRE_LPS` whatever the shape.
    noise_hu : float
        Standard deviation of additive Gaussian noise, HU (>= 0).
    metal_streak : bool
        Add a metal insert (a neighbouring implant) with its streak artefact.
    seed : int
        Seed of the noise generator.
    partial_volume : int
        Sub-samples per axis averaged into each voxel (1 .. 5): 1 samples the field at the
        voxel centre (exact values, hard edges); 3 averages 27 points, the partial-volume
        blur of a real scanner at tissue edges.

    Returns
    -------
    Phantom
        Voxels (int16), geometry, canal truth and the ``ctdrill-plan/1`` plan.
    """
    key = str(misch).upper()
    if key not in MISCH_CLASSES:
        raise PhantomInputError(
            f"misch: unknown bone class {misch!r}; use one of {', '.join(MISCH_CLASSES)}"
        )
    spacing = float(spacing_mm)
    if not (np.isfinite(spacing) and 0.1 <= spacing <= 2.0):
        raise PhantomInputError(f"spacing_mm: must be within 0.1..2.0 mm, got {spacing_mm!r}")
    noise = float(noise_hu)
    if not (np.isfinite(noise) and 0.0 <= noise <= 1000.0):
        raise PhantomInputError(f"noise_hu: must be within 0..1000 HU, got {noise_hu!r}")
    sub = int(partial_volume)
    if sub != partial_volume or not 1 <= sub <= 5:
        raise PhantomInputError(
            "partial_volume: sub-samples per axis must be a whole number 1..5, "
            f"got {partial_volume!r}"
        )
    dims = default_shape(spacing) if shape is None else tuple(int(v) for v in shape)
    if len(dims) != 3 or min(dims) < 2 or int(np.prod(dims)) > MAX_VOXELS:
        raise PhantomInputError(
            f"shape: expected (slices, rows, cols), each >= 2, at most {MAX_VOXELS:,} voxels; "
            f"got {shape!r} (use a coarser spacing_mm or a smaller shape)"
        )
    trab_hu, cort_hu, cort_t = MISCH_CLASSES[key]

    centre = np.asarray(FOV_CENTRE_LPS, dtype=np.float64)
    # Plan site on the arch: 2 mm buccal of the FOV centre so the curved body fits.
    site_x, site_y = centre[0] + 2.0, centre[1]
    arch_radius = 50.0
    insert_xy = None
    insert_z = (0.0, 0.0)
    body_z = float(centre[2])
    half_height = 11.0
    if metal_streak:
        # A neighbouring implant (4 mm wide, 10 mm long) 10 mm posterior along the arch.
        ang = 10.0 / arch_radius
        insert_xy = (
            site_x - arch_radius + arch_radius * np.cos(ang),
            site_y + arch_radius * np.sin(ang),
        )
        insert_z = (body_z + half_height - 10.0, body_z + half_height)
    geom = MandibleGeometry(
        arch_centre_xy_lps=(site_x - arch_radius, site_y),
        arch_radius_mm=arch_radius,
        body_centre_z_mm=body_z,
        half_width_mm=5.5,
        half_height_mm=half_height,
        corner_radius_mm=3.0,
        cortical_thickness_mm=cort_t,
        soft_tissue_mm=3.0,
        canal_w_mm=-3.0,
        canal_radius_mm=1.2,
        cortical_hu=cort_hu,
        trabecular_hu=trab_hu,
        metal_xy_lps=None if insert_xy is None else (float(insert_xy[0]), float(insert_xy[1])),
        metal_z_range_mm=insert_z,
    )

    affine = np.eye(4)
    affine[:3, :3] *= spacing
    half_extent = (np.array([dims[2], dims[1], dims[0]], dtype=np.float64) - 1.0) / 2.0 * spacing
    affine[:3, 3] = np.round(centre - half_extent, 6)

    field_hu = _voxelise(dims, affine, geom, sub)
    if noise > 0.0:
        field_hu = field_hu + np.random.default_rng(seed).normal(0.0, noise, size=field_hu.shape)
    hu = np.clip(np.rint(field_hu), HU_MIN, HU_MAX).astype(np.int16)

    centerline = _canal_centerline(geom, affine, dims)
    margin_mm = CLINICAL_MARGIN_MM
    max_safe = geom.half_height_mm - geom.canal_w_mm - geom.canal_radius_mm - margin_mm
    planned_depth = round(max_safe + 1.2, 6)
    entry = np.array([site_x, site_y, geom.crest_z_mm])
    target = entry - np.array([0.0, 0.0, planned_depth])
    plan: dict[str, Any] = {
        "format": "ctdrill-plan/1",
        "coordinate_system": "LPS",
        "entry_mm": [float(v) for v in entry],
        "target_mm": [float(v) for v in target],
        "drill": {"diameter_mm": 2.0, "tip_length_mm": 0.6, "blades": 2, "rpm": 900},
        "feed_mm_s": 0.4,
        "calibration": "bone-illustrative",
        "margin_mm": margin_mm,
        "landmarks": [
            {
                "name": "left mandibular canal",
                "kind": "canal",
                "points_mm": [[float(v) for v in p] for p in centerline],
                "radius_mm": geom.canal_radius_mm,
            }
        ],
        "implant": _demo_implant(planned_depth),
        "arch_mm": [[float(v) for v in p] for p in _arch_polyline(geom, affine, dims)],
    }
    return Phantom(
        hu=hu,
        affine_lps=affine,
        canal_centerline_lps=centerline,
        canal_radius_mm=geom.canal_radius_mm,
        cortical_thickness_mm=geom.cortical_thickness_mm,
        misch=key,
        geometry=geom,
        plan=plan,
        max_safe_depth_mm=float(max_safe),
        noise_hu=noise,
        seed=int(seed),
        metal_streak=bool(metal_streak),
        partial_volume=sub,
    )


#: The implant the phantom's plan places (a generic library size shorter than the planned
#: depth, so its platform sits just under the crest).
DEMO_IMPLANT = "tapered 4.1 x 11.5"
#: Arc length between two points of the phantom's arch polyline, mm.
ARCH_STEP_MM = 2.0


def _demo_implant(planned_depth_mm: float) -> dict[str, Any]:
    """The plan's ``implant`` object: :data:`DEMO_IMPLANT` from the generic library."""
    spec = next(s for s in load_implant_library() if s.name == DEMO_IMPLANT)
    if not spec.length_mm <= planned_depth_mm:
        raise PhantomInputError(
            f"the demo implant {DEMO_IMPLANT!r} is longer than the planned depth "
            f"{planned_depth_mm:g} mm"
        )
    return spec.to_json()


def _arc_angles(
    geom: MandibleGeometry, affine_lps: np.ndarray, dims: tuple[int, ...]
) -> tuple[float, float]:
    """The arch angles (rad) whose y stays inside the grid (the arch runs along y at 0)."""
    a = affine_lps
    lo = a[:3, 3]
    hi = a[:3, 3] + (np.array([dims[2], dims[1], dims[0]], dtype=np.float64) - 1.0) * np.diag(
        a[:3, :3]
    )
    cy = geom.arch_centre_xy_lps[1]
    r = geom.arch_radius_mm
    s_lo = np.clip((lo[1] - cy) / r, -1.0, 1.0)
    s_hi = np.clip((hi[1] - cy) / r, -1.0, 1.0)
    return float(np.arcsin(s_lo)), float(np.arcsin(s_hi))


def _arch_polyline(
    geom: MandibleGeometry, affine_lps: np.ndarray, dims: tuple[int, ...]
) -> np.ndarray:
    """(K, 3) the dental arch: the body's mid-line (u = 0) at mid-height (w = 0), one point
    every ~:data:`ARCH_STEP_MM` of arc over the grid's extent along the arch; a panoramic
    reformat along it shows the body from the crest to the lower border, canal included."""
    a0, a1 = _arc_angles(geom, affine_lps, dims)
    n = max(2, int(np.ceil((a1 - a0) * geom.arch_radius_mm / ARCH_STEP_MM)) + 1)
    return np.asarray(geom.arch_point_lps(np.linspace(a0, a1, n), w_mm=0.0))


def _canal_centerline(
    geom: MandibleGeometry, affine_lps: np.ndarray, dims: tuple[int, ...]
) -> np.ndarray:
    """(N, 3) canal centreline points every ~0.5 mm of arc, inside the voxel-centre hull."""
    a = affine_lps
    lo = a[:3, 3]
    hi = a[:3, 3] + (np.array([dims[2], dims[1], dims[0]], dtype=np.float64) - 1.0) * np.diag(
        a[:3, :3]
    )
    a0, a1 = _arc_angles(geom, affine_lps, dims)
    r = geom.arch_radius_mm
    n = max(2, int(np.ceil((a1 - a0) * r / 0.5)) + 1)
    pts = geom.arch_point_lps(np.linspace(a0, a1, n), w_mm=geom.canal_w_mm)
    keep = np.all((pts >= lo - 1e-9) & (pts <= hi + 1e-9), axis=1)
    return np.asarray(pts[keep])
