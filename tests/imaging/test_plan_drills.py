"""Drill sequences in plans: ``drills`` in ``ctdrill-plan/1`` and in Slicer markups (issue 18)."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path
from typing import Any

import pytest

from ctdrill.imaging.plan.load import load_plan, load_plan_set
from ctdrill.imaging.plan.types import MAX_DRILLS, DrillSpec, Plan, PlanInputError
from ctdrill.imaging.plan.write import plan_to_dict, plan_to_markups, save_plan
from tests.imaging.slicer_files import slicer_save, validate_markups

PILOT = DrillSpec(diameter_mm=2.0, tip_length_mm=0.6, blades=2, rpm=900.0)
MIDDLE = DrillSpec(diameter_mm=2.8, tip_length_mm=0.84, blades=3, rpm=800.0)
FINAL = DrillSpec(diameter_mm=3.5, tip_length_mm=1.05, blades=2, rpm=700.5)


def _doc(**extra: Any) -> dict[str, Any]:
    return {
        "format": "ctdrill-plan/1",
        "entry_mm": [0.0, 0.0, 0.0],
        "target_mm": [0.0, 0.0, -12.0],
        **extra,
    }


def _write(tmp_path: Path, doc: dict[str, Any], name: str = "plan.json") -> Path:
    path = tmp_path / name
    path.write_text(json.dumps(doc))
    return path


def test_drills_list_reads_in_drilling_order_and_final_is_plan_drill(tmp_path: Path) -> None:
    seq = [PILOT.to_json(), MIDDLE.to_json(), FINAL.to_json()]
    plan = load_plan(_write(tmp_path, _doc(drills=seq)))
    assert plan.drills == (PILOT, MIDDLE, FINAL)
    assert plan.drill == FINAL
    assert plan.earlier_drills == (PILOT, MIDDLE)


def test_single_drill_plan_has_a_one_drill_sequence(tmp_path: Path) -> None:
    plan = load_plan(_write(tmp_path, _doc(drill=MIDDLE.to_json())))
    assert plan.drills == (MIDDLE,)
    assert plan.drill == MIDDLE
    assert plan.notes == ()
    # neither drill nor drills: the default drill, said so (a plan_default note)
    default = load_plan(_write(tmp_path, _doc(), "bare.json"))
    assert default.drills == (DrillSpec(),)
    assert default.notes == (
        "bare.json: gives no drill; using the default 2 mm drill (0.6 mm tip, 2 blades, 900 rpm)",
    )


def test_sequence_items_default_like_drill_but_need_a_diameter(tmp_path: Path) -> None:
    plan = load_plan(_write(tmp_path, _doc(drills=[{"diameter_mm": 2.0}, {"diameter_mm": 3.0}])))
    assert plan.drills == (DrillSpec(diameter_mm=2.0), DrillSpec(diameter_mm=3.0))
    with pytest.raises(PlanInputError, match=r"plan\.json: drills\[1\]\.diameter_mm is missing"):
        load_plan(_write(tmp_path, _doc(drills=[{"diameter_mm": 2.0}, {"rpm": 800}])))


@pytest.mark.parametrize(
    ("extra", "pattern"),
    [
        (
            {"drill": PILOT.to_json(), "drills": [PILOT.to_json(), FINAL.to_json()]},
            r"plan\.json: drills and drill are both given",
        ),
        ({"drills": []}, r"plan\.json: drills must list at least one drill"),
        ({"drills": {"diameter_mm": 2.0}}, r"plan\.json: drills must be a list of drill objects"),
        ({"drills": [2.0, 2.8]}, r"plan\.json: drills\[0\] must be a drill object"),
        (
            {"drills": [{"diameter_mm": 2.8}, {"diameter_mm": 2.0}]},
            r"plan\.json: drills\[1\]\.diameter_mm \(2 mm\) must be larger than "
            r"drills\[0\]\.diameter_mm \(2\.8 mm\)",
        ),
        (
            {"drills": [{"diameter_mm": 2.0}, {"diameter_mm": 2.0}]},
            r"drills\[1\]\.diameter_mm \(2 mm\) must be larger",
        ),
        (
            {"drills": [{"diameter_mm": 2.0}, {"diameter_mm": -3.0}]},
            r"drills\[1\]\.diameter_mm must be a positive number",
        ),
        (
            {"drills": [{"diameter_mm": 2.0, "speed": 3}]},
            r"drills\[0\]\.speed is not a known field",
        ),
        (
            {"drills": [{"diameter_mm": 1.0 + 0.1 * i} for i in range(MAX_DRILLS + 1)]},
            rf"drills lists {MAX_DRILLS + 1} drills, more than the {MAX_DRILLS} accepted",
        ),
    ],
)
def test_nonsense_sequences_are_refused_naming_the_field(
    tmp_path: Path, extra: dict[str, Any], pattern: str
) -> None:
    with pytest.raises(PlanInputError, match=pattern):
        load_plan(_write(tmp_path, _doc(**extra)))


def test_cli_refuses_both_with_one_error_line(tmp_path: Path) -> None:
    import subprocess
    import sys

    path = _write(tmp_path, _doc(drill=PILOT.to_json(), drills=[PILOT.to_json()]))
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "ctdrill.app.cli",
            "export",
            "--dicom",
            str(tmp_path),
            "--plan",
            str(path),
            "--out",
            str(tmp_path / "out"),
        ],
        capture_output=True,
        text=True,
        check=False,
    )
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ")
    assert "drills and drill are both given" in lines[0]


def _plan() -> Plan:
    return Plan(entry_lps=[1.0, 2.0, 3.0], target_lps=[1.0, 2.0, -9.0], name="seq").with_drills(
        (PILOT, MIDDLE, FINAL)
    )


def test_plan_json_round_trip_keeps_the_sequence(tmp_path: Path) -> None:
    plan = _plan()
    doc = plan_to_dict(plan)
    assert "drill" not in doc
    assert doc["drills"] == [PILOT.to_json(), MIDDLE.to_json(), FINAL.to_json()]
    path = tmp_path / "seq.json"
    save_plan(plan, path)
    back = load_plan(path)
    assert back.drills == plan.drills and back.drill == FINAL
    # a single-drill plan keeps today's layout: "drill", no "drills"
    single = plan_to_dict(plan.for_drill(0))
    assert single["drill"] == PILOT.to_json() and "drills" not in single


def test_markups_round_trip_through_slicer_keeps_the_sequence(tmp_path: Path) -> None:
    plan = _plan()
    doc = plan_to_markups(plan)
    validate_markups(doc)
    desc = doc["markups"][0]["controlPoints"][0]["description"]
    assert "drills=" in desc and "diameter_mm=" not in desc.split("drills=")[0]
    path = tmp_path / "seq.mrk.json"
    save_plan(plan, path)
    assert load_plan(path).drills == plan.drills
    out = tmp_path / "slicer"
    out.mkdir()
    slicer_save(path, out)
    (again,) = load_plan_set([out])
    assert again.drills == plan.drills


def test_markups_refuse_both_and_malformed_drills(tmp_path: Path) -> None:
    doc = plan_to_markups(_plan())
    cp = doc["markups"][0]["controlPoints"][0]
    cp["description"] += " diameter_mm=3.5"
    path = tmp_path / "both.mrk.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(PlanInputError, match=r"setting drills and diameter_mm are both given"):
        load_plan(path)
    cp["description"] = 'drills="[{\\"diameter_mm\\": 3}, {\\"diameter_mm\\": 2}]"'
    path.write_text(json.dumps(doc))
    with pytest.raises(PlanInputError, match=r"drills\[1\]\.diameter_mm \(2 mm\) must be larger"):
        load_plan(path)
    cp["description"] = "drills=2.0"
    path.write_text(json.dumps(doc))
    with pytest.raises(PlanInputError, match=r"setting drills must be a quoted JSON list"):
        load_plan(path)


def test_plan_type_keeps_the_invariant() -> None:
    plan = _plan()
    assert plan.for_drill(1).drills == (MIDDLE,)
    # replace(drill=...) changes the final drill only
    wider = replace(plan, drill=replace(FINAL, diameter_mm=4.0))
    assert wider.drills[:2] == (PILOT, MIDDLE) and wider.drill.diameter_mm == 4.0
    with pytest.raises(PlanInputError, match=r"drills\[2\]\.diameter_mm \(2\.5 mm\) must be"):
        replace(plan, drill=replace(FINAL, diameter_mm=2.5))
    with pytest.raises(PlanInputError, match="must list at least one drill"):
        plan.with_drills(())


def test_merge_tells_sequences_apart(tmp_path: Path) -> None:
    """The same trajectory in two files must carry the same drills (sequence included)."""
    plan = _plan()
    save_plan(plan, tmp_path / "a.json")
    save_plan(plan, tmp_path / "same.json")
    (merged,) = load_plan_set([tmp_path / "a.json", tmp_path / "same.json"])
    assert merged.drills == plan.drills
    save_plan(plan.with_drills((MIDDLE, FINAL)), tmp_path / "b.json")
    with pytest.raises(PlanInputError, match=r"b\.json: trajectory 'seq' disagrees"):
        load_plan_set([tmp_path / "a.json", tmp_path / "b.json"])
