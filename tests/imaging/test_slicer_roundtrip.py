"""Round trips with 3D Slicer: settings survive Slicer's writer, Slicer 5 files, curves, merges."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from ctdrill.imaging.plan.curve import POINTS_PER_SEGMENT, slicer_curve
from ctdrill.imaging.plan.landmarks import CanalLandmark, PointLandmark
from ctdrill.imaging.plan.load import load_plan, load_plan_set
from ctdrill.imaging.plan.slicer import MAX_CURVE_POINTS
from ctdrill.imaging.plan.types import DrillSpec, Plan, PlanInputError, plan_warnings
from ctdrill.imaging.plan.write import plan_to_markups, save_plan
from ctdrill.warning_codes import LoadWarning
from tests.imaging.slicer_files import (
    slicer_control_point,
    slicer_document,
    slicer_markup,
    slicer_save,
    validate_markups,
)


def _plan() -> Plan:
    """The issue's case: settings that differ from every default."""
    canal = CanalLandmark(
        "left IAN canal",
        [[0.0, 20.0, 10.0], [10.0, 21.0, 10.5], [20.0, 20.0, 11.0]],
        radius_mm=1.5,
        margin_mm=2.5,
    )
    return Plan(
        entry_lps=[10.0, 20.0, 30.0],
        target_lps=[10.0, 20.0, 18.0],
        drill=DrillSpec(diameter_mm=3.5, tip_length_mm=0.8, blades=3, rpm=1200.5),
        feed_mm_s=0.55,
        calibration="pine-wood-paper",
        margin_mm=2.5,
        landmarks=(canal, PointLandmark("apex 36", [14.0, 20.0, 20.0], margin_mm=1.5)),
        name="implant 36",
    )


def _assert_same(a: Plan, b: Plan) -> None:
    np.testing.assert_array_equal(a.entry_lps, b.entry_lps)
    np.testing.assert_array_equal(a.target_lps, b.target_lps)
    assert (a.name, a.drill, a.feed_mm_s, a.calibration, a.margin_mm) == (
        b.name,
        b.drill,
        b.feed_mm_s,
        b.calibration,
        b.margin_mm,
    )
    assert [(lm.name, lm.kind, lm.margin_mm, lm.radius_mm) for lm in a.landmarks] == [
        (lm.name, lm.kind, lm.margin_mm, lm.radius_mm) for lm in b.landmarks
    ]
    for la, lb in zip(a.landmarks, b.landmarks, strict=True):
        if isinstance(la, CanalLandmark) and isinstance(lb, CanalLandmark):
            np.testing.assert_allclose(la.points_lps, lb.points_lps, rtol=0, atol=1e-9)
        if isinstance(la, PointLandmark) and isinstance(lb, PointLandmark):
            np.testing.assert_array_equal(la.point_lps, lb.point_lps)


def test_written_markups_validate_and_keep_settings_in_control_points(tmp_path: Path) -> None:
    plan = _plan()
    doc = plan_to_markups(plan)
    validate_markups(doc)
    for mk in doc["markups"]:
        assert "description" not in mk  # Slicer drops it: nothing is kept there
    entry = doc["markups"][0]["controlPoints"][0]
    assert entry["description"] == (
        'name="implant 36" diameter_mm=3.5 tip_length_mm=0.8 blades=3 rpm=1200.5 '
        'feed_mm_s=0.55 calibration="pine-wood-paper" margin_mm=2.5 min_wall_mm=1.5'
    )


def test_plan_survives_slicer_load_and_save(tmp_path: Path) -> None:
    """The issue's loss: after Slicer's save a 3.5 mm drill became 2.0 mm, etc."""
    plan = _plan()
    path = tmp_path / "case.mrk.json"
    save_plan(plan, path)
    validate_markups(json.loads(path.read_text()))
    once = tmp_path / "slicer1"
    once.mkdir()
    files = slicer_save(path, once)
    # Slicer names each node (and file) by the markup's name, and writes one markup per file.
    assert sorted(f.name for f in files) == sorted(
        ["implant 36.mrk.json", "left IAN canal.mrk.json", "apex 36.mrk.json"]
    )
    for f in files:
        saved = json.loads(f.read_text())
        validate_markups(saved)
        assert "name" not in saved["markups"][0]
    (merged,) = load_plan_set([once])
    assert merged.notes == ()
    # The canal is the polyline ctdrill was given (curve=polyline kept in the description).
    _assert_same(plan, replace_order(merged, plan))
    # A second Slicer round trip of Slicer's own files changes nothing either.
    twice = tmp_path / "slicer2"
    twice.mkdir()
    for f in files:
        slicer_save(f, twice)
    (again,) = load_plan_set([twice])
    _assert_same(merged, again)


