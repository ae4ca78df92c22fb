"""The osteotomy follows the implant: drilling protocols, each drill's planned depth (the apex
plus its tip), the plan keys ``min_wall_mm`` and ``site`` in files and Slicer markups."""

from __future__ import annotations

import itertools
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from ctdrill.imaging.plan.implants import (
    DEFAULT_LIBRARY,
    ImplantInputError,
    ImplantSpec,
    implant_placement,
    load_implant_library,
)
from ctdrill.imaging.plan.load import load_plan, load_plan_set
from ctdrill.imaging.plan.protocol import (
    FINAL_UNDERSIZE_MM,
    MAX_STEP_MM,
    PILOT_DIAMETER_MM,
    final_drill_warnings,
    generic_protocol,
    with_implant_protocol,
)
from ctdrill.imaging.plan.site import site_text
from ctdrill.imaging.plan.types import (
    DEFAULT_MIN_WALL_MM,
    DrillSpec,
    Plan,
    PlanInputError,
    plan_warnings,
)
from ctdrill.imaging.plan.write import plan_to_markups, save_plan
from tests.imaging.slicer_files import slicer_save, validate_markups

TAPERED = ImplantSpec("tapered 4.1 x 10", 4.1, 10.0, 2.9, "round")
PARALLEL = ImplantSpec("parallel 4.1 x 10", 4.1, 10.0, 4.1, "flat")


def _doc(**extra: Any) -> dict[str, Any]:
    return {"format": "ctdrill-plan/1", "entry_mm": [0, 0, 0], "target_mm": [0, 0, -12], **extra}


def _write(tmp_path: Path, doc: dict[str, Any], name: str = "plan.json") -> Path:
    path = tmp_path / name
    path.write_text(json.dumps(doc))
    return path


def test_the_library_protocols_follow_the_generic_rule() -> None:
    lib = load_implant_library()
    assert len(lib) == 40
    for spec in lib:
        drills = spec.drills
        assert drills == generic_protocol(spec.diameter_mm), spec.name
        sizes = [d.diameter_mm for d in drills]
        assert sizes[0] == PILOT_DIAMETER_MM
        assert sizes[-1] == pytest.approx(spec.diameter_mm - FINAL_UNDERSIZE_MM, abs=1e-9)
        assert all(0.0 < b - a <= MAX_STEP_MM + 1e-9 for a, b in itertools.pairwise(sizes))
        # the published tip range, and a 120 deg point to 0.05 mm
        for d in drills:
            assert 0.4 <= d.tip_length_mm <= 1.5
            expect = d.diameter_mm / (2.0 * math.tan(math.radians(60.0)))
            assert abs(d.tip_length_mm - expect) <= 0.05 + 1e-9
        plan = Plan(np.zeros(3), np.array([0, 0, -12.0]), implant=spec).with_drills(drills)
        assert final_drill_warnings(plan) == []  # a protocol suits its own implant
    raw = json.loads(DEFAULT_LIBRARY.read_text(encoding="utf-8"))
    assert all("drills" in item for item in raw["implants"])


def test_generic_protocol_examples() -> None:
    sizes = {d: [s.diameter_mm for s in generic_protocol(d)] for d in (3.3, 4.1, 4.8, 5.0)}
    assert sizes == {
        3.3: [2.0, 2.7],
        4.1: [2.0, 2.8, 3.5],
        4.8: [2.0, 2.7, 3.5, 4.2],
        5.0: [2.0, 2.8, 3.6, 4.4],
    }
    assert [d.tip_length_mm for d in generic_protocol(4.1)] == [0.6, 0.8, 1.0]
    assert generic_protocol(2.5) == (DrillSpec(1.9, 0.5),)  # narrower than the pilot: one


