"""Reslicing: exact values on the analytic phantom, view orientation, plane round trips."""

from __future__ import annotations

import numpy as np
import pytest

from ctdrill.app.gui.slices import (
    VIEWS,
    _grid_aligned,
    polyline_in_plane,
    reslice,
    view_axes,
    volume_corners_lps,
    window_to_uint8,
)
from ctdrill.imaging import CTVolume, SeriesInfo
from tests.app.gui.phantom import CANAL_YZ, SPACING_MM, phantom_volume


def test_axial_slice_through_the_canal_shows_canal_bone_and_air() -> None:
    vol = phantom_volume()
    img = reslice(vol, "axial", np.array([0.0, CANAL_YZ[0], CANAL_YZ[1]]))
    assert img.pixel_mm == pytest.approx(SPACING_MM)
    # The canal runs along x at y = 0 in this plane: every pixel with |y| < 1 mm is canal.
    uv, off = img.to_plane_mm(np.array([[0.0, 0.0, CANAL_YZ[1]], [0.0, 19.0, CANAL_YZ[1]]]))
    assert np.allclose(off, 0.0)
    col, row = np.rint(uv[0] / img.pixel_mm).astype(int)
    assert img.hu[row, col] == pytest.approx(30.0)
    col, row = np.rint(uv[1] / img.pixel_mm).astype(int)
    assert img.hu[row, col] == pytest.approx(-1000.0)


def test_every_pixel_is_the_volume_sample_at_its_lps_position() -> None:
    vol = phantom_volume()
    entry = np.array([1.0, -2.0, 12.0])
    target = np.array([-2.0, 1.5, -1.0])
    img = reslice(vol, "trajectory", target, axis_lps=target - entry)
    rows, cols = np.mgrid[0 : img.hu.shape[0] : 7, 0 : img.hu.shape[1] : 7]
    uv = np.stack([cols, rows], axis=-1) * img.pixel_mm
    expected = vol.sample(img.to_lps(uv), order=1, outside_hu=-1000.0)
    assert np.allclose(img.hu[rows, cols], expected, atol=1e-3)


def test_the_trajectory_plane_contains_the_drill_axis_and_runs_down_the_image() -> None:
    vol = phantom_volume()
    entry = np.array([3.0, -1.0, 12.0])
    target = np.array([0.0, 1.0, -2.0])
    img = reslice(vol, "trajectory", target, axis_lps=target - entry)
    uv, off = img.to_plane_mm(np.stack([entry, target]))
    assert np.allclose(off, 0.0, atol=1e-9)
    assert uv[1, 1] > uv[0, 1]  # target below the entry
    assert uv[1, 1] - uv[0, 1] == pytest.approx(np.linalg.norm(target - entry))


@pytest.mark.parametrize(
    ("view", "u", "v"),
    [
        ("axial", (1, 0, 0), (0, 1, 0)),  # patient left right, anterior up
        ("coronal", (1, 0, 0), (0, 0, -1)),  # superior up
        ("sagittal", (0, 1, 0), (0, 0, -1)),
    ],
)
def test_radiological_orientation(view: str, u: tuple[int, ...], v: tuple[int, ...]) -> None:
    got_u, got_v = view_axes(view)  # type: ignore[arg-type]
    assert np.array_equal(got_u, u) and np.array_equal(got_v, v)


def test_each_view_covers_the_whole_volume_and_round_trips() -> None:
    vol = phantom_volume()
    corners = volume_corners_lps(vol.affine_lps, vol.hu.shape)
    for view in VIEWS:
        img = reslice(vol, view, np.zeros(3), axis_lps=np.array([0.3, 0.2, -1.0]))
        uv, _ = img.to_plane_mm(corners)
        h, w = img.hu.shape
        assert uv[:, 0].min() >= -1e-9 and uv[:, 0].max() <= (w - 1) * img.pixel_mm + 1e-9
        assert uv[:, 1].min() >= -1e-9 and uv[:, 1].max() <= (h - 1) * img.pixel_mm + 1e-9
        back, off = img.to_plane_mm(img.to_lps(np.array([[3.5, 7.25]])))
        assert np.allclose(back, [[3.5, 7.25]]) and np.allclose(off, 0.0)


def test_max_pixels_coarsens_the_grid() -> None:
    img = reslice(phantom_volume(), "coronal", np.zeros(3), max_pixels=25)
    assert max(img.hu.shape) <= 26
    assert img.pixel_mm == pytest.approx(49.5 / 25)  # x spans 100 voxel centres, 0.5 mm apart


def test_window_to_uint8_is_linear_and_clipped() -> None:
    hu = np.array([-1000.0, -100.0, 0.0, 50.0, 100.0, 3000.0])
    grey = window_to_uint8(hu, level_hu=0.0, width_hu=200.0)
    assert grey.tolist() == [0, 0, 128, 191, 255, 255]
    with pytest.raises(ValueError, match="width"):
        window_to_uint8(hu, level_hu=0.0, width_hu=0.0)


def test_polyline_near_the_plane_is_flagged() -> None:
    img = reslice(phantom_volume(), "axial", np.array([0.0, 0.0, -4.0]))
    pts = np.array([[0.0, 0.0, -4.0], [0.0, 0.0, -5.5], [0.0, 0.0, 0.0]])
    _, near = polyline_in_plane(img, pts, slab_mm=2.0)
    assert near.tolist() == [True, True, False]


def _flipped_padded_volume() -> CTVolume:
    """The phantom with rows and slices reversed (negative spacings) and a padded corner."""
    vol = phantom_volume()
    aff = np.array(vol.affine_lps)
    nk, nj, _ = vol.hu.shape
    aff[:3, 3] += aff[:3, 1] * (nj - 1) + aff[:3, 2] * (nk - 1)
    aff[:3, 1] *= -1.0
    aff[:3, 2] *= -1.0
    hu = np.ascontiguousarray(vol.hu[::-1, ::-1, :])
    valid = np.ones(hu.shape, dtype=bool)
    valid[:10, :15, :20] = False
    return CTVolume(hu=hu, affine_lps=aff, valid=valid, info=SeriesInfo(series_uid="1.2.3.4"))


@pytest.mark.parametrize("view", ["axial", "coronal", "sagittal"])
@pytest.mark.parametrize("center", [(0.3, -1.1, -4.27), (-24.75, 19.5, -15.0), (0.0, 0.0, 99.0)])
def test_the_grid_aligned_fast_path_equals_trilinear_sampling(
    view: str, center: tuple[float, float, float]
) -> None:
    for vol in (phantom_volume(), _flipped_padded_volume()):
        fast = reslice(vol, view, np.array(center))  # type: ignore[arg-type]
        slow = reslice(vol, view, np.array(center), fast=False)  # type: ignore[arg-type]
        assert fast.hu.shape == slow.hu.shape
        assert np.allclose(fast.hu, slow.hu, atol=1e-3)
        assert np.array_equal(fast.origin_lps, slow.origin_lps)
        taken = _grid_aligned(
            vol,
            fast.origin_lps,
            fast.u_lps * fast.pixel_mm,
            fast.v_lps * fast.pixel_mm,
            fast.hu.shape,
            -1000.0,
        )
        assert taken is not None  # the fast path really ran


def test_oblique_planes_take_the_general_path() -> None:
    vol = phantom_volume()
    img = reslice(vol, "trajectory", np.zeros(3), axis_lps=np.array([0.3, 0.2, -1.0]))
    assert _grid_aligned(vol, img.origin_lps, img.u_lps, img.v_lps, img.hu.shape, -1000.0) is None
