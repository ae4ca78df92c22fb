"""The dental arch, implants and several trajectories in plan files, and their Slicer round trip."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from ctdrill.imaging.plan.curve import slicer_curve
from ctdrill.imaging.plan.implants import ImplantSpec, load_implant_library
from ctdrill.imaging.plan.landmarks import CanalLandmark, PointLandmark
from ctdrill.imaging.plan.load import load_plan_set, load_plans
from ctdrill.imaging.plan.types import DrillSpec, Plan, PlanInputError
from ctdrill.imaging.plan.write import plan_to_markups, write_plans
from tests.imaging.slicer_files import (
    slicer_control_point,
    slicer_document,
    slicer_markup,
    slicer_save,
    validate_markups,
)

#: A hand-drawn arch: not a Slicer spline (so it is kept as straight segments).
ARCH = np.array(
    [[40.0, -20.0, -40.0], [35.5, 0.25, -40.5], [20.125, 18.0, -41.0], [0.0, 25.0, -41.0]]
)


def _plans() -> tuple[Plan, ...]:
    """Three trajectories sharing landmarks and an arch, each with its own settings."""
    canal = CanalLandmark(
        "left IAN canal",
        [[30.0, -10.0, -45.0], [31.0, 0.0, -45.5], [30.5, 10.0, -46.0]],
        radius_mm=1.4,
        margin_mm=2.5,
    )
    lms = (canal, PointLandmark("mental foramen", [29.0, 12.0, -44.0], margin_mm=1.5))
    lib = load_implant_library()
    base = Plan(
        entry_lps=[33.0, -2.0, -30.0],
        target_lps=[33.5, -2.0, -41.0],
        drill=DrillSpec(diameter_mm=2.8, tip_length_mm=0.7, blades=3, rpm=800.25),
        feed_mm_s=0.35,
        calibration="pine-wood-paper",
        margin_mm=2.25,
        landmarks=lms,
        name="implant 36",
        implant=lib[25],
        arch_lps=ARCH,
        series_uid_sha256="a" * 64,
    )
    second = replace(
        base,
        name="implant 37",
        entry_lps=[32.0, -11.0, -30.0],
        target_lps=[32.0, -11.5, -39.5],
        implant=ImplantSpec("custom 4.3 x 9.5", 4.3, 9.5, 3.1, "round"),
    ).with_drills([DrillSpec(diameter_mm=2.0), DrillSpec(diameter_mm=3.2)])
    third = replace(base, name="implant 35", entry_lps=[34.0, 8.0, -30.0], implant=None)
    return (base, second, third)


def _assert_same(a: Plan, b: Plan) -> None:
    """Equal to 1e-9 mm (canal centrelines) and exactly everywhere else."""
    assert (a.name, a.drills, a.feed_mm_s, a.calibration, a.margin_mm, a.implant) == (
        b.name,
        b.drills,
        b.feed_mm_s,
        b.calibration,
        b.margin_mm,
        b.implant,
    )
    assert a.series_uid_sha256 == b.series_uid_sha256
    np.testing.assert_array_equal(a.entry_lps, b.entry_lps)
    np.testing.assert_array_equal(a.target_lps, b.target_lps)
    assert a.arch_lps is not None and b.arch_lps is not None
    np.testing.assert_allclose(a.arch_lps, b.arch_lps, rtol=0, atol=1e-9)
    assert [(lm.kind, lm.name, lm.margin_mm) for lm in a.landmarks] == [
        (lm.kind, lm.name, lm.margin_mm) for lm in b.landmarks
    ]
    for la, lb in zip(a.landmarks, b.landmarks, strict=True):
        np.testing.assert_allclose(
            la.control_points_lps(), lb.control_points_lps(), rtol=0, atol=1e-9
        )


def test_several_trajectories_round_trip_through_ctdrill_and_slicer(tmp_path: Path) -> None:
    plans = _plans()
    first = tmp_path / "case.json"
    write_plans(plans, first)
    doc = json.loads(first.read_text(encoding="utf-8"))
    assert [t["name"] for t in doc["trajectories"]] == ["implant 36", "implant 37", "implant 35"]
    assert "entry_mm" not in doc and doc["arch_mm"] == ARCH.tolist()
    assert doc["trajectories"][0]["implant"] == plans[0].implant.to_json()  # type: ignore[union-attr]
    assert "implant" not in doc["trajectories"][2]
    back = load_plans(first)
    for a, b in zip(plans, back, strict=True):
        _assert_same(a, b)
    # ctdrill-plan/1 -> Slicer markups -> Slicer's own load and save (one markup a file,
    # markup names and descriptions dropped) -> a folder merge -> ctdrill-plan/1.
    markups = tmp_path / "case.mrk.json"
    write_plans(back, markups)
    validate_markups(json.loads(markups.read_text(encoding="utf-8")))
    saved = tmp_path / "slicer"
    saved.mkdir()
    files = slicer_save(markups, saved)
    assert len(files) == 3 + 2 + 1  # three Lines, a Curve and a Fiducial, the arch Curve
    for f in files:
        validate_markups(json.loads(f.read_text(encoding="utf-8")))
    merged = load_plan_set([saved])
    final = tmp_path / "final.json"
    write_plans(sorted(merged, key=lambda p: [q.name for q in plans].index(p.name)), final)
    for a, b in zip(plans, load_plans(final), strict=True):
        _assert_same(a, b)


def test_one_trajectory_is_written_in_the_single_form(tmp_path: Path) -> None:
    plan = _plans()[1]
    out = tmp_path / "one.json"
    write_plans([plan], out)
    doc = json.loads(out.read_text(encoding="utf-8"))
    assert "trajectories" not in doc
    assert doc["name"] == "implant 37" and len(doc["drills"]) == 2
    assert doc["implant"] == {
        "name": "custom 4.3 x 9.5",
        "diameter_mm": 4.3,
        "length_mm": 9.5,
        "apex_diameter_mm": 3.1,
        "apex": "round",
    }
    _assert_same(plan, load_plans(out)[0])
    assert [p.name for p in tmp_path.iterdir()] == ["one.json"]  # nothing left aside


def test_a_slicer_spline_arch_keeps_its_control_points(tmp_path: Path) -> None:
    ctrl = [[40.0, -20.0, -40.0], [36.0, 0.0, -40.0], [20.0, 18.0, -41.0], [0.0, 25.0, -41.0]]
    cps = [
        slicer_control_point(i, p, label=f"A-{i + 1}", description="Arch" if i == 0 else "")
        for i, p in enumerate(ctrl)
    ]
    arch_file = tmp_path / "Jaw.mrk.json"
    arch_file.write_text(json.dumps(slicer_document(slicer_markup("Curve", cps))))
    line = slicer_markup(
        "Line",
        [slicer_control_point(0, [33.0, -2.0, -30.0]), slicer_control_point(1, [33, -2, -40])],
    )
    (tmp_path / "implant.mrk.json").write_text(json.dumps(slicer_document(line)))
    (plan,) = load_plan_set([tmp_path])
    assert plan.landmarks == ()  # the arch is not a canal
    assert plan.arch_lps is not None
    np.testing.assert_array_equal(plan.arch_lps, slicer_curve(np.array(ctrl)))
    doc = plan_to_markups(plan)
    validate_markups(doc)
    arch_mk = doc["markups"][-1]
    assert arch_mk["type"] == "Curve"
    assert [cp["position"] for cp in arch_mk["controlPoints"]] == ctrl
    assert arch_mk["controlPoints"][0]["description"] == "arch"


def _write(tmp_path: Path, doc: dict[str, Any], name: str = "plan.json") -> Path:
    path = tmp_path / name
    path.write_text(json.dumps(doc), encoding="utf-8")
    return path


_ONE = {
    "format": "ctdrill-plan/1",
    "entry_mm": [0.0, 0.0, 0.0],
    "target_mm": [0.0, 0.0, -10.0],
    "drill": {"diameter_mm": 2.0},
}


@pytest.mark.parametrize(
    ("arch", "expected"),
    [
        ([[0, 0, 0]], "plan.json: arch_mm must hold at least 2 points, got 1"),
        ([[0, 0, 0], [0, 0, 0]], "plan.json: arch_mm[1] repeats the point before it"),
        ([[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 1e6]], "plan.json: arch_mm[3] must be 3 finite"),
        ([[0, 0, 0], [1, 0, "2"]], "plan.json: arch_mm[1] must be 3 finite numbers"),
        ([[0, 0, 0], [1, 0]], "plan.json: arch_mm[1] must be 3 finite numbers"),
        ([[0, 0, 0], [1, 0, True]], "plan.json: arch_mm[1] must be 3 finite numbers"),
        ([[0, 0, 0], [1, 0, 10**400]], "plan.json: arch_mm[1] must be 3 finite numbers"),
        ("arch", "plan.json: arch_mm must be a list of [x, y, z] points"),
        ({"x": 1}, "plan.json: arch_mm must be a list of [x, y, z] points"),
    ],
)
def test_bad_arches_are_refused_naming_file_and_index(
    tmp_path: Path, arch: object, expected: str
) -> None:
    with pytest.raises(PlanInputError) as info:
        load_plans(_write(tmp_path, _ONE | {"arch_mm": arch}))
    assert str(info.value).startswith(expected)
    assert "\n" not in str(info.value)


def test_nan_in_a_plan_is_refused_before_parsing(tmp_path: Path) -> None:
    path = tmp_path / "plan.json"
    path.write_text(json.dumps(_ONE)[:-1] + ', "arch_mm": [[0, 0, NaN], [1, 0, 0]]}')
    with pytest.raises(PlanInputError, match=r"plan\.json"):
        load_plans(path)


def test_ras_arch_is_converted_to_lps(tmp_path: Path) -> None:
    doc = _ONE | {"coordinate_system": "RAS", "arch_mm": [[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]}
    (plan,) = load_plans(_write(tmp_path, doc))
    assert plan.arch_lps is not None
    np.testing.assert_array_equal(plan.arch_lps, [[-1.0, -2.0, 3.0], [-4.0, -5.0, 6.0]])
    assert not plan.arch_lps.flags.writeable


@pytest.mark.parametrize(
    ("doc", "expected"),
    [
        (
            {"format": "ctdrill-plan/1", "entry_mm": [0, 0, 0], "trajectories": [_ONE]},
            "plan.json: entry_mm is given with trajectories",
        ),
        (
            {"format": "ctdrill-plan/1", "trajectories": []},
            "plan.json: trajectories must be a non-empty list",
        ),
        (
            {"format": "ctdrill-plan/1", "trajectories": [
                {"name": "a", "entry_mm": [0, 0, 0], "target_mm": [0, 0, 1]},
                {"name": "a", "entry_mm": [1, 0, 0], "target_mm": [1, 0, 1]}]},
            "plan.json: trajectories[1].name repeats the name of trajectories[0]",
        ),
        (
            {"format": "ctdrill-plan/1", "trajectories": [
                {"name": "a", "entry_mm": [0, 0, 0], "target_mm": [0, 0, 1], "landmarks": []}]},
            "plan.json: trajectories[0].landmarks is not a known field",
        ),
        (
            {"format": "ctdrill-plan/1", "trajectories": [
                {"name": "a", "entry_mm": [0, 0, 0], "target_mm": [0, 0, 1],
                 "drill": {"diameter_mm": -1}}]},
            "plan.json: trajectories[0].drill.diameter_mm must be a positive number",
        ),
        (
            {"format": "ctdrill-plan/1", "trajectories": [
                {"name": "a", "entry_mm": [0, 0, 0], "target_mm": [0, 0, 1],
                 "implant": {"name": "x", "diameter_mm": 4, "length_mm": 1e9,
                             "apex_diameter_mm": 3, "apex": "flat"}}]},
            "plan.json: trajectories[0].implant.length_mm must be at most 30 mm",
        ),
        (
            _ONE | {"implant": {"name": "x", "diameter_mm": 4, "length_mm": 10}},
            "plan.json: implant.apex_diameter_mm is missing",
        ),
        (
            {"format": "ctdrill-plan/1", "trajectories": [["not", "an", "object"]]},
            "plan.json: trajectories[0] must be a trajectory object",
        ),
    ],
)  # fmt: skip
def test_bad_trajectories_are_refused_naming_the_field(
    tmp_path: Path, doc: dict[str, Any], expected: str
) -> None:
    with pytest.raises(PlanInputError) as info:
        load_plans(_write(tmp_path, doc))
    assert str(info.value).startswith(expected)


def test_two_files_with_different_arches_are_refused_naming_both(tmp_path: Path) -> None:
    a = _write(tmp_path, _ONE | {"name": "a", "arch_mm": ARCH.tolist()}, "a.json")
    b = _write(tmp_path, _ONE | {"name": "b", "arch_mm": ARCH[:3].tolist()}, "b.json")
    with pytest.raises(PlanInputError, match=r"b.json: its dental arch disagrees .* a.json"):
        load_plan_set([a, b])
    same = _write(tmp_path, _ONE | {"name": "c", "arch_mm": ARCH.tolist()}, "c.json")
    plans = load_plan_set([a, same])
    assert all(p.arch_lps is not None and np.array_equal(p.arch_lps, ARCH) for p in plans)


def test_writing_plans_that_share_nothing_is_refused(tmp_path: Path) -> None:
    a, b, _ = _plans()
    out = tmp_path / "x.json"
    with pytest.raises(PlanInputError, match="different dental arches"):
        write_plans([a, replace(b, arch_lps=None)], out)
    with pytest.raises(PlanInputError, match="protect different landmarks"):
        write_plans([a, replace(b, landmarks=())], out)
    with pytest.raises(PlanInputError, match="named 'implant 36'"):
        write_plans([a, replace(b, name=a.name)], out)
    assert not out.exists()


def test_plan_refuses_a_bad_arch_built_in_code() -> None:
    with pytest.raises(PlanInputError, match=r"arch\[2\] repeats"):
        Plan(entry_lps=[0, 0, 0], target_lps=[0, 0, 1], arch_lps=[[0, 0, 0], [1, 0, 0], [1, 0, 0]])


def test_slicer_line_implant_needs_every_setting(tmp_path: Path) -> None:
    desc = 'implant="x" implant_diameter_mm=4.0 implant_length_mm=10.0'
    line = slicer_markup(
        "Line",
        [
            slicer_control_point(0, [0.0, 0.0, 0.0], description=desc),
            slicer_control_point(1, [0.0, 0.0, -12.0]),
        ],
    )
    path = _write(tmp_path, slicer_document(line), "line.mrk.json")
    with pytest.raises(PlanInputError, match="setting implant_apex_diameter_mm is missing"):
        load_plans(path)


@pytest.mark.parametrize(
    ("points", "expected"),
    [
        ([[0.0, 0.0, 0.0]], "arch.mrk.json: markups[0].controlPoints of the arch Curve must hold"),
        (
            [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 0.0, 0.0]],
            "arch.mrk.json: markups[0].controlPoints[2] repeats the point before it",
        ),
        (
            [[0.0, 0.0, 0.0], [1.0, 0.0, 1e9]],
            "arch.mrk.json: markups[0].controlPoints[1].position must be a list of 3 finite",
        ),
    ],
)
def test_bad_slicer_arches_are_refused(
    tmp_path: Path, points: list[list[float]], expected: str
) -> None:
    cps = [
        slicer_control_point(i, p, description="arch" if i == 0 else "")
        for i, p in enumerate(points)
    ]
    path = _write(tmp_path, slicer_document(slicer_markup("Curve", cps)), "arch.mrk.json")
    with pytest.raises(PlanInputError) as info:
        load_plan_set([path])
    assert str(info.value).startswith(expected)


def test_two_arch_curves_in_one_file_are_refused(tmp_path: Path) -> None:
    cps = [slicer_control_point(i, [float(i), 0.0, 0.0], description="ARCH") for i in range(2)]
    doc = {"markups": [slicer_markup("Curve", cps), slicer_markup("Curve", cps)]}
    with pytest.raises(PlanInputError, match=r"markups\[1\] is a second arch Curve"):
        load_plans(_write(tmp_path, doc, "two.mrk.json"))


def test_a_canal_named_like_an_arch_word_inside_another_word_stays_a_canal(
    tmp_path: Path,
) -> None:
    desc = 'name="archaic canal" radius_mm=1.0'
    cps = [slicer_control_point(i, [float(i), 0.0, 0.0], description=desc) for i in range(2)]
    line = slicer_markup(
        "Line", [slicer_control_point(0, [5.0, 5.0, 5.0]), slicer_control_point(1, [5, 5, 0])]
    )
    doc = {"markups": [line, slicer_markup("Curve", cps)]}
    (plan,) = load_plans(_write(tmp_path, doc, "c.mrk.json"))
    assert plan.arch_lps is None and [lm.name for lm in plan.landmarks] == ["archaic canal"]


def test_plan_to_markups_takes_several_trajectories() -> None:
    plans = _plans()
    doc = plan_to_markups(plans)
    validate_markups(doc)
    assert [m["type"] for m in doc["markups"]] == ["Line"] * 3 + ["Curve", "Fiducial", "Curve"]
    assert doc == plan_to_markups(list(plans))
