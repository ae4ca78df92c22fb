"""Anatomical landmarks the drill must keep clear of, in LPS millimetres.

Every kind implements one small protocol, :class:`Landmark`: its signed clearance to the
drill solid, what draws it (:class:`LandmarkDrawing`) and its plan-file form. Nothing else
in ctdrill needs to know which kind it holds; a new kind is one new class here (plus its
reader in :mod:`ctdrill.imaging.plan.read`).

- :class:`CanalLandmark`: a centerline polyline with a radius (a union of capsules), e.g. the
  mandibular canal. Clearance: signed distance from the solid to the centerline - radius.
- :class:`PointLandmark`: a single point, radius 0 (a fiducial such as a root apex).
- :class:`MaskLandmark`: a labelmap on a voxel grid; each labelled voxel is a box of anatomy
  and the clearance is the signed distance to the union of the boxes, exact on any grid
  (:mod:`ctdrill.imaging.plan.voxels`).

Clearances are signed (negative inside the landmark), so a radius or a margin of 0 means
"touch, never cross".
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

import numpy as np

from ctdrill.imaging.errors import ImagingInputError
from ctdrill.imaging.plan.distance import DrillSolid, segments_distance_mm
from ctdrill.imaging.plan.voxels import exposed_face_centres, voxel_union_segments

#: Canal radius used when a plan or markup gives none, mm (a typical inferior alveolar canal
#: is 2-3 mm wide).
DEFAULT_CANAL_RADIUS_MM = 1.2
#: Most surface points a mask's drawing holds (evenly thinned beyond).
MAX_DRAWN_SURFACE_POINTS = 2000


class LandmarkInputError(ImagingInputError):
    """A landmark that cannot be used (missing mask file, mask off the CT grid, ...)."""


def _frozen(array: np.ndarray) -> np.ndarray:
    out = np.array(array, copy=True)
    out.flags.writeable = False
    return out


_NO_POINTS = _frozen(np.empty((0, 3)))


@dataclass(frozen=True, eq=False)
class LandmarkDrawing:
    """What draws a landmark (LPS mm), whatever its kind.

    Attributes
    ----------
    polylines_lps : each (N >= 2, 3): a tube of ``radius_mm`` along it.
    points_lps : (P, 3): a sphere of ``radius_mm`` at each point.
    surface_lps : (Q, 3): points on the landmark's surface, drawn as a cloud (no envelope).
    radius_mm : tube and sphere radius, mm.
    """

    polylines_lps: tuple[np.ndarray, ...] = ()
    points_lps: np.ndarray = field(default_factory=lambda: _NO_POINTS)
    surface_lps: np.ndarray = field(default_factory=lambda: _NO_POINTS)
    radius_mm: float = 0.0


@runtime_checkable
class Landmark(Protocol):
    """What every landmark kind provides."""

    @property
    def name(self) -> str:
        """A label for messages and views."""
        ...

    @property
    def kind(self) -> str:
        """The plan file's ``kind`` (``canal``, ``point``, ``mask``)."""
        ...

    @property
    def margin_mm(self) -> float | None:
        """Its own safety margin, mm (None: the plan's)."""
        ...

    @property
    def radius_mm(self) -> float:
        """Radius around its core, mm (0 for points and masks)."""
        ...

    def clearance_mm(self, solid: DrillSolid, depth_mm: np.ndarray) -> np.ndarray:
        """(D,) signed clearance from the drill solid at each tip depth, mm (< 0 inside)."""
        ...

    def drawing(self) -> LandmarkDrawing:
        """What draws it."""
        ...

    def to_plan_item(self, out_dir: str | os.PathLike[str] | None = None) -> dict[str, Any]:
        """Its ``ctdrill-plan/1`` landmark object (LPS); file paths relative to ``out_dir``
        (the folder the plan is saved in) when given."""
        ...

    def control_points_lps(self) -> np.ndarray:
        """(N, 3) the coordinates the plan gave for it, LPS mm (for bounds checks)."""
        ...

    def with_margin(self, margin_mm: float | None) -> Landmark:
        """The same landmark with its own margin set (None: the plan's)."""
        ...

    def same_shape(self, other: Landmark) -> bool:
        """``other`` is the same kind with the same geometry (margins not compared)."""
        ...

    @property
    def needs_grid(self) -> bool:
        """True for a mask without a grid of its own (it takes the CT's, if it has one)."""
        ...

    def on_grid(self, affine_lps: np.ndarray, shape: tuple[int, ...]) -> Landmark:
        """The landmark with a grid-less mask bound to the CT grid (others unchanged)."""
        ...