def replace_order(merged: Plan, like: Plan) -> Plan:
    """``merged`` with its landmarks in ``like``'s order (a folder is read by file name)."""
    by_name = {lm.name: lm for lm in merged.landmarks}
    from dataclasses import replace

    return replace(merged, landmarks=tuple(by_name[lm.name] for lm in like.landmarks))


def _slicer5_case(tmp_path: Path) -> Path:
    """A case as a Slicer 5 user saves it: a Line, a Curve, a point list, one file each."""
    case = tmp_path / "case"
    case.mkdir()
    line = slicer_markup(
        "Line",
        [
            slicer_control_point(0, [-10.0, -20.0, 30.0], label="L-1"),
            slicer_control_point(1, [-10.0, -20.0, 18.0], label="L-2"),
        ],
        system="RAS",
    )
    curve_pts = [[0.0, 20.0, 10.0], [10.0, 21.0, 10.5], [20.0, 20.0, 11.0], [30.0, 18.0, 12.0]]
    curve = slicer_markup(
        "Curve",
        [
            slicer_control_point(
                i,
                p,
                label=f"OC-{i + 1}",
                description='name="OC" radius_mm=1.4' if i == 0 else "",
            )
            for i, p in enumerate(curve_pts)
        ]
        # The user was placing a fifth point when saving: Slicer keeps it as a preview.
        + [slicer_control_point(4, None, label="OC-5", status="preview")],
    )
    points = slicer_markup(
        "Fiducial",
        [
            slicer_control_point(0, [14.0, 20.0, 20.0], label="apex 36"),
            slicer_control_point(1, [0.0, 0.0, 0.0], label="F-2", status="undefined"),
        ],
        units=["mm", "UCUM", "millimeter"],
    )
    roi = slicer_markup("ROI", [slicer_control_point(0, [0.0, 0.0, 0.0], label="R-1")])
    for name, mk in [("L", line), ("OC", curve), ("F", points), ("R", roi)]:
        doc = slicer_document(mk)
        if name in ("L", "R"):  # Slicer's own "position": "" (unplaced) breaks its schema
            validate_markups(doc)
        (case / f"{name}.mrk.json").write_text(json.dumps(doc, indent=4), encoding="utf-8")
    return case


def test_slicer5_case_in_separate_files_runs_without_edits(tmp_path: Path) -> None:
    case = _slicer5_case(tmp_path)
    (plan,) = load_plan_set([case])
    assert plan.name == "L"  # Slicer names the node after the file
    np.testing.assert_array_equal(plan.entry_lps, [10.0, 20.0, 30.0])  # RAS -> LPS
    np.testing.assert_array_equal(plan.target_lps, [10.0, 20.0, 18.0])
    assert plan.drill == DrillSpec() and plan.margin_mm == 2.0
    apex, canal = plan.landmarks  # files in name order: F, L, OC, R
    # a Curve is named by its description (Slicer keeps it), never after its file
    assert isinstance(canal, CanalLandmark) and canal.name == "OC" and canal.radius_mm == 1.4
    # The preview point is ignored: 4 placed points, 3 segments of 10 samples.
    assert canal.points_lps.shape == (31, 3)
    np.testing.assert_array_equal(canal.points_lps[::10][-1], [30.0, 18.0, 12.0])
    assert isinstance(apex, PointLandmark) and apex.name == "apex 36"  # undefined point ignored
    codes = [w.code for w in plan_warnings(plan)]
    assert codes == ["plan_default", "markups_skipped"]  # the line names no drill: said so
    assert plan_warnings(plan)[0].message == (
        "L.mrk.json: markups[0] gives no drill; using the default 2 mm drill (0.6 mm tip, "
        "2 blades, 900 rpm)"
    )
    (message,) = [w.message for w in plan_warnings(plan) if w.code == "markups_skipped"]
    assert message.startswith("R.mrk.json: skipped markups ctdrill does not use: markups[0] (ROI)")


