"""A CT synthesised inside a real mandible's shape (``../shared/data/tcia_mandible_masks``).

The four masks are real mandible segmentations of head-and-neck planning CTs, without their CT
(tests/data/README.md). :func:`real_mandible` turns one into a test case with real anatomy and
known numbers, for tests of the arch, the bone walls, the panoramic and the suggestions:

1. the mask is read by ctdrill's own NRRD reader (LPS, 0.97-1.11 mm x 2.5 mm), cropped to the
   bone plus :data:`MARGIN_MM`, and resampled to an isotropic grid of ``voxel_mm`` by trilinear
   interpolation of the 0/1 mask, kept where >= 0.5 (smooths the 2.5 mm slice steps);
2. HU from the distance to the bone's surface (scipy's exact Euclidean distance transform):
   cortical bone within ``cortical_mm`` of the surface, trabecular deeper (both from the
   phantom's Misch classes, :data:`ctdrill.imaging.phantom.classes.MISCH_CLASSES`), soft
   tissue within :data:`SOFT_TISSUE_MM` outside, air beyond; Gaussian noise of ``noise_hu``;
3. the dental arch: a parabola ``y(x)`` fitted (least squares) to the bone voxels of the body,
   at the body's mid-height, over the body's width (the rami left out);
4. two mandibular canals, one per side: from the mental foramen (:data:`MENTAL_ARC_MM` of arc
   from the midline) back along the arch to the end of the body, each point at
   :data:`CANAL_HEIGHT` of the body's height above its inferior border and half-way across the
   bone there; carved as a tube of ``canal_radius_mm`` holding :data:`CANAL_HU`, every centre
   point at least ``canal_radius_mm + 1`` mm inside the bone (checked).

Everything is deterministic for a given case and arguments (``seed``), and built once per
process (``functools.cache``): about 1-2 s at the default 0.75 mm.
"""

from __future__ import annotations

import functools
import itertools
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import ndimage

from ctdrill.imaging.phantom.classes import MISCH_CLASSES
from ctdrill.imaging.phantom.field import AIR_HU, CANAL_HU, SOFT_TISSUE_HU
from ctdrill.imaging.plan.landmarks import LandmarkInputError
from ctdrill.imaging.volume import CTVolume, SeriesInfo
from ctdrill.imaging.volumes.nrrd_file import read_nrrd
from tests.conftest import SHARED_DATA

MASKS = SHARED_DATA / "tcia_mandible_masks"
CASES = ("0522c0251", "0522c0427", "0522c0669", "TCGA-CV-A6JY")
#: Bone kept around the crop, mm.
MARGIN_MM = 14.0
#: Soft tissue around the bone, mm (air beyond).
SOFT_TISSUE_MM = 10.0
#: Arc length from the arch's midline to the mental foramen, mm (about the premolars).
MENTAL_ARC_MM = 22.0
#: Height of the canal above the body's inferior border, as a fraction of the body's height.
CANAL_HEIGHT = 0.35


@dataclass(frozen=True, eq=False)
class RealMandible:
    """A synthetic CT in a real mandible's shape, and its known anatomy (LPS mm).

    Attributes
    ----------
    case : the mask's id in ``tcia_mandible_masks``.
    volume : the CT (HU int16, isotropic ``voxel_mm``).
    bone : (k, j, i) bool, the mandible on the volume's grid.
    depth_mm : (k, j, i) float32, distance inside the bone to its surface (0 outside).
    arch_lps : (K, 3) the dental arch (the body's mid-line at mid-height), patient right first.
    canals_lps : the right and left canal centrelines, each (C, 3), mental foramen first.
    canal_radius_mm : the canals' radius.
    trabecular_hu, cortical_hu, cortical_mm : the bone's values.
    """

    case: str
    volume: CTVolume
    bone: np.ndarray
    depth_mm: np.ndarray
    arch_lps: np.ndarray
    canals_lps: tuple[np.ndarray, np.ndarray]
    canal_radius_mm: float
    trabecular_hu: float
    cortical_hu: float
    cortical_mm: float


