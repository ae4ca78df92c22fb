"""plan_path on in-memory volumes with known answers: layered slabs, stops, refusals."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from ctdrill.app.pipeline import PathInputError, plan_calibration, plan_calibration_key, plan_path
from ctdrill.imaging.plan.landmarks import CanalLandmark, MaskLandmark
from ctdrill.imaging.plan.types import DrillSpec, Plan, load_plan
from ctdrill.imaging.volume import CTVolume, SeriesInfo
from ctdrill.model.calibration import load_calibration
from ctdrill.model.layered import layered_profile
from ctdrill.model.profile import force_n

DZ = 0.002  # slice spacing, mm: the trilinear blur between slabs spans one slice
Z0 = -1.001  # first slice centre; the slab boundaries fall half-way between slice centres
N_SLICES = 3501
#: (top depth, HU) of each slab along +z from the entry at z = 0; air above 1 mm.
SLABS = ((1.0, 800.0), (2.5, 40.0), (3.0, 1500.0), (4.5, 300.0))
BOUNDARIES = (1.0, 2.5, 3.0, 4.5, 6.0)
R_MM, LT_MM = 1.0, 0.6


def _hu_of_z(z: np.ndarray) -> np.ndarray:
    hu = np.full(z.shape, -1000.0)
    for (top, value), bottom in zip(SLABS, BOUNDARIES[1:], strict=True):
        hu = np.where((z >= top) & (z < bottom), value, hu)
    return hu


def _volume(
    *,
    n_slices: int = N_SLICES,
    valid: np.ndarray | None = None,
    positions: np.ndarray | None = None,
    is_hu: bool = True,
) -> CTVolume:
    z = Z0 + DZ * np.arange(n_slices)
    hu = np.broadcast_to(_hu_of_z(z)[:, None, None], (n_slices, 9, 9)).astype(np.int16)
    affine = np.array(
        [[1.0, 0.0, 0.0, -4.0], [0.0, 1.0, 0.0, -4.0], [0.0, 0.0, DZ, Z0], [0.0, 0.0, 0.0, 1.0]]
    )
    return CTVolume(
        hu=hu,
        affine_lps=affine,
        valid=valid,
        info=SeriesInfo(series_uid="1.2.3", is_hu=is_hu),
        slice_positions_mm=np.empty(0) if positions is None else positions,
    )


def _plan(depth_mm: float = 5.0, landmarks: tuple[CanalLandmark, ...] = ()) -> Plan:
    return Plan(
        entry_lps=np.array([0.0, 0.0, 0.0]),
        target_lps=np.array([0.0, 0.0, depth_mm]),
        drill=DrillSpec(diameter_mm=2 * R_MM, tip_length_mm=LT_MM, blades=2, rpm=900.0),
        feed_mm_s=0.5,
        calibration="bone-illustrative",
        landmarks=landmarks,
        name="slabs",
    )


@pytest.fixture(scope="module")
def slabs() -> CTVolume:
    return _volume()


def test_layered_force_matches_the_paper_equations(slabs: CTVolume) -> None:
    cal = load_calibration("bone-illustrative")
    n_rings = 400
    res = plan_path(slabs, _plan(), cal, n_rings=n_rings, n_angles=3)
    prof = res.profile
    exact = layered_profile(
        BOUNDARIES,
        [hu for _, hu in SLABS],
        res.depth_mm,
        cal,
        tip_length_mm=LT_MM,
        blades=2,
        rpm=900.0,
    )
    # Error bound per slab edge inside the lip (at most 2): one ring of the midpoint rule
    # (1 / n_rings) plus the trilinear ramp between the two slices around the edge (DZ / LT).
    tol = 2 * (1 / n_rings + DZ / LT_MM)
    assert tol < 0.012
    np.testing.assert_allclose(prof.s_t, exact.s_t, atol=tol)
    np.testing.assert_allclose(prof.s0_n, exact.s0_n, atol=tol * float(np.max(exact.s0_n)))
    np.testing.assert_allclose(prof.sk_n, exact.sk_n, atol=tol * float(np.max(exact.sk_n)))
    # Eq. 2-4 (contact state): the cut fraction grows linearly while the cone enters the slab.
    x = res.depth_mm
    contact = (x > 1.05) & (x < 1.55)
    np.testing.assert_allclose(prof.s_t[contact], (x[contact] - 1.0) / LT_MM, atol=tol / 2)
    # Fully engaged in the 1500 HU slab: Eq. 19 with s_t = 1, written out by hand.
    cp = 1500.0 + 1000.0
    a0 = 10**-5.9535 * cp**2.0
    b1 = 10**5.9638 * cp**-1.91
    b2 = 10**3.1928 * cp**-1.29
    i = int(np.argmin(np.abs(x - 4.0)))
    assert prof.s_t[i] == pytest.approx(1.0, abs=1e-12)
    assert prof.s0_n[i] == pytest.approx(a0, rel=1e-9)
    np.testing.assert_allclose(prof.sk_n[:, i], [b1, b2], rtol=1e-9)
    v, t = 0.5, 0.0123
    f1, f2 = 30.0, 60.0
    want = (
        a0 * (1 + 0.25 * v)
        + b1 * math.sin(2 * math.pi * f1 * t)
        + b2 * math.sin(2 * math.pi * f2 * t)
    )
    assert force_n(prof, float(x[i]), v, t) == pytest.approx(want, rel=1e-9)
    # Soft tissue (40 HU) is below the gate: at x = 3.0 the lip spans [2.4, 3.0] and cuts
    # only the last 0.1 mm of the 800 HU slab.
    j = int(np.argmin(np.abs(x - 3.0)))
    assert prof.s_t[j] == pytest.approx(0.1 / LT_MM, abs=tol)
    assert res.stop_reason == "planned_depth" and res.stop_depth_mm == pytest.approx(5.0)
    assert res.out_of_volume_depth_mm is None and res.min_clearance_mm is None
    assert "calibration_illustrative" in [w.code for w in res.warnings]


def test_margin_stop_is_the_exact_safe_depth(slabs: CTVolume) -> None:
    canal = CanalLandmark("canal", [[-10.0, 0.0, 4.0], [10.0, 0.0, 4.0]], radius_mm=0.5)
    res = plan_path(slabs, _plan(landmarks=(canal,)), load_calibration("bone-illustrative"))
    assert res.stop_reason == "margin"
    assert res.stop_depth_mm == pytest.approx(4.0 - 0.5 - 2.0, abs=1e-3)
    assert res.stop_depth_mm <= 1.5
    assert res.min_clearance_mm == pytest.approx(2.0, abs=1e-3)
    assert res.nearest_landmark == 0
    assert res.clearance_mm.shape == (res.depth_mm.size, 1)
    assert "plan_default" not in [w.code for w in res.warnings]
    noted = replace(_plan(landmarks=(canal,)), notes=("plan.json: a default was used",))
    warned = plan_path(slabs, noted, load_calibration("bone-illustrative")).warnings
    assert ("plan_default", "plan.json: a default was used") in [
        (w.code, w.message) for w in warned
    ]
    # distance to the core (0 once inside it) minus the radius
    want = np.maximum(4.0 - res.depth_mm, 0.0) - 0.5
    np.testing.assert_allclose(res.clearance_mm[:, 0], want, atol=1e-9)


def test_out_of_volume_stop_where_the_lip_leaves_the_grid(slabs: CTVolume) -> None:
    n_rings = 4
    res = plan_path(
        slabs, _plan(depth_mm=8.0), load_calibration("bone-illustrative"), n_rings=n_rings
    )
    z_last = Z0 + DZ * (N_SLICES - 1)
    # the deepest lip sample is the innermost ring, at x - l_t * r0 / R with r0 = R / (2 n)
    want = z_last + LT_MM / (2 * n_rings)
    assert res.stop_reason == "out_of_volume"
    assert res.out_of_volume_depth_mm == pytest.approx(want, abs=1.5e-3)
    assert res.stop_depth_mm == res.out_of_volume_depth_mm
    assert "out_of_volume" in [w.code for w in res.warnings]


def test_refusals_name_the_problem() -> None:
    cal = load_calibration("bone-illustrative")
    with pytest.raises(PathInputError, match="single slice is not a volume"):
        plan_path(_volume(n_slices=1), _plan(), cal)
    with pytest.raises(PathInputError, match="not Hounsfield units"):
        plan_path(_volume(is_hu=False), _plan(), cal)
    valid = np.ones((N_SLICES, 9, 9), dtype=bool)
    valid[1500:1510, 4, 4] = False  # padding on the axis at z ~ 2 mm
    with pytest.raises(PathInputError, match="crosses padding"):
        plan_path(_volume(valid=valid), _plan(), cal)
    valid = np.ones((N_SLICES, 9, 9), dtype=bool)
    valid[:, 0, 0] = False  # padding in a corner, away from the drill: fine
    assert plan_path(_volume(valid=valid), _plan(), cal).stop_reason == "planned_depth"
    huge = CanalLandmark("c", [[0.0, 0.0, 1e308], [0.0, 1.0, 1e308]])
    with pytest.raises(PathInputError, match="a coordinate is not finite or beyond"):
        plan_path(_volume(), _plan(landmarks=(huge,)), cal)
    with pytest.raises(PathInputError, match="planned depth 1000 mm exceeds 200 mm"):
        plan_path(_volume(), _plan(depth_mm=1000.0), cal)
    far = Plan(entry_lps=[50.0, 0.0, 0.0], target_lps=[50.0, 0.0, 5.0], name="far")
    with pytest.raises(PathInputError, match="lies outside the CT volume"):
        plan_path(_volume(), far, cal)


def test_slice_gap_refused_on_the_path_and_a_warning_off_it() -> None:
    cal = load_calibration("bone-illustrative")
    z = Z0 + DZ * np.arange(N_SLICES)
    gap_on_path = z.copy()
    gap_on_path[2000:] += DZ  # a missing slice between z = 2.997 and 3.001
    with pytest.raises(PathInputError, match="irregular slice step"):
        plan_path(_volume(positions=gap_on_path), _plan(), cal)
    # the same gap beyond a 2 mm trajectory (the lip reaches z = 2 mm at most)
    res = plan_path(_volume(positions=gap_on_path), _plan(depth_mm=2.0), cal)
    assert res.stop_reason == "planned_depth"
    assert "nonuniform_spacing" in [w.code for w in res.warnings]


def test_mask_landmark_from_a_plan_file_on_the_ct_grid(slabs: CTVolume, tmp_path: Path) -> None:
    # A bar of voxels along x at y = 0 with 3.5 <= z <= 4.5 mm: the voxel centre nearest to
    # the drill sits on the axis at z = 3.501 mm, so the 2 mm margin allows 1.501 mm.
    z = Z0 + DZ * np.arange(N_SLICES)
    labels = np.zeros(slabs.hu.shape, dtype=np.uint8)
    labels[(z >= 3.5) & (z <= 4.5), 4, :] = 5
    np.save(tmp_path / "canal.npy", labels)
    doc = {
        "format": "ctdrill-plan/1",
        "entry_mm": [0.0, 0.0, 0.0],
        "target_mm": [0.0, 0.0, 5.0],
        "drill": {"diameter_mm": 2 * R_MM, "tip_length_mm": LT_MM},
        "landmarks": [{"name": "segmented canal", "kind": "mask", "path": "canal.npy", "label": 5}],
    }
    (tmp_path / "plan.json").write_text(json.dumps(doc), encoding="utf-8")
    plan = load_plan(tmp_path / "plan.json")
    res = plan_path(slabs, plan, load_calibration("bone-illustrative"))
    assert res.stop_reason == "margin"
    assert res.stop_depth_mm == pytest.approx(3.501 - 2.0, abs=1e-3)
    assert res.stop_depth_mm <= 1.501 + 1e-9
    lm = res.landmarks[0]
    assert isinstance(lm, MaskLandmark) and lm.affine_lps is not None


def test_plan_calibration_is_a_bundled_name_or_a_path_beside_the_plan(tmp_path: Path) -> None:
    root = Path(__file__).resolve().parents[2]
    doc = json.loads((root / "assets" / "demo" / "plan.json").read_text())
    bundled = root / "assets" / "calibration" / "pine-wood-paper.json"
    (tmp_path / "sets").mkdir()
    (tmp_path / "sets" / "mine.json").write_text(bundled.read_text())
    plan_file = tmp_path / "plan.json"
    plan_file.write_text(json.dumps({**doc, "calibration": "sets/mine.json"}))
    plan = load_plan(plan_file)
    assert plan_calibration_key(plan) == str(tmp_path / "sets" / "mine.json")
    assert plan_calibration(plan).name == "pine-wood-paper"
    named = replace(plan, calibration="bone-illustrative")
    assert plan_calibration_key(named) == "bone-illustrative"
    assert plan_calibration(named).name == "bone-illustrative"
