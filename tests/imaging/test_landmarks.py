"""Landmark values: canal segments, mask files and binding masks to the CT grid."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ctdrill.imaging.plan.landmarks import (
    CanalLandmark,
    Landmark,
    LandmarkInputError,
    MaskLandmark,
    PointLandmark,
    bind_to_grid,
    load_mask_file,
)


def test_every_kind_implements_the_protocol() -> None:
    canal = CanalLandmark("c", [[0, 0, 0], [1, 0, 0], [1, 2, 0]], radius_mm=1.5, margin_mm=3.0)
    a, b = canal.segments_lps()
    np.testing.assert_array_equal(a, [[0, 0, 0], [1, 0, 0]])
    np.testing.assert_array_equal(b, [[1, 0, 0], [1, 2, 0]])
    assert canal.kind == "canal" and not canal.points_lps.flags.writeable
    assert len(canal.drawing().polylines_lps) == 1 and canal.drawing().radius_mm == 1.5
    dot = CanalLandmark("one point", [[4, 5, 6]])
    assert dot.radius_mm == 1.2  # default canal radius
    assert dot.drawing().points_lps.shape == (1, 3) and dot.drawing().polylines_lps == ()
    apex = PointLandmark("p", [1, 2, 3])
    assert apex.radius_mm == 0.0 and apex.kind == "point"
    assert apex.to_plan_item() == {"name": "p", "kind": "point", "point_mm": [1.0, 2.0, 3.0]}
    assert apex.with_margin(0.5).margin_mm == 0.5 and apex.margin_mm is None
    mask = MaskLandmark("m", np.ones((1, 1, 1), dtype=bool), affine_lps=np.eye(4), source="m.npy")
    assert mask.drawing().surface_lps.shape == (6, 3)  # the six face centres of one voxel
    for lm in (canal, dot, apex, mask):
        assert isinstance(lm, Landmark)
        assert lm.to_plan_item()["kind"] == lm.kind
    with pytest.raises(LandmarkInputError, match="singular"):
        MaskLandmark("flat", np.ones((1, 1, 1), dtype=bool), affine_lps=np.diag([1, 1, 0, 1.0]))


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
    # (k, j, i) = (1, 2, 3) -> centre (10 + 2*3, 20 + 3*2, 30 + 5*1); its six face centres
    faces = bound.surface_points_lps()
    centre = np.array([16.0, 26.0, 35.0])
    half = np.array([1.0, 1.5, 2.5])
    want = [centre + sign * half * np.eye(3)[m] for m in range(3) for sign in (-1, 1)]
    assert sorted(map(tuple, faces)) == sorted(map(tuple, want))
    with pytest.raises(LandmarkInputError, match="expected a 3-D array"):
        MaskLandmark("bad", np.zeros((3, 3), dtype=bool))
    with pytest.raises(LandmarkInputError, match="finite 4x4"):
        MaskLandmark("bad", mask, affine_lps=np.eye(3))
