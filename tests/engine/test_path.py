"""plan_path on in-memory volumes with known answers: layered slabs, stops, refusals."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from ctdrill.engine.path import PathInputError, plan_path
from ctdrill.engine.plans import plan_calibration, plan_calibration_key
from ctdrill.imaging.plan.landmarks import CanalLandmark, MaskLandmark
from ctdrill.imaging.plan.load import load_plan
from ctdrill.imaging.plan.types import DrillSpec, Plan, series_uid_hash
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
    assert res.binding_landmark == 0 and res.binding_margin_mm == 2.0
    assert res.clearance_mm.shape == (res.depth_mm.size, 1)
    assert "plan_default" not in [w.code for w in res.warnings]
    noted = replace(_plan(landmarks=(canal,)), notes=("plan.json: a default was used",))
    warned = plan_path(slabs, noted, load_calibration("bone-illustrative")).warnings
    assert ("plan_default", "plan.json: a default was used") in [
        (w.code, w.message) for w in warned
    ]
    # signed distance to the core minus the radius: past contact the deepest core point is on
    # the axis, -(x - 4) R / sqrt(R^2 + l_t^2) inside the cone
    d = res.depth_mm
    inside = -(d - 4.0) * R_MM / math.hypot(R_MM, LT_MM)
    want = np.where(d <= 4.0, 4.0 - d, inside) - 0.5
    np.testing.assert_allclose(res.clearance_mm[:, 0], want, atol=1e-7)
    # the planned path (5 mm) runs into the canal: it says so
    assert res.plan_clearance_mm == pytest.approx(want[-1], abs=1e-7) and want[-1] < 0.0
    codes = [w.code for w in res.warnings]
    assert codes.count("plan_violates_margin") == 1 and "margin_below_clinical" not in codes


def test_out_of_volume_stop_where_the_lip_leaves_through_the_bottom(slabs: CTVolume) -> None:
    res = plan_path(slabs, _plan(depth_mm=8.0), load_calibration("bone-illustrative"), n_rings=4)
    # The tip point (radius 0, the deepest point of the lip) reaches the last slice plane.
    z_last = Z0 + DZ * (N_SLICES - 1)
    assert res.stop_reason == "out_of_volume"
    assert res.out_of_volume_depth_mm == pytest.approx(z_last, abs=1e-9)
    assert res.stop_depth_mm == res.out_of_volume_depth_mm
    assert "out_of_volume" in [w.code for w in res.warnings]


def _dense_lip_inside(vol: CTVolume, plan: Plan, depth_mm: float) -> bool:
    """The lip sampled on 400 rings x 720 angles plus its rim and tip lies in the hull."""
    axis = plan.target_lps - plan.entry_lps
    axis = axis / np.linalg.norm(axis)
    e1 = np.cross(axis, [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(axis, e1)
    r = np.linspace(0.0, R_MM, 401)[:, None]
    th = np.linspace(0.0, 2 * np.pi, 721)[None, :]
    xi = depth_mm - LT_MM * r / R_MM
    pts = (
        plan.entry_lps
        + (xi[..., None] * axis)
        + r[..., None] * (np.cos(th)[..., None] * e1 + np.sin(th)[..., None] * e2)
    )
    return bool(np.all(vol.inside(pts.reshape(-1, 3))))


@pytest.mark.parametrize("tilt_deg", [45.0, 60.0])
def test_out_of_volume_stop_where_the_lip_leaves_through_a_side_face(
    slabs: CTVolume, tilt_deg: float
) -> None:
    # Towards +x at tilt_deg from +z, from (0, 0, 0.5): the lip leaves through the face
    # x = 4 mm (the last column) where its outer rim's highest point reaches it.
    a = math.radians(tilt_deg)
    u = np.array([math.sin(a), 0.0, math.cos(a)])
    entry = np.array([0.0, 0.0, 0.5])
    plan = replace(_plan(), entry_lps=entry, target_lps=entry + 8.0 * u)
    res = plan_path(slabs, plan, load_calibration("bone-illustrative"))
    # Highest x on the lip at depth x: x sin a + max(0, R cos a - l_t sin a) (rim at r = R).
    want = (4.0 - max(0.0, R_MM * math.cos(a) - LT_MM * math.sin(a))) / math.sin(a)
    assert res.stop_reason == "out_of_volume"
    assert res.out_of_volume_depth_mm == pytest.approx(want, abs=1e-9)
    # and against a brute-force lip, independent of the closed form: inside 1e-3 mm before,
    # outside 1e-3 mm after
    assert _dense_lip_inside(slabs, plan, want - 1e-3)
    assert not _dense_lip_inside(slabs, plan, want + 1e-3)


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


def _without_slices(vol: CTVolume, drop: slice) -> CTVolume:
    """``vol`` with the slices ``drop`` deleted (the others keep their true positions)."""
    keep = np.ones(vol.hu.shape[0], dtype=bool)
    keep[drop] = False
    return CTVolume(
        hu=vol.hu[keep],
        affine_lps=vol.affine_lps,
        valid=None,
        info=vol.info,
        slice_positions_mm=vol.slice_positions_mm[keep],
    )


def test_deleted_slices_off_the_path_change_nothing(slabs: CTVolume) -> None:
    # 5 slices deleted at z ~ 5.0 mm, below a 3 mm path whose lip ends at z = 3 mm: the median
    # step affine would shift every slice after them; true positions keep the profile exact.
    cal = load_calibration("bone-illustrative")
    gapped = _without_slices(slabs, slice(3000, 3005))
    assert not gapped.regular
    ref = plan_path(slabs, _plan(depth_mm=3.0), cal)
    res = plan_path(gapped, _plan(depth_mm=3.0), cal)
    np.testing.assert_array_equal(res.lip.hu, ref.lip.hu)
    np.testing.assert_array_equal(res.profile.s0_n, ref.profile.s0_n)
    assert res.interpolated_gaps == ()
    assert "gap_interpolated" not in [w.code for w in res.warnings]


def test_a_gap_crossed_by_the_lip_is_refused_or_interpolated_on_request(slabs: CTVolume) -> None:
    cal = load_calibration("bone-illustrative")
    # slices 2000..2004 (z = 2.999 .. 3.007) deleted: a gap of 6 DZ between z = 2.997 and 3.009
    gapped = _without_slices(slabs, slice(2000, 2005))
    with pytest.raises(PathInputError) as err:
        plan_path(gapped, _plan(), cal)
    # the lip [x - 0.6, x] reaches into (2.997, 3.009) for 2.997 < x < 3.609
    msg = str(err.value)
    assert "slice gap of 0.012 mm between the slices at 2.997 and 3.009 mm" in msg
    assert "tip depths 2.997..3.609 mm" in msg and "--interpolate-gaps" in msg
    res = plan_path(gapped, _plan(), cal, interpolate_gaps=True)
    (gap,) = res.interpolated_gaps
    assert (gap.lower_mm, gap.upper_mm) == pytest.approx((2.997, 3.009), abs=1e-9)
    assert (gap.depth_from_mm, gap.depth_to_mm) == pytest.approx((2.997, 3.609), abs=1e-9)
    codes = [w.code for w in res.warnings]
    assert codes.count("gap_interpolated") == 1
    # interpolated exactly between the two real slices: HU at z = 3.003 (the gap's middle) is
    # the mean of 40 (z = 2.997) and 1500 (z = 3.009)
    mid = gapped.sample(np.array([[0.0, 0.0, 3.003]]))
    assert mid[0] == pytest.approx(0.5 * (40.0 + 1500.0), abs=1e-9)
    # a path that stops above the gap (the lip reaches z = 2.99 at most) is exact
    assert plan_path(gapped, _plan(depth_mm=2.99), cal).interpolated_gaps == ()


def test_each_warning_once(slabs: CTVolume) -> None:
    from ctdrill.imaging.volume import LoadWarning

    twice = (LoadWarning("nonuniform_spacing", "x"),) * 2 + (LoadWarning("padding", "y"),)
    vol = replace_warnings(slabs, twice)
    res = plan_path(vol, _plan(depth_mm=2.0), load_calibration("bone-illustrative"))
    pairs = [(w.code, w.message) for w in res.warnings]
    assert len(pairs) == len(set(pairs))
    assert pairs.count(("nonuniform_spacing", "x")) == 1


def replace_warnings(vol: CTVolume, warnings: tuple[object, ...]) -> CTVolume:
    return CTVolume(
        hu=vol.hu,
        affine_lps=vol.affine_lps,
        valid=vol.valid,
        info=vol.info,
        warnings=warnings,  # type: ignore[arg-type]
        slice_positions_mm=vol.slice_positions_mm,
    )


def test_mask_landmark_from_a_plan_file_on_the_ct_grid(slabs: CTVolume, tmp_path: Path) -> None:
    # A bar of voxels along x at y = 0 with centres 3.5 <= z <= 4.5 mm: the first labelled
    # slice is centred at z = 3.501 mm, so its boxes start at 3.500 mm (half a 0.002 mm slice
    # above their centres) and the 2 mm margin allows 1.500 mm, not 1.501 (voxel centres).
    z = Z0 + DZ * np.arange(N_SLICES)
    labels = np.zeros(slabs.hu.shape, dtype=np.uint8)
    labels[(z >= 3.5) & (z <= 4.5), 4, :] = 5
    np.save(tmp_path / "canal.npy", labels)
    doc = {
        "format": "ctdrill-plan/1",
        "entry_mm": [0.0, 0.0, 0.0],
        "target_mm": [0.0, 0.0, 5.0],
        "drill": {"diameter_mm": 2 * R_MM, "tip_length_mm": LT_MM},
        "landmarks": [
            {
                "name": "segmented canal",
                "kind": "mask",
                "path": "canal.npy",
                "label": 5,
                "axes": "kji",
            }
        ],
    }
    (tmp_path / "plan.json").write_text(json.dumps(doc), encoding="utf-8")
    plan = load_plan(tmp_path / "plan.json")
    res = plan_path(slabs, plan, load_calibration("bone-illustrative"))
    assert res.stop_reason == "margin"
    assert res.stop_depth_mm == pytest.approx(3.5 - 2.0, abs=1e-3)
    assert res.stop_depth_mm <= 1.5
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


def test_margin_warnings_and_the_series_check(slabs: CTVolume) -> None:
    cal = load_calibration("bone-illustrative")
    canal = CanalLandmark("canal", [[-10.0, 0.0, 9.0], [10.0, 0.0, 9.0]], radius_mm=0.5)
    safe = _plan(landmarks=(canal,))  # 5 mm deep, the canal 9 mm deep: 3.5 mm of clearance

    def codes(plan: Plan) -> list[str]:
        return [w.code for w in plan_path(slabs, plan, cal).warnings]

    assert "margin_below_clinical" not in codes(safe)
    assert "plan_violates_margin" not in codes(safe)
    for margin in (0.0, 1.5, 1.999):
        low = replace(safe, margin_mm=margin)
        assert codes(low).count("margin_below_clinical") == 1
    own = replace(safe, landmarks=(canal.with_margin(0.5),))  # a landmark's own margin counts
    res = plan_path(slabs, own, cal)
    (msg,) = [w.message for w in res.warnings if w.code == "margin_below_clinical"]
    assert "0.5 mm" in msg and "clinical 2 mm" in msg
    assert res.plan_clearance_mm == pytest.approx(3.5, abs=1e-7)
    # a plan made on this series: no warning; on another: plan_other_series, once
    mine = replace(safe, series_uid_sha256=series_uid_hash("1.2.3"))
    other = replace(safe, series_uid_sha256=series_uid_hash("1.2.4"))
    assert "plan_other_series" not in codes(mine)
    assert codes(other).count("plan_other_series") == 1
