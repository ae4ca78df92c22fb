"""Every drill's tip follows from its diameter and point angle by the one tip rule, wherever the
drill comes from; a tip given that differs is a named override; a plan never contradicts its
implant's protocol."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st

from ctdrill.engine.plans import with_set_warnings
from ctdrill.imaging.plan.drill_spec import DrillSpec, tip_length_rule_mm
from ctdrill.imaging.plan.implants import ImplantSpec, load_implant_library
from ctdrill.imaging.plan.load import load_plan
from ctdrill.imaging.plan.protocol import generic_tip_length_mm
from ctdrill.imaging.plan.types import Plan, plan_warnings
from ctdrill.imaging.plan.write import plan_to_markups, save_plan
from tests.imaging.slicer_files import slicer_save


def _cone_tip_mm(diameter_mm: float, angle_deg: float) -> float:
    """The cone's length from its half-angle, by right-triangle trigonometry, to 0.1 mm."""
    radius = diameter_mm / 2.0
    return round(
        radius * math.cos(math.radians(angle_deg / 2)) / math.sin(math.radians(angle_deg / 2)), 1
    )


def test_the_rule_is_the_cone_of_the_point_angle() -> None:
    for d, tip in ((2.0, 0.6), (2.8, 0.8), (3.5, 1.0), (4.4, 1.3), (2.5, 0.7)):
        assert tip_length_rule_mm(d) == tip
        assert DrillSpec(d).tip_length_mm == tip  # a drill built without a tip
        assert generic_tip_length_mm(d) == tip  # the generic protocol asks the same rule
    assert DrillSpec(3.0, point_angle_deg=90.0).tip_length_mm == 1.5
    assert DrillSpec().tip_length_mm == 0.6 and not DrillSpec().tip_override


@given(st.floats(1.0, 8.0).map(lambda v: round(v, 1)), st.sampled_from([90.0, 118.0, 120.0, 135.0]))
def test_rule_matches_an_independent_cone(diameter_mm: float, angle_deg: float) -> None:
    assert (
        abs(
            DrillSpec(diameter_mm, point_angle_deg=angle_deg).tip_length_mm
            - _cone_tip_mm(diameter_mm, angle_deg)
        )
        <= 0.1 + 1e-9
    )


def test_a_given_tip_that_differs_is_a_named_override() -> None:
    plan = Plan([0, 0, 0], [0, 0, -12]).with_drills([DrillSpec(2.0), DrillSpec(3.5, 1.4)])
    assert [d.tip_override for d in plan.drills] == [False, True]
    (marked,) = with_set_warnings([plan])
    found = [w.message for w in plan_warnings(marked) if w.code == "drill_tip_override"]
    assert len(found) == 1 and "3.5 mm drill" in found[0] and "1 mm" in found[0]


def _doc(**extra: Any) -> dict[str, Any]:
    return {"format": "ctdrill-plan/1", "entry_mm": [0, 0, 0], "target_mm": [0, 0, -12], **extra}


def test_every_source_gives_the_same_drills(tmp_path: Path) -> None:
    spec = next(s for s in load_implant_library() if s.name == "tapered 4.1 x 11.5")
    # a plan file giving diameters only
    path = tmp_path / "p.json"
    path.write_text(json.dumps(_doc(drills=[{"diameter_mm": d} for d in (2.0, 2.8, 3.5)])))
    from_file = load_plan(path)
    # the implant's protocol (no drills given)
    path2 = tmp_path / "q.json"
    path2.write_text(json.dumps(_doc(implant=spec.to_json())))
    from_protocol = load_plan(path2)
    # typed in the window, and picking the implant in the window
    from ctdrill.app.gui import planning

    base = Plan([0, 0, 0], [0, 0, -12])
    typed = planning.with_drill_sequence(base, "2 -> 2.8 -> 3.5")
    picked = planning.with_implant(base, spec)
    # a Slicer line description after a Slicer save
    mrk = tmp_path / "t.mrk.json"
    mrk.write_text(json.dumps(plan_to_markups(from_file)))
    case = tmp_path / "case"
    case.mkdir()
    slicer_save(mrk, case)
    from_slicer = load_plan(next(case.glob("*.mrk.json")))
    tips = [0.6, 0.8, 1.0]
    for plan in (from_file, from_protocol, typed, picked, from_slicer):
        assert [d.tip_length_mm for d in plan.drills] == tips
    for plan in (from_protocol, picked):  # each drill's full diameter to the apex (12 mm)
        assert plan.drill_depths_mm() == pytest.approx((12.6, 12.8, 13.0), abs=1e-9)


def test_a_plan_contradicting_its_implant_is_reconciled_and_saved_whole(tmp_path: Path) -> None:
    spec = ImplantSpec(
        "tapered 4.1 x 10",
        4.1,
        10.0,
        2.9,
        "round",
        drills=(DrillSpec(2.0), DrillSpec(2.8), DrillSpec(3.5)),
    )
    doc = _doc(
        implant=spec.to_json(),
        drills=[{"diameter_mm": d, "tip_length_mm": 0.6} for d in (2.0, 2.8, 3.5)],
    )
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(doc))
    plan = load_plan(path)
    assert [d.tip_length_mm for d in plan.drills] == [0.6, 0.8, 1.0]
    codes = [w.code for w in plan_warnings(plan)]
    assert codes.count("drills_reconciled") == 2
    # built in code: reconciled the same way, never held contradicting
    built = Plan([0, 0, 0], [0, 0, -12], implant=spec).with_drills(
        [DrillSpec(2.0, 0.6), DrillSpec(2.8, 0.6), DrillSpec(3.5, 0.6)]
    )
    assert [d.tip_length_mm for d in built.drills] == [0.6, 0.8, 1.0]
    out = tmp_path / "saved.json"
    save_plan(built, out)
    saved = json.loads(out.read_text())
    traj = {d["diameter_mm"]: d["tip_length_mm"] for d in saved["drills"]}
    imp = {d["diameter_mm"]: d["tip_length_mm"] for d in saved["implant"]["drills"]}
    assert traj == imp


def test_point_angle_is_read_and_checked(tmp_path: Path) -> None:
    path = tmp_path / "p.json"
    path.write_text(json.dumps(_doc(drill={"diameter_mm": 3.0, "point_angle_deg": 90})))
    assert load_plan(path).drill.tip_length_mm == 1.5
    path.write_text(json.dumps(_doc(drill={"diameter_mm": 3.0, "point_angle_deg": 200})))
    with pytest.raises(ValueError, match=r"drill\.point_angle_deg must be between"):
        load_plan(path)
