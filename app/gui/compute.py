"""The window's background work, as plain functions (run in a worker thread by the window, and
directly by the tests and the benchmark): loading a series with its bone surface, reslicing the
four views, and planning the path.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np
import pyvista as pv

from app.gui.scene import bone_surface
from app.gui.slices import VIEWS, SliceImage, reslice
from imaging import CTVolume, load_series
from imaging.plan import Plan

#: Longest side of the strided grid the bone surface is contoured on, samples.
SURFACE_MAX_DIM = 160


@dataclass(frozen=True, eq=False)
class Loaded:
    """A loaded series and its bone surface at ``iso_hu``."""

    path: str
    volume: CTVolume
    surface: pv.PolyData
    iso_hu: float


def load_case(
    path: str | os.PathLike[str],
    *,
    series_uid: str | None = None,
    iso_hu: float = 300.0,
    max_dim: int = SURFACE_MAX_DIM,
) -> Loaded:
    """Load the series at ``path`` and contour its bone surface."""
    volume = load_series(str(path), series_uid=series_uid)
    surface = volume_surface(volume, iso_hu=iso_hu, max_dim=max_dim)
    return Loaded(path=str(path), volume=volume, surface=surface, iso_hu=iso_hu)


def volume_surface(
    volume: CTVolume, *, iso_hu: float = 300.0, max_dim: int = SURFACE_MAX_DIM
) -> pv.PolyData:
    """The bone surface of ``volume`` at ``iso_hu`` (padding counts as air)."""
    return bone_surface(
        volume.hu, volume.affine_lps, iso_hu=iso_hu, max_dim=max_dim, valid=volume.valid
    )


def slice_views(
    volume: CTVolume, plan: Plan, *, center_lps: np.ndarray | None = None
) -> dict[str, SliceImage]:
    """The axial, coronal and sagittal planes through ``center_lps`` (default the target) and
    the plane through the drill axis."""
    center = plan.target_lps if center_lps is None else np.asarray(center_lps, dtype=np.float64)
    out: dict[str, SliceImage] = {}
    for view in VIEWS:
        if view == "trajectory":
            out[view] = reslice(volume, view, plan.target_lps, axis_lps=plan.direction)
        else:
            out[view] = reslice(volume, view, center)
    return out
