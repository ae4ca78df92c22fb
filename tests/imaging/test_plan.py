"""Plan files: ctdrill-plan/1 and Slicer markups, RAS conversion, validation, round trips."""

from __future__ import annotations

import copy
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from ctdrill.imaging.plan.landmarks import (
    DEFAULT_CANAL_RADIUS_MM,
    CanalLandmark,
    LandmarkInputError,
    MaskLandmark,
    PointLandmark,
    bind_to_grid,
)
from ctdrill.imaging.plan.load import load_plan, load_plans
from ctdrill.imaging.plan.types import DrillSpec, Plan, PlanInputError
from ctdrill.imaging.plan.write import save_plan
from tests.imaging.slicer_files import validate_markups

BASE: dict[str, Any] = {
    "format": "ctdrill-plan/1",
    "coordinate_system": "LPS",
    "entry_mm": [10.0, 20.0, 30.0],
    "target_mm": [10.0, 20.0, 18.0],
    "drill": {"diameter_mm": 2.0, "tip_length_mm": 0.6, "blades": 2, "rpm": 900},
    "feed_mm_s": 0.4,
    "calibration": "pine-wood-paper",
    "margin_mm": 2.0,
    "landmarks": [
        {
            "name": "left mandibular canal",
            "kind": "canal",
            "points_mm": [[0.0, 20.0, 10.0], [20.0, 20.0, 10.0]],
            "radius_mm": 1.2,
        },
        {"name": "apex", "kind": "point", "point_mm": [14.0, 20.0, 20.0], "margin_mm": 1.5},
    ],
}


def _write(tmp_path: Path, doc: object, name: str = "plan.json") -> Path:
    path = tmp_path / name
    path.write_text(json.dumps(doc), encoding="utf-8")
    return path


def test_ctdrill_plan_parses_every_field(tmp_path: Path) -> None:
    plan = load_plan(_write(tmp_path, BASE))
    np.testing.assert_array_equal(plan.entry_lps, [10.0, 20.0, 30.0])
    np.testing.assert_array_equal(plan.target_lps, [10.0, 20.0, 18.0])
    assert plan.drill == DrillSpec(diameter_mm=2.0, tip_length_mm=0.6, blades=2, rpm=900.0)
    assert plan.planned_depth_mm == pytest.approx(12.0)
    np.testing.assert_allclose(plan.direction, [0.0, 0.0, -1.0])
    assert plan.feed_mm_s == 0.4 and plan.calibration == "pine-wood-paper"
    assert plan.name == "plan"
    canal, apex = plan.landmarks
    assert isinstance(canal, CanalLandmark) and canal.radius_mm == 1.2
    assert canal.margin_mm is None and plan.landmark_margin_mm(canal) == 2.0
    assert isinstance(apex, PointLandmark) and plan.landmark_margin_mm(apex) == 1.5
    assert not plan.entry_lps.flags.writeable
    assert plan.notes == ()
    doc = copy.deepcopy(BASE)
    del doc["landmarks"][0]["radius_mm"]
    plan = load_plan(_write(tmp_path, doc))
    assert plan.landmarks[0].radius_mm == DEFAULT_CANAL_RADIUS_MM
    assert plan.notes == (
        "plan.json: landmarks[0] (left mandibular canal) has no radius_mm; using the default "
        "1.2 mm",
    )


def test_ras_plan_negates_x_and_y(tmp_path: Path) -> None:
    doc = copy.deepcopy(BASE)
    doc["coordinate_system"] = "RAS"
    plan = load_plan(_write(tmp_path, doc))
    np.testing.assert_array_equal(plan.entry_lps, [-10.0, -20.0, 30.0])
    np.testing.assert_array_equal(plan.target_lps, [-10.0, -20.0, 18.0])
    canal = plan.landmarks[0]
    assert isinstance(canal, CanalLandmark)
    np.testing.assert_array_equal(canal.points_lps, [[-0.0, -20.0, 10.0], [-20.0, -20.0, 10.0]])
    apex = plan.landmarks[1]
    assert isinstance(apex, PointLandmark)
    np.testing.assert_array_equal(apex.point_lps, [-14.0, -20.0, 20.0])


def test_defaults_when_optional_fields_are_missing(tmp_path: Path) -> None:
    doc = {"format": "ctdrill-plan/1", "entry_mm": [0, 0, 0], "target_mm": [0, 0, 5]}
    plan = load_plan(_write(tmp_path, doc))
    assert plan.drill == DrillSpec()
    assert plan.calibration == "bone-literature"
    assert plan.margin_mm == 2.0 and plan.feed_mm_s == 0.4 and plan.landmarks == ()


