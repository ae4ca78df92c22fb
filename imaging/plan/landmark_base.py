"""The landmark protocol and what every kind shares: the drawing, the input error, helpers.

The kinds themselves live in :mod:`ctdrill.imaging.plan.landmarks` (canal, point) and
:mod:`ctdrill.imaging.plan.mask` (labelmaps); import them from ``landmarks``.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

import numpy as np

from ctdrill.imaging.errors import ImagingInputError
from ctdrill.imaging.plan.distance import AxialSolid

#: Canal radius used when a plan or markup gives none, mm (a typical inferior alveolar canal
#: is 2-3 mm wide).
DEFAULT_CANAL_RADIUS_MM = 1.2
#: Most surface points a mask's drawing holds (evenly thinned beyond).
MAX_DRAWN_SURFACE_POINTS = 2000


class LandmarkInputError(ImagingInputError):
    """A landmark that cannot be used (missing mask file, mask off the CT grid, ...)."""


def frozen_array(array: np.ndarray) -> np.ndarray:
    out = np.array(array, copy=True)
    out.flags.writeable = False
    return out


NO_POINTS = frozen_array(np.empty((0, 3)))


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
    points_lps: np.ndarray = field(default_factory=lambda: NO_POINTS)
    surface_lps: np.ndarray = field(default_factory=lambda: NO_POINTS)
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

    def clearance_mm(self, solid: AxialSolid, depth_mm: np.ndarray) -> np.ndarray:
        """(D,) signed clearance from a solid placed at each depth, mm (< 0 inside, minus the
        penetration depth): the swept drill (:class:`~ctdrill.imaging.plan.distance.DrillSolid`,
        tip at the depth) or the implant body
        (:class:`~ctdrill.imaging.plan.implant_safety.ImplantBody`, apex at the depth). A kind
        measures any convex solid of revolution on the trajectory's axis the same way."""
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


def margin_item(margin_mm: float | None) -> dict[str, Any]:
    return {} if margin_mm is None else {"margin_mm": margin_mm}
