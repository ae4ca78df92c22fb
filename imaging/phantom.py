"""A synthetic mandible phantom defined analytically, so tests know the exact answers.

Geometry (LPS mm). The mandibular body is a rounded-rectangle cross-section swept along a
circular arch in the axial plane: for a point ``p`` the body coordinates are

- ``u = |p_xy - arch_centre_xy| - arch_radius`` (bucco-lingual offset, > 0 buccal), and
- ``w = p_z - body_centre_z`` (vertical offset, > 0 towards the alveolar crest).

In the ``(u, w)`` plane the bone outline is the rounded box of half-width ``half_width_mm``,
half-height ``half_height_mm`` and corner radius ``corner_radius_mm``; its exact signed distance
``d`` (< 0 inside) orders the layers:

==========================  ==========================================
region                      HU
==========================  ==========================================
``d > soft_tissue_mm``      air (-1000)
``0 < d <= soft_tissue_mm`` gingiva / soft tissue (40)
``-t_c <= d <= 0``          cortical shell (Misch-class dependent)
``d < -t_c``                trabecular bone (Misch-class dependent)
canal tube                  ``hypot(u, w - canal_w_mm) <= canal_radius_mm``: 30
metal insert (optional)     vertical cylinder, 3071
==========================  ==========================================

The canal centreline is the circle ``u = 0, w = canal_w_mm`` (exact distance ``hypot(u, w -
canal_w)``), under the crest. Voxel values are the analytic field at the voxel centres,
plus the optional metal streak artefact and Gaussian noise, rounded and clipped to the
12-bit CT range [-1024, 3071]. The plan: entry on the crest straight above the canal, drilling
straight down deeper than the 2 mm margin allows (``max_safe_depth_mm`` below).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from imaging.errors import ImagingInputError

#: Misch class -> (trabecular HU, cortical HU, cortical thickness mm). Trabecular values sit
#: inside each class's HU band (D1 > 1250, D2 850-1250, D3 350-850, D4 150-350, D5 < 150).
MISCH_CLASSES: dict[str, tuple[float, float, float]] = {
    "D1": (1400.0, 1800.0, 2.0),
    "D2": (1050.0, 1700.0, 2.0),
    "D3": (600.0, 1600.0, 1.6),
    "D4": (250.0, 1500.0, 1.5),
    "D5": (100.0, 1500.0, 1.5),
}

AIR_HU = -1000.0
SOFT_TISSUE_HU = 40.0
CANAL_HU = 30.0
METAL_HU = 3071.0
#: Range of 12-bit CT numbers stored unsigned with rescale intercept -1024.
HU_MIN, HU_MAX = -1024.0, 3071.0

#: Default field of view, mm, as (slices: S-I, rows: A-P, cols: R-L).
FOV_MM = (32.0, 40.0, 32.0)
#: LPS centre of the field of view, mm (a left posterior mandible segment).
FOV_CENTRE_LPS = (30.0, 10.0, -40.0)

#: Labels of :func:`mandible_labels`.
LABELS: dict[str, int] = {
    "air": 0,
    "soft_tissue": 1,
    "cortical": 2,
    "trabecular": 3,
    "canal": 4,
    "metal": 5,
}


class PhantomInputError(ImagingInputError):
    """Bad phantom parameter."""


@dataclass(frozen=True)
class MandibleGeometry:
    """Analytic description of the phantom (all lengths mm, LPS, HU values).

    Attributes
    ----------
    arch_centre_xy_lps : tuple[float, float]
        Centre of the arch circle in the axial plane (x, y), mm.
    arch_radius_mm : float
        Radius of the arch (the body's mid-line), mm.
    body_centre_z_mm : float
        LPS z of the body's vertical centre, mm.
    half_width_mm, half_height_mm, corner_radius_mm : float
        Rounded-box cross-section of the bone, mm.
    cortical_thickness_mm : float
        Cortical shell thickness, mm.
    soft_tissue_mm : float
        Soft-tissue envelope thickness over the bone, mm.
    canal_w_mm, canal_radius_mm : float
        Canal centreline height above the body centre, and canal radius, mm.
    cortical_hu, trabecular_hu : float
        Bone HU for the Misch class.
    metal_xy_lps : tuple[float, float] | None
        Axis of the metal insert (vertical cylinder) in the axial plane, or None.
    metal_radius_mm : float
        Insert radius, mm.
    metal_z_range_mm : tuple[float, float]
        LPS z extent of the insert, mm.
    streak_amplitude_hu, streak_lobes : float, int
        Streak artefact ``a cos(lobes phi) (r_metal / r)`` in the insert's slices.
    """

    arch_centre_xy_lps: tuple[float, float]
    arch_radius_mm: float
    body_centre_z_mm: float
    half_width_mm: float
    half_height_mm: float
    corner_radius_mm: float
    cortical_thickness_mm: float
    soft_tissue_mm: float
    canal_w_mm: float
    canal_radius_mm: float
    cortical_hu: float
    trabecular_hu: float
    metal_xy_lps: tuple[float, float] | None = None
    metal_radius_mm: float = 2.0
    metal_z_range_mm: tuple[float, float] = (0.0, 0.0)
    streak_amplitude_hu: float = 400.0
    streak_lobes: int = 3

    @property
    def crest_z_mm(self) -> float:
        """LPS z of the alveolar crest (top of the bone), mm."""
        return self.body_centre_z_mm + self.half_height_mm

    def arch_point_lps(self, angle_rad: np.ndarray, *, w_mm: float = 0.0) -> np.ndarray:
        """(..., 3) LPS points on the arch mid-line (u = 0) at height ``w_mm``."""
        a = np.asarray(angle_rad, dtype=np.float64)
        cx, cy = self.arch_centre_xy_lps
        z = np.full_like(a, self.body_centre_z_mm + w_mm)
        return np.stack(
            [cx + self.arch_radius_mm * np.cos(a), cy + self.arch_radius_mm * np.sin(a), z], -1
        )


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
    noise_hu, seed, metal_streak : float, int, bool
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

    @property
    def spacing_mm(self) -> tuple[float, float, float]:
        """(col, row, slice) voxel spacing, mm."""
        n = np.linalg.norm(self.affine_lps[:3, :3], axis=0)
        return (float(n[0]), float(n[1]), float(n[2]))

    def voxel_centres_lps(self) -> np.ndarray:
        """(slices, rows, cols, 3) LPS mm of every voxel centre."""
        return voxel_centres_lps(self.hu.shape, self.affine_lps)


# ---------------------------------------------------------------------------- analytic field
def body_coords(points_lps: np.ndarray, geom: MandibleGeometry) -> tuple[np.ndarray, np.ndarray]:
    """(u, w) body coordinates of LPS points (..., 3): bucco-lingual and vertical offsets, mm."""
    p = np.asarray(points_lps, dtype=np.float64)
    cx, cy = geom.arch_centre_xy_lps
    u = np.hypot(p[..., 0] - cx, p[..., 1] - cy) - geom.arch_radius_mm
    w = p[..., 2] - geom.body_centre_z_mm
    return u, w


def bone_sdf_mm(u: np.ndarray, w: np.ndarray, geom: MandibleGeometry) -> np.ndarray:
    """Exact signed distance (mm, < 0 inside) to the rounded-box bone outline in (u, w)."""
    rc = geom.corner_radius_mm
    qx = np.abs(u) - (geom.half_width_mm - rc)
    qy = np.abs(w) - (geom.half_height_mm - rc)
    outside = np.hypot(np.maximum(qx, 0.0), np.maximum(qy, 0.0))
    inside = np.minimum(np.maximum(qx, qy), 0.0)
    return np.asarray(outside + inside - rc)


def canal_distance_mm(u: np.ndarray, w: np.ndarray, geom: MandibleGeometry) -> np.ndarray:
    """Exact distance (mm) to the canal centreline circle."""
    return np.asarray(np.hypot(u, w - geom.canal_w_mm))


def mandible_labels(points_lps: np.ndarray, geom: MandibleGeometry) -> np.ndarray:
    """(...) int8 tissue label (:data:`LABELS`) at LPS points (..., 3)."""
    p = np.asarray(points_lps, dtype=np.float64)
    u, w = body_coords(p, geom)
    d = bone_sdf_mm(u, w, geom)
    lab = np.full(d.shape, LABELS["air"], dtype=np.int8)
    lab[d <= geom.soft_tissue_mm] = LABELS["soft_tissue"]
    lab[d <= 0.0] = LABELS["cortical"]
    lab[d < -geom.cortical_thickness_mm] = LABELS["trabecular"]
    lab[(canal_distance_mm(u, w, geom) <= geom.canal_radius_mm) & (d < 0.0)] = LABELS["canal"]
    if geom.metal_xy_lps is not None:
        mx, my = geom.metal_xy_lps
        z0, z1 = geom.metal_z_range_mm
        in_metal = (np.hypot(p[..., 0] - mx, p[..., 1] - my) <= geom.metal_radius_mm) & (
            (p[..., 2] >= z0) & (p[..., 2] <= z1)
        )
        lab[in_metal] = LABELS["metal"]
    return lab


def label_hu(geom: MandibleGeometry) -> np.ndarray:
    """(6,) HU of each label of :data:`LABELS`, in label order."""
    return np.array(
        [AIR_HU, SOFT_TISSUE_HU, geom.cortical_hu, geom.trabecular_hu, CANAL_HU, METAL_HU]
    )


def mandible_hu(points_lps: np.ndarray, geom: MandibleGeometry) -> np.ndarray:
    """Noise- and artefact-free HU (float64) of the phantom at LPS points (..., 3)."""
    return np.asarray(label_hu(geom)[mandible_labels(points_lps, geom)])


def streak_hu(points_lps: np.ndarray, geom: MandibleGeometry) -> np.ndarray:
    """Metal streak artefact (HU, float64) at LPS points (..., 3); 0 without an insert.

    In the axial slices crossing the insert, ``a cos(lobes phi) min(1, r_metal / r)`` with
    ``phi`` the angle around the insert's axis from +x and ``r`` the distance to it: bright and
    dark streaks radiating from the insert, fading as 1/r. Zero inside the insert.
    """
    p = np.asarray(points_lps, dtype=np.float64)
    if geom.metal_xy_lps is None:
        return np.zeros(p.shape[:-1])
    mx, my = geom.metal_xy_lps
    dx, dy = p[..., 0] - mx, p[..., 1] - my
    r = np.hypot(dx, dy)
    z0, z1 = geom.metal_z_range_mm
    in_slices = (p[..., 2] >= z0) & (p[..., 2] <= z1)
    phi = np.arctan2(dy, dx)
    amp = geom.streak_amplitude_hu * np.cos(geom.streak_lobes * phi)
    with np.errstate(divide="ignore"):
        fade = np.where(r > geom.metal_radius_mm, geom.metal_radius_mm / r, 0.0)
    return np.asarray(np.where(in_slices, amp * fade, 0.0))


def voxel_centres_lps(shape: tuple[int, ...], affine_lps: np.ndarray) -> np.ndarray:
    """(slices, rows, cols, 3) LPS mm of the voxel centres of a grid."""
    n_s, n_r, n_c = (int(v) for v in shape)
    k, j, i = np.meshgrid(
        np.arange(n_s, dtype=np.float64),
        np.arange(n_r, dtype=np.float64),
        np.arange(n_c, dtype=np.float64),
        indexing="ij",
    )
    a = np.asarray(affine_lps, dtype=np.float64)
    ijk = np.stack([i, j, k], axis=-1)
    return np.asarray(ijk @ a[:3, :3].T + a[:3, 3])


# ---------------------------------------------------------------------------- generation
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
    dims = default_shape(spacing) if shape is None else tuple(int(v) for v in shape)
    if len(dims) != 3 or min(dims) < 2 or int(np.prod(dims)) > 64_000_000:
        raise PhantomInputError(
            f"shape: expected (slices, rows, cols), each >= 2, at most 64 M voxels; got {shape!r}"
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

    centres = voxel_centres_lps(dims, affine)
    field_hu = mandible_hu(centres, geom) + streak_hu(centres, geom)
    if noise > 0.0:
        field_hu = field_hu + np.random.default_rng(seed).normal(0.0, noise, size=field_hu.shape)
    hu = np.clip(np.rint(field_hu), HU_MIN, HU_MAX).astype(np.int16)

    centerline = _canal_centerline(geom, affine, dims)
    margin_mm = 2.0
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
    )


def _canal_centerline(
    geom: MandibleGeometry, affine_lps: np.ndarray, dims: tuple[int, ...]
) -> np.ndarray:
    """(N, 3) canal centreline points every ~0.5 mm of arc, inside the voxel-centre hull."""
    a = affine_lps
    lo = a[:3, 3]
    hi = a[:3, 3] + (np.array([dims[2], dims[1], dims[0]], dtype=np.float64) - 1.0) * np.diag(
        a[:3, :3]
    )
    # Arc angles whose y stays inside the grid (the arch runs along y at angle 0).
    cy = geom.arch_centre_xy_lps[1]
    r = geom.arch_radius_mm
    s_lo = np.clip((lo[1] - cy) / r, -1.0, 1.0)
    s_hi = np.clip((hi[1] - cy) / r, -1.0, 1.0)
    a0, a1 = float(np.arcsin(s_lo)), float(np.arcsin(s_hi))
    n = max(2, int(np.ceil((a1 - a0) * r / 0.5)) + 1)
    pts = geom.arch_point_lps(np.linspace(a0, a1, n), w_mm=geom.canal_w_mm)
    keep = np.all((pts >= lo - 1e-9) & (pts <= hi + 1e-9), axis=1)
    return np.asarray(pts[keep])