def _mutate(path: str, value: object) -> dict[str, Any]:
    doc = copy.deepcopy(BASE)
    keys = path.split(".")
    node: Any = doc
    for k in keys[:-1]:
        node = node[int(k)] if isinstance(node, list) else node[k]
    last: Any = int(keys[-1]) if isinstance(node, list) else keys[-1]
    if value is _DELETE:
        del node[last]
    else:
        node[last] = value
    return doc


_DELETE = object()


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("format", "ctdrill-plan/2", "format must be \"ctdrill-plan/1\", got 'ctdrill-plan/2'"),
        ("coordinate_system", "XYZ", 'coordinate_system must be "LPS" or "RAS"'),
        ("entry_mm", _DELETE, "entry_mm is missing"),
        ("target_mm", [1, 2], "target_mm must be a list of 3 finite numbers"),
        ("target_mm", [10.0, 20.0, 30.0], "target_mm must differ from the entry point"),
        ("entry_mm", [1, "a", 3], "entry_mm must be a list of 3 finite numbers"),
        ("entry_mm", [10**400, 0, 0], "entry_mm must be a list of 3 finite numbers"),
        ("margin_mm", 10**400, "margin_mm must be a number >= 0"),
        ("entry_mm", [1e308, 0, 0], "entry_mm must be a list of 3 finite numbers"),
        ("landmarks.0.points_mm.1.2", 1e6, "landmarks[0].points_mm[1] must be a list of 3"),
        (
            "drill.diameter_mm",
            1e308,
            "drill.diameter_mm must be at most 50 (check the units), got 1e+308",
        ),
        ("drill.blades", 1000, "drill.blades must be at most 100, got 1000"),
        ("landmarks.0.radius_mm", 5000, "landmarks[0].radius_mm must be at most 1000"),
        ("landmarks.0.kind", ["canal"], 'landmarks[0].kind must be "canal", "point" or "mask"'),
        ("drill", 3, "drill must be an object"),
        ("drill.diameter_mm", -2, "drill.diameter_mm must be a positive number, got -2"),
        ("drill.diameter_mm", True, "drill.diameter_mm must be a positive number, got True"),
        ("drill.tip_length_mm", 0, "drill.tip_length_mm must be a positive number, got 0"),
        ("drill.blades", 1.5, "drill.blades must be a positive whole number, got 1.5"),
        ("drill.rpm", "fast", "drill.rpm must be a positive number, got 'fast'"),
        ("drill.diamter_mm", 2, "drill.diamter_mm is not a known field"),
        ("feed_mm_s", 0, "feed_mm_s must be a positive number, got 0"),
        ("calibration", "", "calibration must be a non-empty string"),
        ("margin_mm", -1, "margin_mm must be a number >= 0, got -1"),
        ("landmarks", {}, "landmarks must be a list"),
        ("landmarks.0", "canal", "landmarks[0] must be an object"),
        ("landmarks.0.kind", "nerve", 'landmarks[0].kind must be "canal", "point" or "mask"'),
        ("landmarks.0.points_mm", [], "landmarks[0].points_mm must be a non-empty list"),
        ("landmarks.0.points_mm", [[0, 0]], "landmarks[0].points_mm[0] must be a list of 3"),
        ("landmarks.0.radius_mm", -1.2, "landmarks[0].radius_mm must be a number >= 0"),
        ("landmarks.0.margin_mm", "x", "landmarks[0].margin_mm must be a number >= 0"),
        ("landmarks.0.colour", "red", "landmarks[0].colour is not a known field"),
        ("landmarks.1.point_mm", _DELETE, "landmarks[1].point_mm is missing"),
        ("landmarks.1.name", 5, "landmarks[1].name must be a non-empty string"),
        ("extra", 1, "extra is not a known field"),
    ],
)
def test_every_validation_error_names_file_and_field(
    tmp_path: Path, field: str, value: object, message: str
) -> None:
    path = _write(tmp_path, _mutate(field, value))
    with pytest.raises(PlanInputError) as info:
        load_plan(path)
    assert str(info.value).startswith("plan.json: ")
    assert message in str(info.value)


def test_file_level_errors(tmp_path: Path) -> None:
    with pytest.raises(PlanInputError, match="plan file not found"):
        load_plan(tmp_path / "missing.json")
    bad = tmp_path / "bad.json"
    bad.write_text("{not json", encoding="utf-8")
    with pytest.raises(PlanInputError, match=r"bad.json: the plan file is not valid JSON \(line 1"):
        load_plan(bad)
    with pytest.raises(PlanInputError, match="must be a JSON object"):
        load_plan(_write(tmp_path, [1, 2]))
    with pytest.raises(PlanInputError, match="format is missing"):
        load_plan(_write(tmp_path, {"entry_mm": [0, 0, 0]}))


