"""The window's background work, as plain functions (run in a worker thread by the window, and
directly by the tests and the benchmark): loading a series with its bone surface, reslicing the
four views, and planning the path.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pyvista as pv

from ctdrill.app.gui.slices import VIEWS, SliceImage, reslice, volume_center_lps
from ctdrill.app.gui.surface import DISPLAY_TRIANGLES, bone_surface, display_block
from ctdrill.imaging import CTVolume, load_ct
from ctdrill.imaging.dicom.series import SeriesSummary, list_series
from ctdrill.imaging.display import BONE_SURFACE_HU
from ctdrill.imaging.plan.types import Plan

#: Triangles of the first bone surface a series opens with (cheap to compute and to draw on
#: software OpenGL); the 3D view then asks for the finest its measured frame time affords.
FIRST_TRIANGLES = 60_000
#: Longest side of the strided grid the bone surface is contoured on, samples; None: every
#: voxel (the default since issue 16; 160 was the earlier coarse surface, every 4th slice on a
#: 512 x 512 series, kept as the benchmark's peer).
SURFACE_MAX_DIM: int | None = None


@dataclass(frozen=True, eq=False)
class Loaded:
    """A loaded series and its bone surface at ``iso_hu`` (None: contoured afterwards)."""

    path: str
    volume: CTVolume
    surface: pv.PolyData | None
    iso_hu: float


@dataclass(frozen=True)
class SeriesChoice:
    """``path`` holds several CT stacks: the user picks one (largest first)."""

    path: str
    series: tuple[SeriesSummary, ...]


def load_case(
    path: str | os.PathLike[str],
    *,
    series_uid: str | None = None,
    iso_hu: float = BONE_SURFACE_HU,
    max_dim: int | None = SURFACE_MAX_DIM,
    ask_series: bool = False,
    surface: bool = True,
) -> Loaded | SeriesChoice:
    """Load the series at ``path`` and contour its bone surface (``surface`` False: leave it
    to :func:`volume_surface` afterwards; the window draws its slices and path first).

    With ``ask_series`` and no ``series_uid``, a folder holding several CT stacks returns a
    :class:`SeriesChoice` instead (the loader alone would take the largest, with a
    ``multiple_series`` warning).
    """
    if ask_series and series_uid is None and Path(path).is_dir():
        series = list_series(str(path))
        if len(series) > 1:
            return SeriesChoice(path=str(path), series=series)
    volume = load_ct(str(path), series_uid=series_uid)
    bone = (
        volume_surface(volume, iso_hu=iso_hu, max_dim=max_dim, max_triangles=FIRST_TRIANGLES)
        if surface
        else None
    )
    return Loaded(path=str(path), volume=volume, surface=bone, iso_hu=iso_hu)


def is_volume_file(path: Path) -> bool:
    """True for a NIfTI, NRRD or MetaImage file (by content), which opens as the CT itself."""
    from ctdrill.imaging.errors import ImagingInputError
    from ctdrill.imaging.volumes.sniff import volume_format

    try:
        return volume_format(path, error=ImagingInputError) != "dicom"
    except ImagingInputError:
        return False


def volume_surface(
    volume: CTVolume,
    *,
    iso_hu: float = BONE_SURFACE_HU,
    max_dim: int | None = SURFACE_MAX_DIM,
    max_triangles: int | None = DISPLAY_TRIANGLES,
) -> pv.PolyData:
    """The bone surface of ``volume`` at ``iso_hu`` (padding counts as air), at the finest
    voxel block whose surface has at most ``max_triangles`` triangles (``display_block``;
    None: every voxel); its field data ``block`` says which. Slices are merged only in a
    regular stack and only where thinner than the block."""
    block = (1, 1, 1)
    if max_dim is None and max_triangles is not None:
        block = display_block(
            volume.hu,
            volume.spacing_mm,
            iso_hu=iso_hu,
            valid=volume.valid,
            merge_slices=regular_stack(volume),
            max_triangles=max_triangles,
        )
    surface = bone_surface(
        volume.hu,
        volume.affine_lps,
        iso_hu=iso_hu,
        max_dim=max_dim,
        valid=volume.valid,
        index_to_lps=volume.index_to_lps,
        block=block,
    )
    surface.field_data["iso_hu"] = np.array([iso_hu])
    return surface


def regular_stack(volume: CTVolume) -> bool:
    """True when the slices are evenly spaced (to 0.1 %): blocks may then merge slices."""
    steps = np.diff(np.asarray(volume.slice_positions_mm, dtype=np.float64))
    return steps.size == 0 or bool(np.allclose(steps, steps[0], rtol=1e-3, atol=1e-6))


def slice_key(volume: CTVolume, plan: Plan | None) -> tuple[object, ...]:
    """What the planes of :func:`slice_views` depend on (equal keys: same images)."""
    if plan is None:
        return (id(volume),)
    return (id(volume), *np.round(plan.target_lps, 9), *np.round(plan.direction, 12))


def slice_views(
    volume: CTVolume, plan: Plan | None, *, center_lps: np.ndarray | None = None
) -> dict[str, SliceImage]:
    """The axial, coronal and sagittal planes through ``center_lps`` (default the target; the
    volume's centre without a plan) and, with a plan, the plane through the drill axis."""
    if center_lps is not None:
        center = np.asarray(center_lps, dtype=np.float64)
    else:
        center = volume_center_lps(volume) if plan is None else plan.target_lps
    out: dict[str, SliceImage] = {}
    for view in VIEWS:
        if view != "trajectory":
            out[view] = reslice(volume, view, center)
        elif plan is not None:
            out[view] = reslice(volume, view, plan.target_lps, axis_lps=plan.direction)
    return out