@pytest.mark.parametrize("mtype", ["ROI", "Plane", "Angle", "ClosedCurve"])
def test_other_markup_types_are_skipped_with_a_warning(tmp_path: Path, mtype: str) -> None:
    doc = plan_to_markups(_plan())
    doc["markups"].append(
        slicer_markup(mtype, [slicer_control_point(0, [1.0, 2.0, 3.0], label="x")])
    )
    path = tmp_path / "p.mrk.json"
    path.write_text(json.dumps(doc))
    plan = load_plan(path)
    assert len(plan.landmarks) == 2
    assert plan.warnings == (
        LoadWarning(
            "markups_skipped",
            f"p.mrk.json: skipped markups ctdrill does not use: markups[3] ({mtype}) (only "
            "Line, Curve and Fiducial markups are read)",
        ),
    )


def test_coordinate_units(tmp_path: Path) -> None:
    def line(units: object) -> Path:
        mk = slicer_markup(
            "Line",
            [
                slicer_control_point(0, [0.0, 0.0, 10000.0]),
                slicer_control_point(1, [0.0, 0.0, 0.0]),
            ],
            units=units,
        )
        path = tmp_path / "u.mrk.json"
        path.write_text(json.dumps(slicer_document(mk)))
        return path

    assert load_plan(line(["mm", "UCUM", "millimeter"])).planned_depth_mm == 10000.0
    assert load_plan(line(["um", "UCUM", "micrometer"])).planned_depth_mm == 10.0
    assert load_plan(line("um")).planned_depth_mm == 10.0
    with pytest.raises(PlanInputError, match=r"markups\[0\].coordinateUnits must be"):
        load_plan(line(["mm", "SNM", "millimeter"]))
    with pytest.raises(PlanInputError, match=r"markups\[0\].coordinateUnits must be"):
        load_plan(line("cm"))


def test_preview_target_is_not_taken_as_the_target(tmp_path: Path) -> None:
    mk = slicer_markup(
        "Line",
        [
            slicer_control_point(0, [0.0, 0.0, 10.0]),
            slicer_control_point(1, [0.0, 0.0, 0.0], status="preview"),
        ],
    )
    mk["controlPoints"][1]["position"] = [0.0, 0.0, 0.0]  # a preview point with a position
    path = tmp_path / "l.mrk.json"
    path.write_text(json.dumps(slicer_document(mk)))
    with pytest.raises(PlanInputError, match="of a Line must hold 2 placed points"):
        load_plan(path)