def _margin_item(margin_mm: float | None) -> dict[str, Any]:
    return {} if margin_mm is None else {"margin_mm": margin_mm}


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

    def clearance_mm(self, solid: DrillSolid, depth_mm: np.ndarray) -> np.ndarray:
        """Signed distance from the solid to the centerline minus the radius, mm."""
        a, b = self.segments_lps()
        out: np.ndarray = segments_distance_mm(a, b, depth_mm, solid) - float(self.radius_mm)
        return out

    def drawing(self) -> LandmarkDrawing:
        """A tube along the centerline (a sphere for a one-point canal)."""
        if len(self.points_lps) == 1:
            return LandmarkDrawing(points_lps=self.points_lps, radius_mm=float(self.radius_mm))
        return LandmarkDrawing(polylines_lps=(self.points_lps,), radius_mm=float(self.radius_mm))

    def to_plan_item(self, out_dir: str | os.PathLike[str] | None = None) -> dict[str, Any]:
        """``{"kind": "canal", "points_mm", "radius_mm"}``."""
        return {
            "name": self.name,
            "kind": "canal",
            "points_mm": self.points_lps.tolist(),
            "radius_mm": self.radius_mm,
            **_margin_item(self.margin_mm),
        }

    def control_points_lps(self) -> np.ndarray:
        """The centerline points."""
        return self.points_lps

    def with_margin(self, margin_mm: float | None) -> CanalLandmark:
        """A copy with ``margin_mm``."""
        return replace(self, margin_mm=margin_mm)

    def same_shape(self, other: Landmark) -> bool:
        """A canal with the same radius and centre line."""
        return (
            isinstance(other, CanalLandmark)
            and self.radius_mm == other.radius_mm
            and np.array_equal(self.points_lps, other.points_lps)
        )

    @property
    def needs_grid(self) -> bool:
        """False: a canal has no grid."""
        return False

    def on_grid(self, affine_lps: np.ndarray, shape: tuple[int, ...]) -> CanalLandmark:
        """Itself (a canal has no grid)."""
        return self


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

    def clearance_mm(self, solid: DrillSolid, depth_mm: np.ndarray) -> np.ndarray:
        """Signed distance from the solid to the point, mm (closed form)."""
        pt = self.point_lps[None, :]
        return segments_distance_mm(pt, pt, depth_mm, solid)

    def drawing(self) -> LandmarkDrawing:
        """One point."""
        return LandmarkDrawing(points_lps=self.point_lps[None, :], radius_mm=0.0)

    def to_plan_item(self, out_dir: str | os.PathLike[str] | None = None) -> dict[str, Any]:
        """``{"kind": "point", "point_mm"}``."""
        return {
            "name": self.name,
            "kind": "point",
            "point_mm": self.point_lps.tolist(),
            **_margin_item(self.margin_mm),
        }

    def control_points_lps(self) -> np.ndarray:
        """The point, (1, 3)."""
        return self.point_lps[None, :]

    def with_margin(self, margin_mm: float | None) -> PointLandmark:
        """A copy with ``margin_mm``."""
        return replace(self, margin_mm=margin_mm)

    def same_shape(self, other: Landmark) -> bool:
        """A point landmark at the same point."""
        return isinstance(other, PointLandmark) and np.array_equal(self.point_lps, other.point_lps)

    @property
    def needs_grid(self) -> bool:
        """False: a point has no grid."""
        return False

    def on_grid(self, affine_lps: np.ndarray, shape: tuple[int, ...]) -> PointLandmark:
        """Itself (a point has no grid)."""
        return self


@dataclass(frozen=True, eq=False)
class MaskLandmark:
    """A labelmap landmark: ``mask`` (slices, rows, cols) bool on the grid ``affine_lps``.

    ``affine_lps`` maps ``(i=col, j=row, k=slice, 1)`` to LPS mm like ``CTVolume.affine_lps``
    (oblique and sheared grids included; it must be invertible). ``None`` means "the CT's
    grid": bind it with :func:`bind_to_grid` before computing clearances. ``source`` is the
    file the mask came from (for messages and saving); ``label`` and ``segment`` what was
    taken from it (a label value, a segment's name). Each labelled voxel is the box
    ``affine @ ([i, j, k] + [-1/2, 1/2]^3)``.
    """

    name: str
    mask: np.ndarray
    affine_lps: np.ndarray | None = None
    margin_mm: float | None = None
    source: str = ""
    label: int | None = None
    segment: str | None = None
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
        object.__setattr__(self, "mask", _frozen(mask))
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
            object.__setattr__(self, "affine_lps", _frozen(aff))

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

    def clearance_mm(self, solid: DrillSolid, depth_mm: np.ndarray) -> np.ndarray:
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
        return item | _margin_item(self.margin_mm)

    def control_points_lps(self) -> np.ndarray:
        """The grid origin when it has a grid, else nothing."""
        return _NO_POINTS if self.affine_lps is None else self.affine_lps[None, :3, 3]

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
        """Bound to the CT grid when it has none (its shape must then be the CT's)."""
        if self.affine_lps is not None:
            return self
        if tuple(self.mask.shape) != tuple(shape):
            raise LandmarkInputError(
                f"mask landmark {self.name!r} ({self.source or 'array'}): shape "
                f"{tuple(self.mask.shape)} does not match the CT grid {tuple(shape)} "
                "(slices, rows, cols); resample the mask onto the CT or give its affine_lps"
            )
        return replace(self, affine_lps=affine_lps)


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
    return tuple(lm.on_grid(affine_lps, shape) for lm in landmarks)
