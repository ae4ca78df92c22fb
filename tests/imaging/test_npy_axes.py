"""A ``.npy`` labelmap carries no geometry and no axis order: stated, or refused where another
order would fit the CT grid.

The demo CT is (80, 100, 80) (slices, rows, cols): as many columns as slices, like any cubic
CBCT. A mask saved in nibabel's (cols, rows, slices) order has the same shape, and used to be
taken as (slices, rows, cols): the canal moved and the drill went to the planned depth. Now
such a file needs ``"axes"``; with it, both orders give the same stop.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from ctdrill import api
from ctdrill.imaging.plan.landmarks import LandmarkInputError
from ctdrill.imaging.plan.types import PlanInputError
from tests.conftest import ASSETS
from tests.robustness.outcomes import error_line_problems, run_cli_in_process

DEMO_CT = ASSETS / "demo" / "ct"


@pytest.fixture(scope="module")
def demo() -> api.CTVolume:
    return api.load_ct(DEMO_CT)


def _canal_kji(volume: api.CTVolume) -> np.ndarray:
    """A block of 'canal' below the demo drill (voxel centres 2-4 mm below its target)."""
    k, j, i = np.indices(volume.hu.shape)
    ijk1 = np.stack([i, j, k, np.ones_like(i)], axis=-1).astype(np.float64)
    lps = ijk1 @ volume.affine_lps.T
    x, y, z = lps[..., 0], lps[..., 1], lps[..., 2]
    box = (np.abs(x - 32.0) < 4.0) & (np.abs(y - 10.0) < 4.0) & (z < -43.0) & (z > -45.0)
    return box.astype(np.uint8) * 3


def _plan(tmp_path: Path, mask: np.ndarray, **extra: object) -> Path:
    np.save(tmp_path / "canal.npy", mask)
    doc = json.loads((ASSETS / "demo" / "plan.json").read_text())
    doc.pop("implant", None)
    doc.pop("series_uid_sha256", None)
    doc["landmarks"] = [{"name": "canal", "kind": "mask", "path": "canal.npy", **extra}]
    path = tmp_path / "plan.json"
    path.write_text(json.dumps(doc))
    return path


def test_an_ambiguous_npy_is_refused_and_a_stated_order_gives_one_answer(
    tmp_path: Path, demo: api.CTVolume
) -> None:
    kji = _canal_kji(demo)
    ijk = np.ascontiguousarray(kji.transpose(2, 1, 0))
    assert kji.shape == ijk.shape == demo.hu.shape  # the trap: both fit
    for arr in (kji, ijk):
        plan = api.load_plan(_plan(tmp_path, arr))
        with pytest.raises(LandmarkInputError, match=r"in more than one axis order.*\"axes\""):
            api.plan_path(demo, plan)
    stops = []
    for arr, axes in ((kji, "kji"), (ijk, "ijk")):
        plan = api.load_plan(_plan(tmp_path, arr, axes=axes))
        result = api.plan_path(demo, plan)
        stops.append((result.stop_reason, round(result.stop_depth_mm, 6)))
    assert stops[0] == stops[1] and stops[0][0] == "margin" and stops[0][1] < 12.0


def test_an_npy_in_another_order_on_an_unambiguous_grid_names_axes(tmp_path: Path) -> None:
    grid = (60, 100, 80)  # (slices, rows, cols): no two sizes equal
    mask = np.zeros((80, 100, 60), dtype=np.uint8)  # (cols, rows, slices)
    mask[40, 50, 30] = 1
    (lm,) = api.load_plan(_plan(tmp_path, mask)).landmarks
    with pytest.raises(LandmarkInputError, match=r"in another axis order; say which with \"axes\""):
        lm.on_grid(np.eye(4), grid)
    plan = api.load_plan(_plan(tmp_path, mask, axes="ijk"))
    (lm,) = plan.landmarks
    assert lm.mask.shape == grid and lm.mask[30, 50, 40]
    assert lm.on_grid(np.eye(4), grid).affine_lps is not None


def test_axes_is_checked_and_only_for_npy(tmp_path: Path) -> None:
    with pytest.raises(PlanInputError, match=r"axes must be \"kji\".*\"ijk\""):
        api.load_plan(_plan(tmp_path, np.ones((2, 2, 2), np.uint8), axes="xyz"))
    from tests.imaging.volume_writers import oblique_affine, write_nrrd

    write_nrrd(tmp_path / "m.nrrd", np.ones((2, 3, 4), np.uint8), oblique_affine())
    path = _plan(tmp_path, np.ones((2, 2, 2), np.uint8), axes="kji")
    doc = json.loads(path.read_text())
    doc["landmarks"][0]["path"] = "m.nrrd"
    path.write_text(json.dumps(doc))
    with pytest.raises(LandmarkInputError, match=r"m\.nrrd: this file carries its own geometry"):
        api.load_plan(path)


def test_the_cli_refuses_an_ambiguous_npy_with_one_line(tmp_path: Path, demo: api.CTVolume) -> None:
    kji = _canal_kji(demo)
    plan = _plan(tmp_path, np.ascontiguousarray(kji.transpose(2, 1, 0)))
    run = run_cli_in_process(
        ["export", "--dicom", str(DEMO_CT), "--plan", str(plan), "--out", str(tmp_path / "o")]
    )
    assert not error_line_problems(run), error_line_problems(run)
    assert "canal.npy" in run.stderr and '"axes"' in run.stderr
    assert not (tmp_path / "o").exists()
