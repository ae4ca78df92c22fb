"""Landmark values: canal segments, mask files and binding masks to the CT grid."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ctdrill.imaging.plan.landmarks import (
    CanalLandmark,
    LandmarkInputError,
    MaskLandmark,
    PointLandmark,
    bind_to_grid,
    landmark_core,
    load_mask_file,
)


def test_cores_of_each_kind() -> None:
    canal = CanalLandmark("c", [[0, 0, 0], [1, 0, 0], [1, 2, 0]], radius_mm=1.5, margin_mm=3.0)
    a, b, r = landmark_core(canal)
    np.testing.assert_array_equal(a, [[0, 0, 0], [1, 0, 0]])
    np.testing.assert_array_equal(b, [[1, 0, 0], [1, 2, 0]])
    assert r == 1.5 and canal.kind == "canal" and not canal.points_lps.flags.writeable
    dot = CanalLandmark("one point", [[4, 5, 6]])
    a, b, r = landmark_core(dot)
    assert a.shape == b.shape == (1, 3) and r == 1.2  # default canal radius
    apex = PointLandmark("p", [1, 2, 3])
    a, b, r = landmark_core(apex)
    np.testing.assert_array_equal(a, [[1, 2, 3]])
    assert r == 0.0 and apex.radius_mm == 0.0 and apex.kind == "point"


def test_mask_files_are_checked(tmp_path: Path) -> None:
    with pytest.raises(LandmarkInputError, match=r"\.npy labelmaps"):
        load_mask_file(tmp_path / "seg.nrrd")
    np.save(tmp_path / "flat.npy", np.ones((4, 4), dtype=np.uint8))
    with pytest.raises(LandmarkInputError, match="expected a 3-D labelmap"):
        load_mask_file(tmp_path / "flat.npy")
    np.save(tmp_path / "float.npy", np.ones((2, 2, 2), dtype=np.float32))
    with pytest.raises(LandmarkInputError, match="must be integer or bool"):
        load_mask_file(tmp_path / "float.npy")
    np.save(tmp_path / "labels.npy", np.array([[[0, 1], [2, 2]]], dtype=np.int16))
    with pytest.raises(LandmarkInputError, match="empty for label 7"):
        load_mask_file(tmp_path / "labels.npy", label=7)
    assert int(load_mask_file(tmp_path / "labels.npy").sum()) == 3
    assert int(load_mask_file(tmp_path / "labels.npy", label=2).sum()) == 2
    (tmp_path / "junk.npy").write_bytes(b"not numpy")
    with pytest.raises(LandmarkInputError, match=r"not a readable \.npy"):
        load_mask_file(tmp_path / "junk.npy")


def test_binding_gives_grid_less_masks_the_ct_affine() -> None:
    mask = np.zeros((2, 3, 4), dtype=bool)
    mask[1, 2, 3] = True
    free = MaskLandmark("m", mask)
    with pytest.raises(LandmarkInputError, match="bind it to the CT"):
        free.surface_points_lps()
    affine = np.array([[2.0, 0, 0, 10.0], [0, 3.0, 0, 20.0], [0, 0, 5.0, 30.0], [0, 0, 0, 1.0]])
    canal = CanalLandmark("c", [[0, 0, 0]])
    bound_canal, bound = bind_to_grid((canal, free), affine, (2, 3, 4))
    assert bound_canal is canal
    assert isinstance(bound, MaskLandmark)
    # (k, j, i) = (1, 2, 3) -> (10 + 2*3, 20 + 3*2, 30 + 5*1)
    np.testing.assert_allclose(bound.surface_points_lps(), [[16.0, 26.0, 35.0]])
    with pytest.raises(LandmarkInputError, match="expected a 3-D array"):
        MaskLandmark("bad", np.zeros((3, 3), dtype=bool))
    with pytest.raises(LandmarkInputError, match="finite 4x4"):
        MaskLandmark("bad", mask, affine_lps=np.eye(3))
