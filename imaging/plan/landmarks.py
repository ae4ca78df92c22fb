"""Anatomical landmarks the drill must keep clear of, in LPS millimetres.

Every kind implements one small protocol, :class:`Landmark`: its signed clearance to the
drill solid or the implant body (any convex solid of revolution on the axis), what draws it
(:class:`LandmarkDrawing`) and its plan-file form. Nothing else
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
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ctdrill.imaging.plan.distance import AxialSolid, segments_distance_mm
from ctdrill.imaging.plan.landmark_base import (
    DEFAULT_CANAL_RADIUS_MM,
    MAX_DRAWN_SURFACE_POINTS,
    Landmark,
    LandmarkDrawing,
    LandmarkInputError,
    frozen_array,
    margin_item,
)
from ctdrill.imaging.plan.mask import MaskLandmark

__all__ = [
    "DEFAULT_CANAL_RADIUS_MM",
    "MAX_DRAWN_SURFACE_POINTS",
    "CanalLandmark",
    "Landmark",
    "LandmarkDrawing",
    "LandmarkInputError",
    "MaskLandmark",
    "PointLandmark",
    "bind_to_grid",
]


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
        object.__setattr__(self, "points_lps", frozen_array(pts))

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

    def clearance_mm(self, solid: AxialSolid, depth_mm: np.ndarray) -> np.ndarray:
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
            **margin_item(self.margin_mm),
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
        object.__setattr__(self, "point_lps", frozen_array(pt))

    @property
    def kind(self) -> str:
        """``"point"``."""
        return "point"

    @property
    def radius_mm(self) -> float:
        """Always 0: the landmark is the point itself."""
        return 0.0

    def clearance_mm(self, solid: AxialSolid, depth_mm: np.ndarray) -> np.ndarray:
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
            **margin_item(self.margin_mm),
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
