"""Anatomical landmarks the drill must keep clear of, in LPS millimetres.

Three kinds, one distance rule: a landmark is a *core* (segments or points) inflated by a
radius; its clearance to the drill is ``distance(drill solid, core) - radius``.

- :class:`CanalLandmark`: a centerline polyline with a radius (a union of capsules), e.g. the
  mandibular canal.
- :class:`PointLandmark`: a single point, radius 0 (a fiducial such as a root apex).
- :class:`MaskLandmark`: a labelmap on a voxel grid (e.g. a segmented canal aligned to the CT);
  its core is the set of centres of the mask's boundary voxels, so its clearance is exact to
  the voxel centres (within half a voxel diagonal of the voxelised surface).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from scipy import ndimage

from ctdrill.imaging.errors import ImagingInputError

#: Canal radius used when a plan or markup gives none, mm (a typical inferior alveolar canal
#: is 2-3 mm wide).
DEFAULT_CANAL_RADIUS_MM = 1.2


class LandmarkInputError(ImagingInputError):
    """A landmark that cannot be used (missing mask file, mask off the CT grid, ...)."""


def _frozen(array: np.ndarray) -> np.ndarray:
    out = np.array(array, copy=True)
    out.flags.writeable = False
    return out


@dataclass(frozen=True, eq=False)
class CanalLandmark:
    """A canal: centerline polyline ``points_lps`` (N, 3) LPS mm, inflated by ``radius_mm``.

    ``margin_mm`` overrides the plan's safety margin for this landmark when not None.
    """

    name: str
    points_lps: np.ndarray
    radius_mm: float = DEFAULT_CANAL_RADIUS_MM
    margin_mm: float | None = None

    def __post_init__(self) -> None:
        pts = np.asarray(self.points_lps, dtype=np.float64).reshape(-1, 3)
        object.__setattr__(self, "points_lps", _frozen(pts))

    @property
    def kind(self) -> str:
        """``"canal"``."""
        return "canal"

    def segments_lps(self) -> tuple[np.ndarray, np.ndarray]:
        """Segment end points ``(a, b)``, each (S, 3); one degenerate segment for one point."""
        pts = self.points_lps
        if len(pts) == 1:
            return pts, pts
        return pts[:-1], pts[1:]


@dataclass(frozen=True, eq=False)
class PointLandmark:
    """A point landmark at ``point_lps`` (3,) LPS mm, radius 0."""

    name: str
    point_lps: np.ndarray
    margin_mm: float | None = None

    def __post_init__(self) -> None:
        pt = np.asarray(self.point_lps, dtype=np.float64).reshape(3)
        object.__setattr__(self, "point_lps", _frozen(pt))

    @property
    def kind(self) -> str:
        """``"point"``."""
        return "point"

    @property
    def radius_mm(self) -> float:
        """Always 0: the landmark is the point itself."""
        return 0.0


@dataclass(frozen=True, eq=False)
class MaskLandmark:
    """A labelmap landmark: ``mask`` (slices, rows, cols) bool on the grid ``affine_lps``.

    ``affine_lps`` maps ``(i=col, j=row, k=slice, 1)`` to LPS mm like ``CTVolume.affine_lps``.
    ``None`` means "the CT's grid": bind it with :func:`bind_to_grid` before computing
    clearances. ``source`` is the file the mask came from (for messages and saving);
    ``label`` and ``segment`` what was taken from it (a label value, a segment's name).
    """

    name: str
    mask: np.ndarray
    affine_lps: np.ndarray | None = None
    margin_mm: float | None = None
    source: str = ""
    label: int | None = None
    segment: str | None = None

    def __post_init__(self) -> None:
        mask = np.asarray(self.mask).astype(bool, copy=False)
        if mask.ndim != 3:
            raise LandmarkInputError(
                f"mask landmark {self.name!r} ({self.source or 'array'}): expected a 3-D array "
                f"(slices, rows, cols), got shape {mask.shape}"
            )
        object.__setattr__(self, "mask", _frozen(mask))
        if self.affine_lps is not None:
            aff = np.asarray(self.affine_lps, dtype=np.float64)
            if aff.shape != (4, 4) or not np.all(np.isfinite(aff)):
                raise LandmarkInputError(
                    f"mask landmark {self.name!r}: affine_lps must be a finite 4x4 matrix"
                )
            object.__setattr__(self, "affine_lps", _frozen(aff))

    @property
    def kind(self) -> str:
        """``"mask"``."""
        return "mask"

    @property
    def radius_mm(self) -> float:
        """Always 0: the core is the mask's boundary voxel centres."""
        return 0.0

    def surface_points_lps(self) -> np.ndarray:
        """Centres of the mask's boundary voxels (6-connected erosion), (P, 3) LPS mm."""
        if self.affine_lps is None:
            raise LandmarkInputError(
                f"mask landmark {self.name!r}: no grid; bind it to the CT with bind_to_grid()"
            )
        boundary = self.mask & ~ndimage.binary_erosion(self.mask, border_value=0)
        kji = np.argwhere(boundary).astype(np.float64)
        ijk1 = np.column_stack([kji[:, 2], kji[:, 1], kji[:, 0], np.ones(len(kji))])
        pts: np.ndarray = (ijk1 @ self.affine_lps.T)[:, :3]
        return pts


Landmark = CanalLandmark | PointLandmark | MaskLandmark


def landmark_core(landmark: Landmark) -> tuple[np.ndarray, np.ndarray, float]:
    """The landmark's core as segments ``(a, b)`` (S, 3) LPS mm and its radius, mm.

    Points and mask voxel centres are degenerate segments (``a == b``).
    """
    if isinstance(landmark, CanalLandmark):
        a, b = landmark.segments_lps()
        return a, b, float(landmark.radius_mm)
    if isinstance(landmark, PointLandmark):
        pt = landmark.point_lps[None, :]
        return pt, pt, 0.0
    pts = landmark.surface_points_lps()
    return pts, pts, 0.0


def load_mask_file(path: Path, *, label: int | None = None) -> np.ndarray:
    """Read a labelmap ``.npy`` (slices, rows, cols) as a bool mask.

    ``label`` selects one label value; ``None`` takes every non-zero voxel. The file is
    checked (regular, bounded, an NPY header whose size fits) before the array is allocated
    (:func:`ctdrill.imaging.plan.segmentation.read_npy`); other formats are read by
    :func:`ctdrill.imaging.plan.segmentation.mask_landmark`.
    """
    if path.suffix.lower() != ".npy":
        raise LandmarkInputError(
            f"{path}: mask landmarks are read from NumPy .npy labelmaps on the CT grid "
            "(slices, rows, cols); convert the segmentation to .npy"
        )
    from ctdrill.imaging.plan.segmentation import read_npy

    arr = read_npy(path)
    if arr.ndim != 3:
        raise LandmarkInputError(
            f"{path}: expected a 3-D labelmap (slices, rows, cols), got shape {arr.shape}"
        )
    if not (np.issubdtype(arr.dtype, np.integer) or arr.dtype == np.bool_):
        raise LandmarkInputError(f"{path}: labelmap must be integer or bool, got {arr.dtype}")
    mask: np.ndarray = arr != 0 if label is None else arr == label
    if not mask.any():
        raise LandmarkInputError(
            f"{path}: the mask is empty" + ("" if label is None else f" for label {label}")
        )
    return mask


def bind_to_grid(
    landmarks: tuple[Landmark, ...], affine_lps: np.ndarray, shape: tuple[int, ...]
) -> tuple[Landmark, ...]:
    """Give grid-less mask landmarks the CT's grid; check that their shape matches it.

    Parameters
    ----------
    landmarks : the plan's landmarks.
    affine_lps : (4, 4) the CT's voxel-to-LPS affine.
    shape : the CT's (slices, rows, cols).
    """
    out: list[Landmark] = []
    for lm in landmarks:
        if isinstance(lm, MaskLandmark) and lm.affine_lps is None:
            if tuple(lm.mask.shape) != tuple(shape):
                raise LandmarkInputError(
                    f"mask landmark {lm.name!r} ({lm.source or 'array'}): shape "
                    f"{tuple(lm.mask.shape)} does not match the CT grid {tuple(shape)} "
                    "(slices, rows, cols); resample the mask onto the CT or give its affine_lps"
                )
            lm = replace(lm, affine_lps=affine_lps)
        out.append(lm)
    return tuple(out)
