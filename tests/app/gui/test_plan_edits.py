"""Headless plan edits of issue 27: implant drags, canal tracing, measurements, naming, drill
sequences, the readouts: closed forms, no Qt."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ctdrill.app.gui import canal_edit, planning
from ctdrill.app.gui.implant_drag import body_hit, drag_mode, dragged_plan, grips_lps
from ctdrill.app.gui.measure import angle_deg, distance_mm, measure_label, next_points
from ctdrill.app.gui.planning import PlanEditError
from ctdrill.app.gui.readouts import (
    ImplantReadout,
    angulation_deg,
    crest_depth_mm,
    implant_readout,
    nearest_arc_mm,
    readout_text,
)
from ctdrill.app.reformat.region import PANORAMA_HEIGHT_MM, PANORAMA_SHIFT_MM, arch_region
from ctdrill.imaging import CTVolume
from ctdrill.imaging.plan.implants import ImplantSpec
from ctdrill.imaging.plan.landmarks import CanalLandmark
from ctdrill.imaging.plan.types import DrillSpec, Plan
from ctdrill.imaging.provenance import SeriesInfo

IMPLANT = ImplantSpec(name="p 4 x 10", diameter_mm=4.0, length_mm=10.0, apex_diameter_mm=4.0)


def plan(**kw: object) -> Plan:
    base = {"entry_lps": np.array([0.0, 0.0, 15.0]), "target_lps": np.zeros(3)}
    return Plan(**{**base, **kw})  # type: ignore[arg-type]


finite = st.floats(-20.0, 20.0, allow_nan=False)
vec = st.tuples(finite, finite, finite).map(np.array)


# ---------------------------------------------------------------------------- implant drags
def test_a_grip_and_the_keys_choose_the_drag() -> None:
    assert drag_mode("target") == "move" and drag_mode("body") == "move"
    assert drag_mode("platform") == "tilt" and drag_mode("entry", shift=True) == "entry"
    assert drag_mode("body", shift=True) == "slide" and drag_mode("platform", shift=True) == "slide"
    assert drag_mode("target", ctrl=True) == "apex" and drag_mode("body", ctrl=True) == "move"


@settings(max_examples=40, deadline=None)
@given(vec)
def test_moving_keeps_the_axis_and_sliding_keeps_the_entry(delta: np.ndarray) -> None:
    p = plan(implant=IMPLANT)
    start = p.target_lps
    moved = dragged_plan(p, "move", start, start + delta)
    np.testing.assert_allclose(moved.entry_lps - p.entry_lps, delta, atol=1e-12)
    np.testing.assert_allclose(moved.target_lps - p.target_lps, delta, atol=1e-12)
    along = float(delta @ p.direction)
    if p.planned_depth_mm + along >= planning.MIN_DEPTH_MM + 1.0:
        slid = dragged_plan(p, "slide", start, start + delta)
        np.testing.assert_array_equal(slid.entry_lps, p.entry_lps)
        assert slid.planned_depth_mm == pytest.approx(p.planned_depth_mm + along, abs=1e-9)
        np.testing.assert_allclose(slid.direction, p.direction, atol=1e-12)
    else:  # never past the entry: held at the shortest depth
        slid = dragged_plan(p, "slide", start, start + delta)
        np.testing.assert_allclose(slid.direction, p.direction, atol=1e-12)
        assert slid.planned_depth_mm >= planning.MIN_DEPTH_MM


def test_the_platform_tilts_the_implant_about_its_apex() -> None:
    p = plan(implant=IMPLANT)
    top = grips_lps(p)["platform"]
    np.testing.assert_allclose(top, [0.0, 0.0, 10.0])
    # the platform dragged 10 mm to the patient's left: the axis leans 45 degrees about the apex
    tilted = dragged_plan(p, "tilt", top, top + np.array([10.0, 0.0, 0.0]))
    np.testing.assert_array_equal(tilted.target_lps, p.target_lps)
    assert tilted.planned_depth_mm == pytest.approx(15.0)
    np.testing.assert_allclose(tilted.entry_lps, 15.0 / math.sqrt(2.0) * np.array([1, 0, 1]))
    np.testing.assert_allclose(
        grips_lps(tilted)["platform"], 10.0 / math.sqrt(2) * np.array([1, 0, 1])
    )
    with pytest.raises(PlanEditError, match="apex"):
        dragged_plan(p, "tilt", top, np.zeros(3))
    # the apex alone (Ctrl) and the entry alone keep the other end
    apex = dragged_plan(p, "apex", p.target_lps, np.array([1.0, 0.0, 0.0]))
    np.testing.assert_array_equal(apex.entry_lps, p.entry_lps)
    entry = dragged_plan(p, "entry", p.entry_lps, p.entry_lps + np.array([0.0, 2.0, 0.0]))
    np.testing.assert_array_equal(entry.target_lps, p.target_lps)


def test_the_body_is_grabbed_within_its_radius() -> None:
    p = plan(implant=IMPLANT)
    assert body_hit(p, np.array([2.4, 0.0, 5.0]), reach_mm=0.5)  # 2 mm radius + 0.5
    assert not body_hit(p, np.array([2.6, 0.0, 5.0]), reach_mm=0.5)
    assert not body_hit(p, np.array([0.0, 0.0, 12.0]), reach_mm=0.5)  # above the platform
    assert body_hit(plan(), np.array([0.0, 1.4, 12.0]), reach_mm=0.5)  # the drill: 1 mm + 0.5


# ---------------------------------------------------------------------------- canals
def test_traced_points_go_where_the_canal_grows_least() -> None:
    pts = np.array([[0.0, 0, 0], [10.0, 0, 0], [20.0, 0, 0]])
    assert canal_edit.insertion_index(pts, np.array([5.0, 1.0, 0.0])) == 1
    assert canal_edit.insertion_index(pts, np.array([25.0, 0.0, 0.0])) == 3
    assert canal_edit.insertion_index(pts, np.array([-4.0, 1.0, 0.0])) == 0
    assert canal_edit.insertion_index(pts[:1], np.array([1.0, 0.0, 0.0])) == 1
    assert canal_edit.insertion_index(np.empty((0, 3)), np.ones(3)) == 0


def test_canals_by_side_with_their_radius_moved_deleted_renamed() -> None:
    arch = np.array([[-25.0, 30.0, 0.0], [0.0, 0.0, 0.0], [25.0, 30.0, 0.0]])  # a whole arch
    mid = canal_edit.midline_x_mm(arch)
    assert mid == pytest.approx(0.0)
    assert canal_edit.midline_x_mm(arch[1:]) == 0.0  # partial: the scanner's axis
    assert canal_edit.midline_x_mm(arch[:, [1, 0, 2]]) == 0.0  # ends on one side
    assert canal_edit.midline_x_mm(arch + np.array([7.0, 0, 0])) == pytest.approx(7.0)
    assert canal_edit.side_of(np.array([3.0, 0, 0]), mid) == "left"
    p = plan()
    for x in (20.0, 10.0, -20.0, 15.0):
        name = canal_edit.SIDE_NAMES[canal_edit.side_of(np.array([x, 0, 0]), mid)]
        p, _lm, _pt = canal_edit.trace(p, np.array([x, 5.0, -3.0]), name=name, radius_mm=1.5)
    left, right = p.landmarks
    assert isinstance(left, CanalLandmark) and isinstance(right, CanalLandmark)
    assert left.name == "left mandibular canal" and right.name == "right mandibular canal"
    assert left.points_lps[:, 0].tolist() == [20.0, 15.0, 10.0]  # 15 between 20 and 10
    assert right.radius_mm == 1.5
    p = canal_edit.move_point(p, 0, 1, np.array([16.0, 5.0, -3.0]))
    assert p.landmarks[0].points_lps[1, 0] == 16.0
    p = canal_edit.set_radius(p, 1, 1.1)
    assert p.landmarks[1].radius_mm == 1.1
    p = canal_edit.delete_point(p, 1, 0)  # its only point: the canal goes
    assert [lm.name for lm in p.landmarks] == ["left mandibular canal"]
    p = canal_edit.rename_landmark(p, 0, " IAN left ")
    assert p.landmarks[0].name == "IAN left"
    for bad in (
        lambda: canal_edit.set_radius(p, 0, 0.0),
        lambda: canal_edit.move_point(p, 0, 9, np.zeros(3)),
        lambda: canal_edit.trace(p, np.array([np.nan, 0, 0]), name="x"),
        lambda: canal_edit.rename_landmark(p, 0, " "),
    ):
        with pytest.raises(PlanEditError):
            bad()


# ---------------------------------------------------------------------------- measurements
def test_distance_and_angle_are_measured_in_the_patient() -> None:
    a, v, b = np.array([3.0, 0, 0]), np.zeros(3), np.array([0.0, 4.0, 0])
    assert distance_mm(a, b) == pytest.approx(5.0)
    assert angle_deg(a, v, b) == pytest.approx(90.0)
    assert angle_deg(a, v, 2 * a) == pytest.approx(0.0, abs=1e-12)
    assert angle_deg(a, v, np.array([-1.0, 1e-9, 0])) == pytest.approx(180.0)
    assert math.isnan(angle_deg(a, v, v))
    points: list[np.ndarray] = []
    for p in (a, v, b):
        points = next_points("angle", points, p)
    assert measure_label("angle", points) == "90.0°"
    assert next_points("angle", points, b) == [b]  # a fourth click starts again
    assert measure_label("distance", [a, b]) == "5.00 mm"
    assert measure_label("distance", [a]) is None


# ---------------------------------------------------------------------------- naming, drills
def test_trajectories_placed_or_added_are_named_implant_n() -> None:
    assert planning.unique_name(()) == "implant 1"
    first = planning.place_handle(None, {"entry": np.array([0.0, 0, 10])}, "target", np.zeros(3))
    assert isinstance(first, Plan) and first.name == "implant 1"
    new, _ = planning.new_trajectory([replace(first, site=36)], 0)
    assert new.name == "implant 2" and new.site is None  # a new site, not the copied one


def test_the_drill_sequence_is_written_as_diameters() -> None:
    p = plan(drill=DrillSpec(diameter_mm=3.5, tip_length_mm=1.0))
    assert planning.drills_text(p) == "3.5"
    seq = planning.with_drill_sequence(p, "2 -> 2.8mm, 3.5")
    assert [d.diameter_mm for d in seq.drills] == [2.0, 2.8, 3.5]
    # a new diameter takes the tip rule's tip, not the final drill's (the typed-tips defect)
    assert seq.drill == p.drill and [d.tip_length_mm for d in seq.drills] == [0.6, 0.8, 1.0]
    assert planning.drills_text(seq) == "2 -> 2.8 -> 3.5"
    for bad, words in (("", "at least one"), ("3 -> 2", "must be larger"), ("two", "diameter")):
        with pytest.raises(PlanEditError, match=words):
            planning.with_drill_sequence(p, bad)


# ---------------------------------------------------------------------------- readouts
def test_angulation_in_the_arch_frame() -> None:
    arch = np.array([[-30.0, 0.0, 0.0], [30.0, 0.0, 0.0], [30.0, 40.0, 0.0]])
    # at x = -10 on the first segment: tangent +x (mesial toward the arch's middle, +x),
    # buccal away from the arch's centre (-y)
    p = plan(entry_lps=np.array([-10.0 + 3.0, -4.0, 10.0]), target_lps=np.array([-10.0, 0, 0]))
    tilt, bl, md = angulation_deg(p, arch)
    assert tilt == pytest.approx(math.degrees(math.atan2(5.0, 10.0)))
    assert bl == pytest.approx(math.degrees(math.atan2(4.0, 10.0)))
    assert md == pytest.approx(math.degrees(math.atan2(3.0, 10.0)))
    assert angulation_deg(p, None)[1:] == (None, None)
    assert nearest_arc_mm(arch, np.array([31.0, 20.0, 5.0])) == pytest.approx(80.0)


def test_the_platform_below_the_crest_and_the_walls_around_the_implant() -> None:
    # bone (800 HU) below z = 0 and within |x| <= 3 mm, air elsewhere
    z = np.arange(-20.0, 20.01, 0.5)
    x = -5.0 + 0.5 * np.arange(20)
    bone = (z[:, None, None] < 0.0) & (np.abs(x)[None, None, :] <= 3.0)
    hu = np.where(bone, 800.0, -1000.0) * np.ones((z.size, 20, 20))
    affine = np.diag([0.5, 0.5, 0.5, 1.0])
    affine[:3, 3] = [-5.0, -5.0, -20.0]
    volume = CTVolume(
        hu=hu.astype(np.float32), affine_lps=affine, valid=None, info=SeriesInfo("1.2")
    )
    p = plan(entry_lps=np.array([0.0, 0.0, 10.0]), target_lps=np.array([0.0, 0.0, -12.0]))
    crest, of = crest_depth_mm(volume, p)
    edge = 0.5 * (800.0 - 150.0) / 1800.0  # 150 HU that far from a bone voxel toward air
    assert of == "apex" and crest == pytest.approx(12.0 - 0.5 + edge, abs=1e-5)
    with_implant = plan(entry_lps=p.entry_lps, target_lps=p.target_lps, implant=IMPLANT)
    crest, of = crest_depth_mm(volume, with_implant)  # platform at z = -2
    assert of == "platform" and crest == pytest.approx(2.0 - 0.5 + edge, abs=1e-5)
    # the wall along +-x: from the body (radius 2) to the bone's edge at x = 3 + edge
    r = implant_readout(volume, with_implant)
    assert r.wall_mm == pytest.approx(1.0 + edge, abs=1e-3)
    assert r.canal_mm is None and r.buccal_mm is None  # no landmark, no arch
    text = readout_text(r)
    # 0.5 mm voxels: lengths known to +-0.25 mm, written to 0.1 mm (imaging.resolution)
    assert "thinnest wall 1.2 mm" in text and "canal: none traced" in text  # the full grid
    text = readout_text(ImplantReadout(tilt_deg=0.0, crest_depth_mm=-1.5, crest_of="platform"))
    assert "platform 1.5 mm above the crest" in text


def test_the_panorama_shows_the_arch_region() -> None:
    affine = np.diag([1.0, 1.0, 1.0, 1.0])
    affine[:3, 3] = [0.0, 0.0, 600.0]
    tall = CTVolume(np.zeros((136, 4, 4), np.float32), affine, None, SeriesInfo("1"))  # 135 mm
    arch = np.array([[0.0, 0.0, 650.0], [3.0, 0.0, 650.0]])
    down = plan(entry_lps=np.array([0.0, 0, 660]), target_lps=np.array([0.0, 0, 648]))
    assert arch_region(tall, arch, [down]) == (PANORAMA_HEIGHT_MM, 650.0 - PANORAMA_SHIFT_MM)
    up = plan(entry_lps=np.array([0.0, 0, 640]), target_lps=np.array([0.0, 0, 652]))
    assert arch_region(tall, arch, [up]) == (PANORAMA_HEIGHT_MM, 650.0 + PANORAMA_SHIFT_MM)
    low = arch - np.array([0.0, 0.0, 45.0])  # near the scan's bottom: the window stays inside
    assert arch_region(tall, low, []) == (PANORAMA_HEIGHT_MM, 600.0 + 0.5 * PANORAMA_HEIGHT_MM)
    short = CTVolume(np.zeros((50, 4, 4), np.float32), affine, None, SeriesInfo("1"))
    assert arch_region(short, arch, []) == (None, None)  # not taller: its whole height