def _resampled_mask(path: Path, voxel_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """The mask on an isotropic axis-aligned grid around the bone: (bone kji, affine_lps)."""
    vol = read_nrrd(path, max_bytes=1 << 30, error=LandmarkInputError)
    src = vol.data.astype(np.float32)
    a = vol.affine_lps
    kji = np.argwhere(src > 0)
    ijk_lo, ijk_hi = kji.min(0)[::-1], kji.max(0)[::-1]
    lo = a[:3, :3] @ ijk_lo + a[:3, 3]
    hi = a[:3, :3] @ ijk_hi + a[:3, 3]
    lo, hi = np.minimum(lo, hi) - MARGIN_MM, np.maximum(lo, hi) + MARGIN_MM
    n = np.ceil((hi - lo) / voxel_mm).astype(int) + 1
    affine = np.eye(4)
    affine[:3, :3] = np.eye(3) * voxel_mm
    affine[:3, 3] = lo
    step = np.diag(a[:3, :3])
    assert np.allclose(a[:3, :3], np.diag(step)), "the TCIA masks are axis-aligned"
    # output (k, j, i) -> source (k, j, i): a diagonal map, in the kji order of the arrays
    occupancy = ndimage.affine_transform(
        src,
        (voxel_mm / step)[::-1],
        offset=((lo - a[:3, 3]) / step)[::-1],
        output_shape=(int(n[2]), int(n[1]), int(n[0])),
        order=1,
        mode="constant",
    )
    return occupancy >= 0.5, affine


def _arch(bone: np.ndarray, affine: np.ndarray, voxel_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """Arch polyline (K, 3) at the body's mid-height and the body's (lo, hi) z per arch point."""
    k, j, i = np.nonzero(bone)
    x, y, z = (np.stack([i, j, k], 1) * voxel_mm + affine[:3, 3]).T
    # The body: bone below the middle of the bone's height (the rami rise above it).
    z_mid = z.min() + 0.5 * (np.percentile(z, 95) - z.min())
    body = z <= z_mid
    coef = np.polyfit(x[body], y[body], 2)
    xs = np.linspace(np.percentile(x[body], 2), np.percentile(x[body], 98), 41)
    ys = np.polyval(coef, xs)
    z_lo = np.empty(xs.size)
    z_hi = np.empty(xs.size)
    for n, (px, py) in enumerate(zip(xs, ys, strict=True)):
        near = body & (np.abs(x - px) <= 2 * voxel_mm) & (np.abs(y - py) <= 4.0)
        zz = z[near] if near.any() else z[body]
        z_lo[n], z_hi[n] = zz.min(), zz.max()
    mid = 0.5 * (z_lo + z_hi)
    order = np.argsort(xs)  # LPS x grows to the patient's left: right first
    arch = np.stack([xs, ys, np.full(xs.size, float(np.median(mid)))], 1)[order]
    return arch, np.stack([z_lo, z_hi], 1)[order]


def _canal(
    arch: np.ndarray,
    heights: np.ndarray,
    depth: np.ndarray,
    affine: np.ndarray,
    side: int,
    radius_mm: float,
    voxel_mm: float,
) -> np.ndarray:
    """One side's canal: from the mental foramen back to the body's end (``side`` -1 right)."""
    seg = np.linalg.norm(np.diff(arch[:, :2], axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    s_mid = s[np.argmin(np.abs(arch[:, 0] - np.median(arch[:, 0])))]
    inv = np.linalg.inv(affine)
    points = []
    idx = np.flatnonzero(side * (s - s_mid) >= MENTAL_ARC_MM)
    for n in idx[::side] if side < 0 else idx:
        z_lo, z_hi = heights[n]
        p = np.array([arch[n, 0], arch[n, 1], z_lo + CANAL_HEIGHT * (z_hi - z_lo)])
        tangent = arch[min(n + 1, len(arch) - 1), :2] - arch[max(n - 1, 0), :2]
        normal = np.array([-tangent[1], tangent[0], 0.0]) / np.linalg.norm(tangent)
        across = p + np.outer(np.arange(-15.0, 15.0, voxel_mm / 2), normal)
        ijk = across @ inv[:3, :3].T + inv[:3, 3]
        d = ndimage.map_coordinates(depth, ijk[:, ::-1].T, order=1, mode="constant")
        if d.max() < radius_mm + 1.0:
            continue  # the body is too thin here for a canal
        inside = np.flatnonzero(d >= radius_mm + 1.0)
        runs = np.split(inside, np.flatnonzero(np.diff(inside) > 1) + 1)
        best = max(runs, key=lambda r: d[r].max())
        points.append(across[best[len(best) // 2]])
    return np.asarray(points)


def _tube(
    shape: tuple[int, ...], affine: np.ndarray, line: np.ndarray, radius_mm: float
) -> np.ndarray:
    """(k, j, i) bool: voxel centres within ``radius_mm`` of the polyline (axis-aligned grid)."""
    out = np.zeros(shape, dtype=bool)
    step, origin = np.diag(affine[:3, :3]), affine[:3, 3]
    top = np.array(shape[::-1]) - 1
    for a, b in itertools.pairwise(line):
        lo = np.clip(np.floor((np.minimum(a, b) - radius_mm - origin) / step), 0, top).astype(int)
        hi = np.clip(np.ceil((np.maximum(a, b) + radius_mm - origin) / step), 0, top).astype(int)
        k, j, i = np.meshgrid(*(np.arange(lo[n], hi[n] + 1) for n in (2, 1, 0)), indexing="ij")
        pts = np.stack([i, j, k], -1) * step + origin
        ab = b - a
        t = np.clip(((pts - a) @ ab) / (ab @ ab), 0.0, 1.0)
        near = np.linalg.norm(pts - (a + t[..., None] * ab), axis=-1) <= radius_mm
        out[lo[2] : hi[2] + 1, lo[1] : hi[1] + 1, lo[0] : hi[0] + 1] |= near
    return out


@functools.cache
def real_mandible(
    case: str = CASES[0],
    *,
    voxel_mm: float = 0.75,
    misch: str = "D3",
    canal_radius_mm: float = 1.2,
    noise_hu: float = 20.0,
    seed: int = 0,
) -> RealMandible:
    """The synthetic CT of ``case`` (module docstring); built once per arguments."""
    bone, affine = _resampled_mask(MASKS / case / "Mandible.nrrd", voxel_mm)
    trabecular, cortical, cortical_mm = MISCH_CLASSES[misch]
    depth = ndimage.distance_transform_edt(bone, sampling=voxel_mm).astype(np.float32)
    outside = ndimage.distance_transform_edt(~bone, sampling=voxel_mm)
    hu = np.where(outside <= SOFT_TISSUE_MM, SOFT_TISSUE_HU, AIR_HU)
    hu = np.where(bone, np.where(depth <= cortical_mm, cortical, trabecular), hu)
    arch, heights = _arch(bone, affine, voxel_mm)
    canals = tuple(
        _canal(arch, heights, depth, affine, side, canal_radius_mm, voxel_mm) for side in (-1, 1)
    )
    for line in canals:
        assert len(line) >= 5, f"{case}: no room for a canal"
        hu = np.where(_tube(bone.shape, affine, line, canal_radius_mm), CANAL_HU, hu)
    rng = np.random.default_rng(seed)
    hu = hu + rng.normal(0.0, noise_hu, hu.shape) if noise_hu else hu
    volume = CTVolume(
        hu=np.rint(hu).astype(np.int16),
        affine_lps=affine,
        valid=None,
        info=SeriesInfo(series_uid=f"tcia-mandible-{case}-{voxel_mm:g}mm", modality="CT"),
    )
    return RealMandible(
        case=case,
        volume=volume,
        bone=bone,
        depth_mm=depth,
        arch_lps=arch,
        canals_lps=(canals[0], canals[1]),
        canal_radius_mm=canal_radius_mm,
        trabecular_hu=trabecular,
        cortical_hu=cortical,
        cortical_mm=cortical_mm,
    )
