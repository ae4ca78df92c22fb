"""The plan problems the window shows (issue 25), headless and in closed form: a vertical implant
beside a straight canal in a small synthetic bone slab, each drill drilled to the apex plus
its tip, implants too close and above the entry, the banner's list and the table's cells."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from ctdrill.app.gui.banner import banner_text
from ctdrill.app.gui.problems import (
    PROBLEM_CODES,
    VIOLATED_MARK,
    implant_check,
    offending_implants,
    plan_problems,
    planned_cells,
)
from ctdrill.app.gui.results import compute_path_view
from ctdrill.imaging import CTVolume
from ctdrill.imaging.plan.implant_safety import implant_clearance, implant_margin_warnings
from ctdrill.imaging.plan.implants import ImplantSpec
from ctdrill.imaging.plan.landmarks import CanalLandmark
from ctdrill.imaging.plan.types import DrillSpec, Plan
from ctdrill.imaging.provenance import SeriesInfo
from ctdrill.imaging.sampling.wall_warnings import bone_wall_warnings
from ctdrill.imaging.sampling.walls import plan_bone_walls
from ctdrill.warning_codes import REGISTRY, LoadWarning

IMPLANT = ImplantSpec(name="p 4 x 10", diameter_mm=4.0, length_mm=10.0, apex_diameter_mm=4.0)
CANAL_R = 1.2
#: The slab's bone edge beyond its last bone voxel (150 HU of a 800 -> -1000 HU step, 0.5 mm).
EDGE = 0.5 * (800.0 - 150.0) / 1800.0


@pytest.fixture(scope="module")
def slab() -> CTVolume:
    """Bone (800 HU) where |x| <= 3 mm, air elsewhere; 0.5 mm voxels, x, y -10..10, z -16..12."""
    x = -10.0 + 0.5 * np.arange(41)
    z = -16.0 + 0.5 * np.arange(57)
    bone = np.abs(x)[None, None, :] <= 3.0
    hu = np.where(bone, 800.0, -1000.0) * np.ones((z.size, 41, 41))
    affine = np.diag([0.5, 0.5, 0.5, 1.0])
    affine[:3, 3] = [-10.0, -10.0, -16.0]
    return CTVolume(hu=hu.astype(np.float32), affine_lps=affine, valid=None, info=SeriesInfo("1"))


def canal(x_mm: float, z_mm: float) -> CanalLandmark:
    """A straight canal along y at (x, z)."""
    pts = np.array([[x_mm, -9.0, z_mm], [x_mm, 9.0, z_mm]])
    return CanalLandmark("canal", pts, radius_mm=CANAL_R)


def vertical(**kw: object) -> Plan:
    """An implant plan: entry z = 10, apex z = -8 on the z axis (platform at z = 2)."""
    base: dict[str, object] = {
        "entry_lps": np.array([0.0, 0.0, 10.0]),
        "target_lps": np.array([0.0, 0.0, -8.0]),
        "implant": IMPLANT,
        "calibration": "bone-literature",
    }
    return Plan(**{**base, **kw})  # type: ignore[arg-type]


def test_registered_codes() -> None:
    registered = {c.code for c in REGISTRY}
    assert set(PROBLEM_CODES) <= registered


def test_an_implant_beside_a_canal_breaks_the_margin_the_drills_keep(slab: CTVolume) -> None:
    d = 5.0  # canal axis 5 mm beside the implant axis, level with the body's side
    drills = (DrillSpec(diameter_mm=2.0, tip_length_mm=0.6), DrillSpec(3.2, 0.8))
    plan = vertical(landmarks=(canal(d, -4.0),)).with_drills(drills)
    view = compute_path_view(slab, plan)
    planned = view.planned
    assert planned is not None and planned.implant_mm is not None
    # clearance = distance - canal radius - implant (drill) radius
    assert planned.implant_mm[0] == pytest.approx(d - CANAL_R - 2.0, abs=1e-6)
    assert planned.osteotomy_mm[0] == pytest.approx(d - CANAL_R - 1.6, abs=1e-6)
    assert planned.osteotomy_drill[0] == 1  # the wider drill is nearer
    assert planned.broken().tolist() == [True]
    codes = [w.code for w in view.problems]
    # the drills keep their margin; the plan's margin covers the implant body too (the engine
    # says so with plan_violates_margin of the body)
    assert codes == ["plan_violates_margin", "implant_violates_margin", "thin_wall"]
    assert "implant body" in view.problems[0].message
    # the messages the outputs write (the imaging functions the engine calls)
    body = implant_margin_warnings(plan, implant_clearance(plan))
    walls = plan_bone_walls(slab, plan)
    assert walls is not None and walls.min_mm == pytest.approx(1.0 + EDGE, abs=1e-3)
    label = f"plan {plan.name!r}: implant {IMPLANT.name!r} ({IMPLANT.size_text})"
    thin = [w for w in bone_wall_warnings(walls, min_wall_mm=1.5, label=label)]
    assert list(view.problems[1:]) == [body[0], thin[0]]
    # the table: 0.5 mm voxels know a clearance to +-0.25 mm: one decimal
    ((implant, osteotomy),) = planned_cells(plan, planned, view.min_clearance_mm)
    assert implant[0] == f"{VIOLATED_MARK} 1.8 mm" and implant[2]
    assert osteotomy[0] == "2.2 mm" and not osteotomy[2]
    assert "drill 2 of 2 (3.2 mm)" in osteotomy[1] and "planned depth 18.80 mm" in osteotomy[1]
    assert offending_implants((plan,), (view,)) == (True,)


def test_each_drill_is_checked_at_the_apex_plus_its_tip(slab: CTVolume) -> None:
    # canal 3.1 + 1.2 mm below the drill's tip (apex z = -8, tip 0.6 mm below): the tip at
    # 18.6 mm keeps 1.9 mm, the implant's flat apex 2.5 mm
    plan = vertical(landmarks=(canal(0.0, -8.0 - 0.6 - CANAL_R - 1.9),))
    view = compute_path_view(slab, plan)
    assert view.planned is not None and view.planned.implant_mm is not None
    assert view.planned.implant_mm[0] == pytest.approx(2.5, abs=1e-6)
    assert view.planned.osteotomy_mm[0] == pytest.approx(1.9, abs=1e-6)
    drill = [w.message for w in view.problems if w.code == "plan_violates_margin"]
    assert len(drill) == 1 and "planned depth 18.600 mm" in drill[0] and "1.900 mm" in drill[0]
    assert "implant_violates_margin" not in {w.code for w in view.problems}


def test_implants_too_close_and_above_the_entry_offend_without_a_ct() -> None:
    a = vertical(name="a")
    b = vertical(name="b", entry_lps=np.array([6.0, 0, 10]), target_lps=np.array([6.0, 0, -8]))
    short = vertical(name="c", entry_lps=np.array([30.0, 0, -2]), target_lps=np.array([30, 0, -8]))
    bare = Plan(entry_lps=np.array([-30.0, 0, 10]), target_lps=np.array([-30.0, 0, 0]), name="d")
    plans = (a, b, short, bare)
    # a and b: 6 mm between axes, 2 mm between their 4 mm bodies (< 3 mm); c 10 mm long in
    # a 6 mm deep osteotomy; d has no implant
    assert offending_implants(plans) == (True, True, True, False)
    far = vertical(name="b", entry_lps=np.array([8.0, 0, 10]), target_lps=np.array([8.0, 0, -8]))
    assert offending_implants((a, far)) == (False, False)


def test_the_banner_lists_every_problem_once_in_order(slab: CTVolume) -> None:
    plan = vertical(landmarks=(canal(5.0, -4.0),))
    view = compute_path_view(slab, plan)
    warnings = [
        LoadWarning("implants_too_close", "two implants 2 mm apart"),
        LoadWarning("plan_default", "x"),
    ]
    extra = plan_problems(warnings, view.problems, view.problems)
    codes = [w.code for w in extra]
    assert codes == [*PROBLEM_CODES[:3], "implants_too_close"]
    shown = replace(view, problems=extra)
    content = banner_text(shown, "", "Coarse data (coarse_voxels): slice step 5 mm")
    assert content is not None
    text, kind = content
    assert kind == "violation" and "4 problems" in text
    assert "the implant and 'canal' are marked red" in text
    for w in extra:
        assert f"({w.code}): {w.message}" in text
    assert text.endswith("Coarse data (coarse_voxels): slice step 5 mm")
    assert banner_text(None, "", "coarse") == ("coarse", "coarse")
    assert banner_text(None, "", "") is None


def test_implant_colours_in_3d_and_on_the_slices() -> None:
    from ctdrill.app.gui.scene import (
        CLEARANCE_COLOURS,
        IMPLANT_COLOUR,
        OTHER_IMPLANT_COLOUR,
        implant_colour,
    )
    from ctdrill.app.gui.scene_plans import implant_geometry
    from ctdrill.app.gui.slice_overlays import CURRENT_COLOUR, OTHER_COLOUR, VIOLATED_COLOUR
    from ctdrill.app.gui.slice_overlays import IMPLANT_COLOUR as SLICE_IMPLANT
    from ctdrill.app.gui.slice_overlays import implant_colour as slice_colour
    from ctdrill.app.gui.slice_scene import trajectory_drawing

    p = vertical()
    expected = {
        (True, False): (IMPLANT_COLOUR, SLICE_IMPLANT),
        (False, False): (OTHER_IMPLANT_COLOUR, OTHER_COLOUR),
        (True, True): (CLEARANCE_COLOURS["violated"], VIOLATED_COLOUR),
        (False, True): (CLEARANCE_COLOURS["violated"], VIOLATED_COLOUR),
    }
    for (current, offending), (in_3d, on_slices) in expected.items():
        geom = implant_geometry(p, current=current, offending=offending)
        assert geom is not None and implant_colour(geom) == in_3d
        tr = trajectory_drawing(p, None, current=current, offending=offending)
        assert slice_colour(tr) == on_slices
    assert CURRENT_COLOUR != VIOLATED_COLOUR


def test_the_path_takes_the_implants_full_grid_outcome(slab: CTVolume) -> None:
    """A drill sequence's view carries the implant outcome its path computed (walls on the
    full grid, as :func:`implant_check` reads them, during a drag as at the release)."""
    d = 5.0
    drills = (DrillSpec(diameter_mm=2.0, tip_length_mm=0.6), DrillSpec(3.2, 0.8))
    plan = vertical(landmarks=(canal(d, -4.0),)).with_drills(drills)
    view = compute_path_view(slab, plan)
    alone = implant_check(slab, plan, view.result.landmarks)
    assert view.implant is not None and alone is not None
    assert view.result.implant is view.implant  # the path's own outcome, not a second read
    assert view.implant.walls is not None and alone.walls is not None
    np.testing.assert_array_equal(view.implant.walls.wall_mm, alone.walls.wall_mm)
    assert view.implant.clearance is not None and alone.clearance is not None
    assert view.implant.clearance.binding_clearance_mm == alone.clearance.binding_clearance_mm


def test_a_final_drill_that_does_not_suit_the_implant_is_a_banner_problem(slab: CTVolume) -> None:
    plan = vertical().with_drills([DrillSpec(2.0), DrillSpec(2.5)])  # 2.5 < 4.0 - 0.8 mm
    view = compute_path_view(slab, plan, plan_set=(plan,))
    found = [w.message for w in view.problems if w.code == "final_drill_mismatch"]
    assert len(found) == 1 and "2.5 mm" in found[0]