def test_mask_landmark_from_npy_on_the_ct_grid(tmp_path: Path) -> None:
    labels = np.zeros((4, 5, 6), dtype=np.uint8)
    labels[1:3, 2, 1:5] = 3
    labels[0, 0, 0] = 1
    np.save(tmp_path / "canal.npy", labels)
    doc = copy.deepcopy(BASE)
    doc["landmarks"] = [{"name": "seg", "kind": "mask", "path": "canal.npy", "label": 3}]
    plan = load_plan(_write(tmp_path, doc))
    (lm,) = plan.landmarks
    assert isinstance(lm, MaskLandmark) and lm.affine_lps is None
    assert int(lm.mask.sum()) == 8
    affine = np.diag([0.5, 0.5, 2.0, 1.0])
    (bound,) = bind_to_grid(plan.landmarks, affine, (4, 5, 6))
    assert isinstance(bound, MaskLandmark)
    pts = bound.surface_points_lps()
    # A 2 x 1 x 4 bar of voxel boxes: its 28 exposed face centres; (k, j, i) -> (0.5 i, 0.5 j,
    # 2 k): side faces at k = 1, 2, the bottom and top faces at k = 0.5, 2.5.
    assert pts.shape == (28, 3)
    np.testing.assert_allclose(sorted(set(pts[:, 2])), [1.0, 2.0, 4.0, 5.0])
    with pytest.raises(LandmarkInputError, match="does not match the CT grid"):
        bind_to_grid(plan.landmarks, affine, (4, 5, 7))
    doc["landmarks"][0]["path"] = "nothing.npy"
    with pytest.raises(LandmarkInputError, match="mask file not found"):
        load_plan(_write(tmp_path, doc))


SLICER: dict[str, Any] = {
    "@schema": "https://raw.githubusercontent.com/slicer/slicer/master/Modules/Loadable/"
    "Markups/Resources/Schema/markups-schema-v1.0.3.json#",
    "markups": [
        {
            "type": "Line",
            "coordinateSystem": "RAS",
            "description": "diameter_mm=2.5 feed_mm_s=0.6 calibration=pine-wood-paper",
            "controlPoints": [
                {"label": "L-1", "position": [-10.0, -20.0, 30.0]},
                {"label": "L-2", "position": [-10.0, -20.0, 18.0]},
            ],
        },
        {
            "type": "Curve",
            "coordinateSystem": "LPS",
            "name": "IAN canal",
            "description": "radius_mm=1.5 margin_mm=2.5",
            "controlPoints": [
                {"position": [0.0, 20.0, 10.0]},
                {"position": [10.0, 20.0, 10.0]},
                {"position": [20.0, 20.0, 11.0]},
            ],
        },
        {
            "type": "Curve",
            "coordinateSystem": "LPS",
            "controlPoints": [
                {
                    "position": [0.0, 0.0, 0.0],
                    "description": 'tip of the canal radius_mm=0.9 name="canal 3"',
                },
                {"position": [1.0, 0.0, 0.0]},
            ],
        },
        {
            "type": "Curve",
            "name": "canal 4",
            "coordinateSystem": "LPS",
            "controlPoints": [{"position": [5.0, 0.0, 0.0]}],
        },
        {
            "type": "Fiducial",
            "coordinateSystem": "RAS",
            "controlPoints": [
                {"label": "apex 36", "position": [1.0, 2.0, 3.0]},
                {"label": "apex 37", "position": [4.0, 5.0, 6.0]},
            ],
        },
    ],
}


def test_slicer_markups_line_curves_fiducials_and_per_markup_frames(tmp_path: Path) -> None:
    plan = load_plan(_write(tmp_path, SLICER, "case.mrk.json"))
    np.testing.assert_array_equal(plan.entry_lps, [10.0, 20.0, 30.0])  # RAS -> LPS
    np.testing.assert_array_equal(plan.target_lps, [10.0, 20.0, 18.0])
    assert plan.name == "case"
    assert (
        plan.drill.diameter_mm == 2.5 and plan.drill.tip_length_mm == 0.7
    )  # the tip rule for 2.5 mm
    assert plan.feed_mm_s == 0.6 and plan.calibration == "pine-wood-paper"
    assert plan.margin_mm == 2.0
    canal, canal2, canal3, apex36, apex37 = plan.landmarks
    assert isinstance(canal3, CanalLandmark) and canal3.radius_mm == DEFAULT_CANAL_RADIUS_MM
    assert plan.notes == (
        "case.mrk.json: markups[3] (canal 4) gives no radius_mm in its description; using the "
        "default canal radius 1.2 mm",
    )
    assert isinstance(canal, CanalLandmark) and canal.name == "IAN canal"
    assert canal.radius_mm == 1.5 and canal.margin_mm == 2.5
    # LPS kept; the centreline is Slicer's spline sampled 10 times per segment.
    assert canal.points_lps.shape == (21, 3)
    np.testing.assert_array_equal(canal.points_lps[20], [20.0, 20.0, 11.0])
    assert isinstance(canal2, CanalLandmark) and canal2.radius_mm == 0.9  # from a point
    assert canal.radius_mm != DEFAULT_CANAL_RADIUS_MM
    assert isinstance(apex36, PointLandmark) and apex36.name == "apex 36"
    np.testing.assert_array_equal(apex36.point_lps, [-1.0, -2.0, 3.0])
    assert isinstance(apex37, PointLandmark)
    np.testing.assert_array_equal(apex37.point_lps, [-4.0, -5.0, 6.0])


