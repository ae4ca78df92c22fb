"""Landmark values: canal segments, mask files and binding masks to the CT grid."""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from ctdrill.imaging.plan.distance import DrillSolid, segments_distance_mm
from ctdrill.imaging.plan.landmarks import (
    CanalLandmark,
    Landmark,
    LandmarkDrawing,
    LandmarkInputError,
    MaskLandmark,
    PointLandmark,
    bind_to_grid,
)
from ctdrill.imaging.plan.safety import safe_depth
from ctdrill.imaging.plan.segmentation import load_mask_file
from ctdrill.imaging.plan.types import Plan
from ctdrill.imaging.plan.write import plan_document


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


@dataclass(frozen=True, eq=False)
class Ball:
    """A landmark kind written only against the protocol (a sphere of ``radius_mm``)."""

    name: str
    centre_lps: np.ndarray
    radius_mm: float
    margin_mm: float | None = None

    @property
    def kind(self) -> str:
        return "ball"

    def clearance_mm(self, solid: DrillSolid, depth_mm: np.ndarray) -> np.ndarray:
        pt = np.asarray(self.centre_lps, dtype=np.float64)[None, :]
        return segments_distance_mm(pt, pt, depth_mm, solid) - self.radius_mm

    def drawing(self) -> LandmarkDrawing:
        return LandmarkDrawing(
            points_lps=np.asarray(self.centre_lps)[None], radius_mm=self.radius_mm
        )

    def to_plan_item(self, out_dir: object = None) -> dict[str, Any]:
        return {"name": self.name, "kind": "ball", "centre_mm": list(self.centre_lps)}

    def control_points_lps(self) -> np.ndarray:
        return np.asarray(self.centre_lps, dtype=np.float64)[None]

    def with_margin(self, margin_mm: float | None) -> Ball:
        return replace(self, margin_mm=margin_mm)

    def same_shape(self, other: Landmark) -> bool:
        return isinstance(other, Ball) and np.array_equal(self.centre_lps, other.centre_lps)

    @property
    def needs_grid(self) -> bool:
        return False

    def on_grid(self, affine_lps: np.ndarray, shape: tuple[int, ...]) -> Ball:
        return self


def test_a_new_kind_is_one_class() -> None:
    # A ball of radius 1 mm on the axis 10 mm deep: a 2 mm margin allows 7 mm; the writer,
    # the merge and the grid binding take it without knowing its kind.
    ball = Ball("ball", np.array([0.0, 0.0, -10.0]), 1.0)
    assert isinstance(ball, Landmark)
    plan = Plan(entry_lps=[0, 0, 0], target_lps=[0, 0, -12.0], landmarks=(ball,), name="b")
    got = safe_depth(plan)
    assert got.depth_mm == pytest.approx(7.0, abs=1e-3) and got.binding == 0
    assert plan_document(plan)["landmarks"] == [ball.to_plan_item()]
    assert bind_to_grid((ball,), np.eye(4), (1, 1, 1)) == (ball,)
    from ctdrill.imaging.plan.merge import _same_landmark

    assert _same_landmark(ball, Ball("other", ball.centre_lps, 1.0))
    assert not _same_landmark(ball, ball.with_margin(0.5))
