"""Properties of the grid rules and the readers: any proper grid reads back exactly, any lie is
refused (hypothesis)."""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ctdrill.imaging import load_ct
from ctdrill.imaging.volumes.grid import ORIENTATION_TOL, check_direction_cosines, check_grid
from ctdrill.imaging.volumes.types import VolumeFileError
from tests.imaging.volume_writers import corners_lps, every_corner_ijk, write_nrrd

unit = st.floats(-1.0, 1.0, allow_nan=False)
quaternions = st.tuples(unit, unit, unit, unit).filter(lambda q: sum(v * v for v in q) > 0.1)


def _rotation(q: tuple[float, float, float, float]) -> np.ndarray:
    w, x, y, z = np.asarray(q) / np.linalg.norm(q)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


@settings(max_examples=25)
@given(
    q=quaternions,
    spacing=st.tuples(*[st.floats(0.05, 5.0)] * 3),
    origin=st.tuples(*[st.floats(-500.0, 500.0)] * 3),
    shape=st.tuples(*[st.integers(1, 5)] * 3),
)
def test_any_proper_grid_reads_back_exactly(
    q: tuple[float, ...],
    spacing: tuple[float, ...],
    origin: tuple[float, ...],
    shape: tuple[int, int, int],
) -> None:
    affine = np.eye(4)
    affine[:3, :3] = _rotation(q) @ np.diag(spacing)  # type: ignore[arg-type]
    affine[:3, 3] = origin
    data = np.arange(int(np.prod(shape)), dtype=np.int16).reshape(shape) - 1000
    with tempfile.TemporaryDirectory() as tmp:
        volume = load_ct(write_nrrd(Path(tmp) / "v.nrrd", data, affine, encoding="raw"))
    np.testing.assert_array_equal(volume.hu, data)
    ijk = every_corner_ijk(shape)
    np.testing.assert_allclose(
        corners_lps(volume.affine_lps, ijk), corners_lps(affine, ijk), rtol=0, atol=1e-9
    )


@settings(max_examples=50)
@given(q=quaternions, scale=st.floats(1e-3, 1e3), axis=st.integers(0, 2))
def test_direction_cosines_must_be_unit(q: tuple[float, ...], scale: float, axis: int) -> None:
    dirs = _rotation(q).T.copy()  # rows: the axes' directions
    check_direction_cosines(dirs, where="f", field="TransformMatrix", error=VolumeFileError)
    dirs[axis] *= scale
    if abs(scale - 1.0) > 2 * ORIENTATION_TOL:
        with pytest.raises(VolumeFileError, match=f"direction {axis + 1} has length"):
            check_direction_cosines(dirs, where="f", field="TransformMatrix", error=VolumeFileError)


@settings(max_examples=50)
@given(q=quaternions, shear=st.floats(2 * ORIENTATION_TOL, 0.5))
def test_skewed_in_plane_axes_are_refused(q: tuple[float, ...], shear: float) -> None:
    rot = _rotation(q)
    affine = np.eye(4)
    affine[:3, :3] = rot
    check_grid(affine, (3, 3, 3), where="f", field="g", error=VolumeFileError)
    affine[:3, 1] = rot[:, 1] + shear * rot[:, 0]
    with pytest.raises(VolumeFileError, match="i and j axes are not perpendicular"):
        check_grid(affine, (3, 3, 3), where="f", field="g", error=VolumeFileError)
