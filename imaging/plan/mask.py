"""Labelmap landmarks: each labelled voxel a box of anatomy, measured exactly on any grid.

Part of the landmark kinds (:mod:`ctdrill.imaging.plan.landmarks` re-exports
:class:`MaskLandmark`); the exact distance to the voxel union is
:mod:`ctdrill.imaging.plan.voxels`. Mask files are read by :mod:`ctdrill.imaging.plan.segmentation`
(above the landmark kinds: a value type reads no file).
"""

from __future__ import annotations

import itertools
import os
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ctdrill.imaging.plan.distance import AxialSolid, segments_distance_mm
from ctdrill.imaging.plan.landmark_base import (
    MAX_DRAWN_SURFACE_POINTS,
    NO_POINTS,
    Landmark,
    LandmarkDrawing,
    LandmarkInputError,
    frozen_array,
    margin_item,
)
from ctdrill.imaging.plan.voxels import exposed_face_centres, voxel_union_segments

#: Axis orders a ``.npy`` labelmap may be stated in (plan key ``axes``): slices, rows, cols
#: (ctdrill's and SimpleITK's arrays) or cols, rows, slices (nibabel's ``get_fdata``).
AXES_KJI = "kji"
AXES_IJK = "ijk"
AXES = (AXES_KJI, AXES_IJK)


def _other_orders(shape: tuple[int, ...]) -> set[tuple[int, ...]]:
    """Shapes an array of the grid ``shape`` would have if its axes were stated in another
    order, when that other order gives the same shape (the grid has two equal sizes)."""
    out = set()
    for perm in itertools.permutations(range(len(shape))):
        if perm != tuple(range(len(shape))) and tuple(shape[p] for p in perm) == shape:
            out.add(shape)
    return out