def _vtk_spline(points: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Slicer's curve (vtkCurveGenerator, curve type spline) evaluated by VTK itself."""
    import vtk

    vpts = vtk.vtkPoints()
    vpts.SetDataTypeToDouble()  # Slicer's control points are doubles (vtkPoints: float)
    for p in points:
        vpts.InsertNextPoint(*p)
    spline = vtk.vtkParametricSpline()
    spline.SetXSpline(vtk.vtkCardinalSpline())
    spline.SetYSpline(vtk.vtkCardinalSpline())
    spline.SetZSpline(vtk.vtkCardinalSpline())
    spline.SetPoints(vpts)
    spline.SetClosed(False)
    spline.SetParameterizeByLength(False)
    out = np.empty((len(u), 3))
    for i, ui in enumerate(u):
        xyz = [0.0, 0.0, 0.0]
        spline.Evaluate([float(ui), 0.0, 0.0], xyz, [0.0] * 9)
        out[i] = xyz
    return out


@pytest.mark.parametrize("n", [2, 3, 4, 7])
def test_canal_centreline_is_slicers_spline(n: int) -> None:
    rng = np.random.default_rng(n)
    ctrl = np.cumsum(rng.uniform(-8.0, 8.0, size=(n, 3)), axis=0)
    centre = slicer_curve(ctrl)
    total = POINTS_PER_SEGMENT * (n - 1) + 1
    assert centre.shape == (total, 3)
    np.testing.assert_array_equal(centre[::POINTS_PER_SEGMENT], ctrl)
    u = np.arange(total) / (total - 1)
    np.testing.assert_allclose(centre, _vtk_spline(ctrl, u), rtol=0, atol=1e-9)
    # Between the samples too: Slicer's polyline is within the chord error of the spline.
    fine = np.linspace(0.0, 1.0, 997)
    ref = _vtk_spline(ctrl, fine)
    # Zero end slopes (VTK's default end constraint): the curve leaves its ends slowly.
    d0 = ref[1] - ref[0]
    assert np.linalg.norm(d0) < 1e-3 * np.linalg.norm(ctrl[1] - ctrl[0])


def test_single_point_curve_is_a_point() -> None:
    np.testing.assert_array_equal(slicer_curve(np.array([[1.0, 2.0, 3.0]])), [[1.0, 2.0, 3.0]])


def test_files_merge_and_disagreements_are_refused(tmp_path: Path) -> None:
    plan = _plan()
    a = tmp_path / "a.json"
    save_plan(plan, a)
    b = tmp_path / "b.mrk.json"
    save_plan(plan, b)
    # The same trajectory and landmarks in two files: kept once.
    (merged,) = load_plan_set([a, b])
    assert [lm.name for lm in merged.landmarks] == ["left IAN canal", "apex 36"]
    doc = json.loads(b.read_text())
    doc["markups"][0]["controlPoints"][1]["position"][2] = 17.0
    b.write_text(json.dumps(doc))
    with pytest.raises(
        PlanInputError,
        match=r"b.mrk.json: trajectory 'implant 36' disagrees with the one in a.json",
    ):
        load_plan_set([a, b])
    doc["markups"][0]["controlPoints"][1]["position"][2] = 18.0
    doc["markups"][2]["controlPoints"][0]["position"][0] = 15.0
    b.write_text(json.dumps(doc))
    with pytest.raises(PlanInputError, match="landmark 'apex 36' disagrees with the one in a"):
        load_plan_set([a, b])


def test_curve_only_file_is_landmarks_and_line_only_file_warns(tmp_path: Path) -> None:
    plan = _plan()
    files = slicer_save(_saved(plan, tmp_path), tmp_path)
    curve = next(f for f in files if f.name.startswith("left"))
    line = next(f for f in files if f.name.startswith("implant"))
    with pytest.raises(PlanInputError, match="no trajectory"):
        load_plan(curve)
    alone = load_plan(line)
    assert alone.landmarks == ()
    last = plan_warnings(alone)[-1]
    assert last.code == "no_landmarks"
    assert last.message.startswith("plan 'implant 36' has no landmark")
    (both,) = load_plan_set([line, curve])
    assert [lm.name for lm in both.landmarks] == ["left IAN canal"]
    assert [w.code for w in plan_warnings(both)] == []


def _saved(plan: Plan, folder: Path) -> Path:
    path = folder / "ctdrill.mrk.json"
    save_plan(plan, path)
    return path


def test_hostile_json_is_refused(tmp_path: Path) -> None:
    deep = tmp_path / "deep.mrk.json"
    deep.write_text('{"markups": ' + "[" * 1000 + "]" * 1000 + "}")
    with pytest.raises(PlanInputError, match="nests arrays/objects 1001 deep"):
        load_plan(deep)
    huge = tmp_path / "huge.json"
    huge.write_text('{"format": "ctdrill-plan/1", "entry_mm": [' + "9" * 5000 + ", 0, 0]}")
    with pytest.raises(PlanInputError, match="holds a value that cannot be read"):
        load_plan(huge)


def test_a_curve_of_too_many_points_is_refused(tmp_path: Path) -> None:
    n = MAX_CURVE_POINTS + 1
    pts = [[float(i) * 0.01, 0.0, 0.0] for i in range(n)]
    mk = slicer_markup("Curve", [{"position": p} for p in pts])
    path = tmp_path / "c.mrk.json"
    path.write_text(json.dumps(slicer_document(mk)))
    expected = rf"of a Curve hold {n} placed points, more than the {MAX_CURVE_POINTS}"
    with pytest.raises(PlanInputError, match=expected):
        load_plan_set([path])
