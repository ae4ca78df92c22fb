"""The analytic field of the mandible phantom: geometry, tissue labels, HU, streak artefact.

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
canal_w)``), under the crest. The metal streak artefact (:func:`streak_hu`) is an additive
field of its own; :mod:`ctdrill.imaging.phantom.mandible` samples both on a voxel grid.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ctdrill.hu import AIR_HU as AIR_HU
from ctdrill.imaging.phantom.classes import MISCH_CLASSES as MISCH_CLASSES

SOFT_TISSUE_HU = 40.0
CANAL_HU = 30.0
METAL_HU = 3071.0
#: Range of 12-bit CT numbers stored unsigned with rescale intercept -1024.
HU_MIN, HU_MAX = -1024.0, 3071.0

#: Labels of :func:`mandible_labels`.
LABELS: dict[str, int] = {
    "air": 0,
    "soft_tissue": 1,
    "cortical": 2,
    "trabecular": 3,
    "canal": 4,
    "metal": 5,
}


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


def voxel_centres_lps(
    shape: tuple[int, ...], affine_lps: np.ndarray, *, slices: tuple[int, int] | None = None
) -> np.ndarray:
    """(slices, rows, cols, 3) LPS mm of the voxel centres of a grid (or of slices k0..k1-1)."""
    n_s, n_r, n_c = (int(v) for v in shape)
    k0, k1 = (0, n_s) if slices is None else slices
    k, j, i = np.meshgrid(
        np.arange(k0, k1, dtype=np.float64),
        np.arange(n_r, dtype=np.float64),
        np.arange(n_c, dtype=np.float64),
        indexing="ij",
    )
    a = np.asarray(affine_lps, dtype=np.float64)
    ijk = np.stack([i, j, k], axis=-1)
    return np.asarray(ijk @ a[:3, :3].T + a[:3, 3])