def test_slicer_errors_and_several_lines(tmp_path: Path) -> None:
    doc = copy.deepcopy(SLICER)
    doc["markups"][0]["controlPoints"].pop()
    with pytest.raises(PlanInputError, match=r"markups\[0\].controlPoints of a Line must hold 2"):
        load_plan(_write(tmp_path, doc, "a.mrk.json"))
    doc = copy.deepcopy(SLICER)
    doc["markups"][1]["description"] = "radius_mm=-3"
    with pytest.raises(
        PlanInputError, match=r"markups\[1\].description.radius_mm must be a number >= 0"
    ):
        load_plan(_write(tmp_path, doc, "a.mrk.json"))
    doc = copy.deepcopy(SLICER)
    doc["markups"][1]["description"] = "radius_mm=1 colour=red"
    with pytest.raises(
        PlanInputError, match=r"markups\[1\].description: setting colour is not a setting"
    ):
        load_plan(_write(tmp_path, doc, "a.mrk.json"))
    doc = copy.deepcopy(SLICER)
    doc["markups"][1]["coordinateSystem"] = "IJK"
    with pytest.raises(PlanInputError, match=r"markups\[1\].coordinateSystem must be"):
        load_plan(_write(tmp_path, doc, "a.mrk.json"))
    doc = copy.deepcopy(SLICER)
    doc["markups"] = doc["markups"][1:]
    with pytest.raises(PlanInputError, match=r"a\.mrk\.json: no trajectory"):
        load_plan(_write(tmp_path, doc, "a.mrk.json"))
    doc = copy.deepcopy(SLICER)
    second = copy.deepcopy(doc["markups"][0])
    second["name"] = "implant 2"
    doc["markups"].append(second)
    path = _write(tmp_path, doc, "two.mrk.json")
    plans = load_plans(path)
    assert [p.name for p in plans] == ["two-1", "implant 2"]
    assert plans[0].landmarks == plans[1].landmarks
    with pytest.raises(PlanInputError, match="holds 2 trajectories"):
        load_plan(path)


def _same(a: Plan, b: Plan) -> None:
    np.testing.assert_allclose(a.entry_lps, b.entry_lps)
    np.testing.assert_allclose(a.target_lps, b.target_lps)
    assert a.drill == b.drill
    assert (a.feed_mm_s, a.calibration, a.margin_mm) == (b.feed_mm_s, b.calibration, b.margin_mm)
    assert len(a.landmarks) == len(b.landmarks)
    for la, lb in zip(a.landmarks, b.landmarks, strict=True):
        assert (la.name, la.kind, la.margin_mm, la.radius_mm) == (
            lb.name,
            lb.kind,
            lb.margin_mm,
            lb.radius_mm,
        )
        if isinstance(la, CanalLandmark) and isinstance(lb, CanalLandmark):
            np.testing.assert_allclose(la.points_lps, lb.points_lps)
        if isinstance(la, PointLandmark) and isinstance(lb, PointLandmark):
            np.testing.assert_allclose(la.point_lps, lb.point_lps)


@pytest.mark.parametrize("name", ["saved.json", "saved.mrk.json"])
def test_save_plan_round_trips(tmp_path: Path, name: str) -> None:
    doc = copy.deepcopy(BASE)
    doc["coordinate_system"] = "RAS"
    doc["drill"]["rpm"] = 1200.5
    plan = load_plan(_write(tmp_path, doc))
    out = tmp_path / name
    save_plan(plan, out)
    if name.endswith(".mrk.json"):
        validate_markups(json.loads(out.read_text(encoding="utf-8")))
    again = load_plan(out)
    _same(plan, again)
    assert again.name == plan.name == "plan"
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["plan.json", name])