@dataclass(frozen=True, eq=False)
class MaskLandmark:
    """A labelmap landmark: ``mask`` (slices, rows, cols) bool on the grid ``affine_lps``.

    ``affine_lps`` maps ``(i=col, j=row, k=slice, 1)`` to LPS mm like ``CTVolume.affine_lps``
    (oblique and sheared grids included; it must be invertible). ``None`` means "the CT's
    grid": bind it with :func:`bind_to_grid` before computing clearances. ``source`` is the
    file the mask came from (for messages and saving); ``label`` and ``segment`` what was
    taken from it (a label value, a segment's name). Each labelled voxel is the box
    ``affine @ ([i, j, k] + [-1/2, 1/2]^3)``.

    ``frame_of_reference_uid`` is the DICOM Frame of Reference its coordinates are in (a DICOM
    SEG's), None when the file carries none: a CT of another frame is refused
    (:func:`ctdrill.imaging.sampling.path.require_grid_for_masks`).

    ``axes`` is the order the array's axes were stated in: :data:`AXES_KJI` (slices, rows,
    cols: an array built in ctdrill's order, the default) or None (a ``.npy`` labelmap whose
    plan entry states no order: the file carries none). A mask of unknown order binds to a CT
    grid only where no other axis order would fit that grid too (:meth:`on_grid`).
    """

    name: str
    mask: np.ndarray
    affine_lps: np.ndarray | None = None
    margin_mm: float | None = None
    source: str = ""
    label: int | None = None
    segment: str | None = None
    axes: str | None = "kji"
    frame_of_reference_uid: str | None = None
    _segments: dict[bytes, tuple[np.ndarray, np.ndarray]] = field(
        init=False, repr=False, default_factory=dict
    )

    def __post_init__(self) -> None:
        mask = np.asarray(self.mask).astype(bool, copy=False)
        if mask.ndim != 3:
            raise LandmarkInputError(
                f"mask landmark {self.name!r} ({self.source or 'array'}): expected a 3-D array "
                f"(slices, rows, cols), got shape {mask.shape}"
            )
        object.__setattr__(self, "mask", frozen_array(mask))
        if self.affine_lps is not None:
            aff = np.asarray(self.affine_lps, dtype=np.float64)
            if aff.shape != (4, 4) or not np.all(np.isfinite(aff)):
                raise LandmarkInputError(
                    f"mask landmark {self.name!r}: affine_lps must be a finite 4x4 matrix"
                )
            lin = aff[:3, :3]
            if abs(np.linalg.det(lin)) <= 1e-12 * float(np.abs(lin).max()) ** 3:
                raise LandmarkInputError(
                    f"mask landmark {self.name!r}: affine_lps is singular (its voxels have no "
                    "volume); give the grid's real voxel axes"
                )
            object.__setattr__(self, "affine_lps", frozen_array(aff))

    @property
    def kind(self) -> str:
        """``"mask"``."""
        return "mask"

    @property
    def radius_mm(self) -> float:
        """Always 0: the landmark is the union of its voxel boxes."""
        return 0.0

    def _grid(self) -> np.ndarray:
        if self.affine_lps is None:
            raise LandmarkInputError(
                f"mask landmark {self.name!r}: no grid; bind it to the CT with bind_to_grid()"
            )
        return self.affine_lps

    def clearance_mm(self, solid: AxialSolid, depth_mm: np.ndarray) -> np.ndarray:
        """Exact signed distance from the solid to the union of the voxel boxes, mm."""
        affine = self._grid()
        key = np.concatenate([solid.entry_lps, solid.direction]).tobytes()
        if key not in self._segments:
            self._segments.clear()
            self._segments[key] = voxel_union_segments(self.mask, affine, solid)
        a, b = self._segments[key]
        return segments_distance_mm(a, b, depth_mm, solid)

    def surface_points_lps(self) -> np.ndarray:
        """Centres of the exposed voxel faces (on the union's surface), (P, 3) LPS mm."""
        affine = self._grid()
        parts = [c for _, c in exposed_face_centres(self.mask)]
        ijk = np.concatenate(parts) if parts else np.empty((0, 3))
        pts: np.ndarray = ijk @ affine[:3, :3].T + affine[:3, 3]
        return pts

    def drawing(self) -> LandmarkDrawing:
        """A cloud of surface points (none while the mask has no grid)."""
        if self.affine_lps is None:
            return LandmarkDrawing()
        pts = self.surface_points_lps()
        return LandmarkDrawing(
            surface_lps=pts[:: max(1, len(pts) // MAX_DRAWN_SURFACE_POINTS)], radius_mm=0.0
        )

    def to_plan_item(self, out_dir: str | os.PathLike[str] | None = None) -> dict[str, Any]:
        """``{"kind": "mask", "path"[, "label"][, "segment"][, "affine_lps"]}``: the path
        relative to ``out_dir`` when given, else as read; ``affine_lps`` only for a ``.npy``
        (other files carry their own geometry). Needs the file it came from."""
        if not self.source:
            raise LandmarkInputError(
                f"mask landmark {self.name!r} has no file to refer to; save the mask as .npy "
                "and set its source"
            )
        path = (
            self.source
            if out_dir is None
            else os.path.relpath(os.path.abspath(self.source), os.path.abspath(out_dir))
        )
        item: dict[str, Any] = {"name": self.name, "kind": "mask", "path": path}
        if self.label is not None:
            item["label"] = self.label
        if self.segment is not None:
            item["segment"] = self.segment
        if self.affine_lps is not None and self.source.lower().endswith(".npy"):
            item["affine_lps"] = self.affine_lps.tolist()
        if self.axes is not None and self.axes != AXES_KJI and self.source.lower().endswith(".npy"):
            item["axes"] = self.axes
        return item | margin_item(self.margin_mm)

    def control_points_lps(self) -> np.ndarray:
        """The grid origin when it has a grid, else nothing."""
        return NO_POINTS if self.affine_lps is None else self.affine_lps[None, :3, 3]

    def with_margin(self, margin_mm: float | None) -> MaskLandmark:
        """A copy with ``margin_mm``."""
        return replace(self, margin_mm=margin_mm)

    def same_shape(self, other: Landmark) -> bool:
        """A mask with the same voxels on the same grid (both grid-less counts as the same)."""
        if not isinstance(other, MaskLandmark):
            return False
        if self.affine_lps is None or other.affine_lps is None:
            same_grid = self.affine_lps is None and other.affine_lps is None
        else:
            same_grid = np.array_equal(self.affine_lps, other.affine_lps)
        return same_grid and np.array_equal(self.mask, other.mask)

    @property
    def needs_grid(self) -> bool:
        """True while it has no ``affine_lps`` of its own."""
        return self.affine_lps is None

    def on_grid(self, affine_lps: np.ndarray, shape: tuple[int, ...]) -> MaskLandmark:
        """Bound to the CT grid when it has none (its shape must then be the CT's, and a mask
        of unknown axis order must fit it in one order only)."""
        if self.affine_lps is not None:
            return self
        ct = tuple(int(n) for n in shape)
        if self.axes is None and tuple(self.mask.shape) in _other_orders(ct):
            raise LandmarkInputError(
                f"mask landmark {self.name!r} ({self.source or 'array'}): a .npy labelmap "
                f"carries no geometry, and its shape {tuple(self.mask.shape)} fits the CT grid "
                f"{ct} (slices, rows, cols) in more than one axis order (the CT has two equal "
                'sizes); say which: "axes": "kji" (slices, rows, cols, as ctdrill and '
                'SimpleITK arrays) or "ijk" (cols, rows, slices, as nibabel returns), or give '
                "its affine_lps, or save the mask as NIfTI or NRRD"
            )
        if self.axes is None and sorted(self.mask.shape) == sorted(ct) != list(self.mask.shape):
            raise LandmarkInputError(
                f"mask landmark {self.name!r} ({self.source or 'array'}): shape "
                f"{tuple(self.mask.shape)} is the CT grid {ct} (slices, rows, cols) in another "
                'axis order; say which with "axes" ("ijk": cols, rows, slices, as nibabel '
                "returns) or give its affine_lps"
            )
        if tuple(self.mask.shape) != tuple(shape):
            raise LandmarkInputError(
                f"mask landmark {self.name!r} ({self.source or 'array'}): shape "
                f"{tuple(self.mask.shape)} does not match the CT grid {tuple(shape)} "
                "(slices, rows, cols); resample the mask onto the CT or give its affine_lps"
            )
        return replace(self, affine_lps=affine_lps)