def test_a_plan_without_drills_drills_its_implants_protocol_and_says_so(tmp_path: Path) -> None:
    spec = next(s for s in load_implant_library() if s.name == "tapered 4.1 x 10")
    plan = load_plan(_write(tmp_path, _doc(implant=spec.to_json())))
    assert plan.drills == spec.drills
    assert plan.notes == ()  # not the default drill
    codes = [w.code for w in plan_warnings(plan)]
    assert codes.count("implant_protocol") == 1 and final_drill_warnings(plan) == []
    note = {w.code: w.message for w in plan_warnings(plan)}["implant_protocol"]
    assert "plan.json" in note and "2 -> 2.8 -> 3.5 mm" in note and "its protocol" in note
    # an implant without a protocol (a plan written before protocols): the generic one
    bare = {k: v for k, v in spec.to_json().items() if k != "drills"}
    old = load_plan(_write(tmp_path, _doc(implant=bare), "old.json"))
    assert old.drills == generic_protocol(4.1)
    assert (
        "the generic protocol for its size"
        in {w.code: w.message for w in old.warnings}["implant_protocol"]
    )
    # explicit drills override it, without a note
    own = load_plan(_write(tmp_path, _doc(implant=bare, drill={"diameter_mm": 3.2}), "own.json"))
    assert own.drills == (DrillSpec(diameter_mm=3.2),)
    assert "implant_protocol" not in {w.code for w in plan_warnings(own)}


def test_each_drill_reaches_the_apex_and_its_tip_beyond() -> None:
    apex = np.array([3.0, 4.0, -12.0])
    entry = np.array([3.0, 1.0, 0.0])
    plan = Plan(entry, apex, implant=TAPERED).with_drills(generic_protocol(4.1))
    depth = float(np.linalg.norm(apex - entry))
    assert plan.planned_depth_mm == pytest.approx(depth)  # the plan's target is the apex
    assert plan.drill_depths_mm() == pytest.approx((depth + 0.6, depth + 0.8, depth + 1.0))
    for k, tip in enumerate((0.6, 0.8, 1.0)):
        view = plan.drilled(k)
        assert view.drills == (plan.drills[k],)
        assert view.planned_depth_mm == pytest.approx(depth + tip)
        np.testing.assert_allclose(view.target_lps, apex + tip * plan.direction, atol=1e-12)
        np.testing.assert_allclose(view.planned_target_lps, apex, atol=1e-12)
        place = implant_placement(view)
        assert place is not None
        np.testing.assert_allclose(place.apex_lps, apex, atol=1e-12)  # the implant stays
        assert place.apex_depth_mm == pytest.approx(depth)
        assert view.drilled(0).planned_depth_mm == pytest.approx(depth + tip)  # idempotent
        assert plan.for_drill(k).planned_depth_mm == pytest.approx(depth)  # the tip at the target
    # without an implant the target is the drill's tip, as before
    plain = Plan(entry, apex).with_drills(generic_protocol(4.1))
    assert plain.drill_depths_mm() == pytest.approx((depth,) * 3)
    # a drilled view made a sequence again, or written, keeps the plan's target: the apex
    written = plan.drilled(1)
    assert written.with_drills(written.drills).planned_depth_mm == pytest.approx(depth)


def test_with_implant_protocol_for_plans_built_in_code() -> None:
    plan = Plan(np.zeros(3), np.array([0.0, 0.0, -11.0]), implant=PARALLEL)
    assert with_implant_protocol(plan).drills == generic_protocol(4.1)
    assert with_implant_protocol(Plan(np.zeros(3), np.ones(3))).drills == (DrillSpec(),)


@pytest.mark.parametrize(
    ("spec", "drills", "word"),
    [
        (TAPERED, [2.0, 2.8, 3.5, 4.2], "wider"),
        (TAPERED, [2.0, 2.8], "narrower"),  # under the apex diameter 2.9
        (PARALLEL, [2.0, 2.8, 3.2], "narrower"),  # under 4.1 - 0.8 = 3.3
        (TAPERED, [2.0, 2.9], None),
        (PARALLEL, [2.0, 2.8, 3.3], None),
        (PARALLEL, [2.0, 2.8, 3.5, 4.1], None),
    ],
)
def test_a_final_drill_that_does_not_suit_the_implant_is_reported(
    spec: ImplantSpec, drills: list[float], word: str | None
) -> None:
    seq = tuple(DrillSpec(diameter_mm=d) for d in drills)
    plan = Plan(np.zeros(3), np.array([0.0, 0.0, -12.0]), implant=spec, name="36").with_drills(seq)
    found = [w.message for w in final_drill_warnings(plan) if w.code == "final_drill_mismatch"]
    if word is None:
        assert found == []
    else:
        assert len(found) == 1 and word in found[0] and f"({drills[-1]:g} mm)" in found[0]
    assert [w.message for w in plan_warnings(plan) if w.code == "final_drill_mismatch"] == []
    # a drilled view holds one drill of the sequence: it reports nothing of the final drill
    assert final_drill_warnings(plan.drilled(0)) == []


