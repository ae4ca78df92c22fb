"""The GUI's surface and slices of an irregular stack sit at the true slice positions."""

from __future__ import annotations

import numpy as np

from ctdrill.app.gui.compute import volume_surface
from ctdrill.app.gui.slices import reslice, volume_center_lps
from ctdrill.imaging import CTVolume, SeriesInfo

#: Slice positions (z, mm) with a 7 mm gap between 3 and 10; bone (1000 HU) from z = 10 on.
POSITIONS = np.array([0.0, 1.0, 2.0, 3.0, 10.0, 11.0, 12.0])


def _volume() -> CTVolume:
    hu = np.where(POSITIONS[:, None, None] >= 10.0, 1000, -1000) * np.ones((1, 12, 12))
    return CTVolume(
        hu=hu.astype(np.int16),
        affine_lps=np.diag([1.0, 1.0, 1.0, 1.0]),
        valid=None,
        info=SeriesInfo(series_uid="1.2.3"),
        slice_positions_mm=POSITIONS,
    )


def test_bone_surface_of_an_irregular_stack_sits_between_the_true_slices() -> None:
    vol = _volume()
    surf = volume_surface(vol, iso_hu=0.0)
    pts = np.asarray(surf.points)
    away_from_sides = np.all((pts[:, :2] > 0.5) & (pts[:, :2] < 10.5), axis=1)
    z = pts[away_from_sides, 2]
    inner = z[(z > 0.5) & (z < 11.5)]
    # 0 HU is half-way between the slices at z = 3 (-1000) and z = 10 (+1000): z = 6.5
    # (the nominal-step affine would put it at z = 3.5)
    assert inner.size > 0
    np.testing.assert_allclose(inner, 6.5, atol=1e-4)


def test_reslice_covers_and_samples_the_true_slices() -> None:
    vol = _volume()
    np.testing.assert_allclose(volume_center_lps(vol), [5.5, 5.5, 6.0])
    img = reslice(vol, "coronal", np.array([5.0, 5.0, 6.0]), pixel_mm=0.5)
    z_of_row = img.origin_lps[2] + np.arange(img.hu.shape[0]) * img.v_lps[2] * img.pixel_mm
    # the coronal plane spans the true stack, z = 0..12 (the nominal affine ends at z = 6)
    assert (float(z_of_row.min()), float(z_of_row.max())) == (0.0, 12.0)
    col = img.hu[:, img.hu.shape[1] // 2]
    want = np.interp(z_of_row, POSITIONS, np.where(POSITIONS >= 10.0, 1000.0, -1000.0))
    np.testing.assert_allclose(col, want, atol=1e-3)