def test_protocols_in_a_user_library_are_checked(tmp_path: Path) -> None:
    item = TAPERED.to_json() | {"name": "ours"}
    bad = [
        (
            [{"tip_length_mm": 0.6}],
            r"mine\.json: implants\[0\]\.drills\[0\]\.diameter_mm is missing",
        ),
        (
            [{"diameter_mm": 2.0, "point_angle_deg": 200}],
            r"mine\.json: implants\[0\]\.drills\[0\]\.point_angle_deg must be between",
        ),
        (
            [
                {"diameter_mm": 2.8, "tip_length_mm": 0.8},
                {"diameter_mm": 2.0, "tip_length_mm": 0.6},
            ],
            r"mine\.json: implants\[0\]\.drills\[1\]\.diameter_mm \(2 mm\) must be larger",
        ),
        ([{"diameter_mm": 2.0, "tip_length_mm": -1}], r"drills\[0\]\.tip_length_mm must be a"),
        ([{"diameter_mm": 2.0, "tip_length_mm": 0.6, "rpm": 5}], r"drills\[0\]\.rpm is not a"),
        ([], r"implants\[0\]\.drills must be a non-empty list"),
    ]
    for drills, pattern in bad:
        path = _write(
            tmp_path,
            {"format": "ctdrill-implants/1", "implants": [item | {"drills": drills}]},
            "mine.json",
        )
        with pytest.raises(ImplantInputError, match=pattern):
            load_implant_library(path)


def _full_plan() -> Plan:
    spec = next(s for s in load_implant_library() if s.name == "tapered 4.1 x 10")
    return Plan(
        np.array([1.0, 2.0, 3.0]),
        np.array([1.5, 2.0, -9.0]),
        implant=spec,
        name="36",
        min_wall_mm=1.8,
        site=36,
    ).with_drills(spec.drills)


@pytest.mark.parametrize("suffix", [".json", ".mrk.json"])
def test_min_wall_site_and_protocol_round_trip(tmp_path: Path, suffix: str) -> None:
    plan = _full_plan()
    path = tmp_path / f"p{suffix}"
    save_plan(plan, path)
    back = load_plan(path)
    assert (back.min_wall_mm, back.site, back.implant, back.drills) == (
        1.8,
        36,
        plan.implant,
        plan.drills,
    )
    assert back.implant is not None and back.implant.drills == plan.drills
    if suffix == ".mrk.json":
        doc = json.loads(path.read_text())
        validate_markups(doc)
        desc = doc["markups"][0]["controlPoints"][0]["description"]
        assert "min_wall_mm=1.8" in desc and "site=36" in desc and "implant_drills=" in desc
        (tmp_path / "slicer").mkdir()
        saved = slicer_save(path, tmp_path / "slicer")  # loaded and saved by Slicer
        again = load_plan_set(saved)[0]
        assert (again.min_wall_mm, again.site, again.drills) == (1.8, 36, plan.drills)
    # a drill's view is written as the plan it belongs to: the target is the apex
    save_plan(plan.drilled(2), path)
    np.testing.assert_allclose(load_plan(path).target_lps, plan.target_lps, atol=1e-12)


def test_defaults_and_slicer_settings(tmp_path: Path) -> None:
    plain = load_plan(_write(tmp_path, _doc(drill={})))
    assert (plain.min_wall_mm, plain.site) == (DEFAULT_MIN_WALL_MM, None)
    assert DEFAULT_MIN_WALL_MM == 1.5
    doc = plan_to_markups(Plan(np.zeros(3), np.array([0, 0, -10.0])))
    cp = doc["markups"][0]["controlPoints"][0]
    assert "min_wall_mm=1.5" in cp["description"]  # a setting is given once: replace it
    cp["description"] = cp["description"].replace("min_wall_mm=1.5", "min_wall_mm=2") + " site=46"
    path = _write(tmp_path, doc, "line.mrk.json")
    line = load_plan(path)
    assert (line.site, line.min_wall_mm) == (46, 2.0)
    assert site_text(46) == "46 (lower right first molar)"


def test_a_trajectory_without_a_name_is_named_by_its_site(tmp_path: Path) -> None:
    assert load_plan(_write(tmp_path, _doc(site=36))).name == "36"
    assert load_plan(_write(tmp_path, _doc())).name == "plan"  # no site: the file's stem
    items = [_doc(site=36), _doc(site=46), _doc(site=36), _doc()]
    for item in items:
        del item["format"]
    multi = _write(tmp_path, {"format": "ctdrill-plan/1", "trajectories": items}, "multi.json")
    assert [p.name for p in load_plan_set([multi])] == ["36", "46", "multi-3", "multi-4"]


@pytest.mark.parametrize(
    ("value", "why"),
    [
        (19, "tooth 9 is not 1-8"),
        (51, "quadrant 5 is not 1-4"),
        (10, "tooth 0 is not 1-8"),
        (36.5, "must be an FDI tooth number 11-48"),
        ("36", "must be an FDI tooth number 11-48"),
        (True, "must be an FDI tooth number 11-48"),
    ],
)
def test_a_bad_site_is_refused_naming_file_and_field(
    tmp_path: Path, value: object, why: str
) -> None:
    with pytest.raises(PlanInputError) as err:
        load_plan(_write(tmp_path, _doc(site=value)))
    msg = str(err.value)
    assert msg.startswith("plan.json: site ") and why in msg and "\n" not in msg
    traj = {"format": "ctdrill-plan/1", "trajectories": [_doc(site=value) | {"name": "a"}]}
    del traj["trajectories"][0]["format"]
    with pytest.raises(PlanInputError, match=r"^multi\.json: trajectories\[0\]\.site "):
        load_plan_set([_write(tmp_path, traj, "multi.json")])
    with pytest.raises(PlanInputError, match=r"plan '36': site must be an FDI"):
        Plan(np.zeros(3), np.ones(3), name="36", site=value if value != 36.5 else 99)  # type: ignore[arg-type]


def test_bad_min_wall_and_slicer_refusals(tmp_path: Path) -> None:
    with pytest.raises(PlanInputError, match=r"^plan\.json: min_wall_mm must be a number >= 0"):
        load_plan(_write(tmp_path, _doc(min_wall_mm=-1)))
    with pytest.raises(PlanInputError, match=r"^plan\.json: min_wall_mm must be at most 1000"):
        load_plan(_write(tmp_path, _doc(min_wall_mm=5000)))
    doc = plan_to_markups(Plan(np.zeros(3), np.array([0, 0, -10.0])))
    doc["markups"][0]["controlPoints"][0]["description"] += " site=59"
    with pytest.raises(PlanInputError) as err:
        load_plan(_write(tmp_path, doc, "l.mrk.json"))
    assert str(err.value).startswith(
        "l.mrk.json: markups[0].controlPoints[0].description: setting site must be an FDI"
    )
    doc["markups"][0]["controlPoints"][0]["description"] = 'implant_drills="[]"'
    with pytest.raises(PlanInputError, match=r"setting implant_drills is given without an implant"):
        load_plan(_write(tmp_path, doc, "l.mrk.json"))


def test_trajectories_that_differ_in_wall_or_site_do_not_merge(tmp_path: Path) -> None:
    a = _write(tmp_path, _doc(name="t", min_wall_mm=1.5), "a.json")
    b = _write(tmp_path, _doc(name="t", min_wall_mm=2.0), "b.json")
    with pytest.raises(PlanInputError, match=r"b\.json: trajectory 't' disagrees"):
        load_plan_set([a, b])
