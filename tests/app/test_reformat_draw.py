"""Overlays (canal zones, bodies) and the shared drawing of a reformat."""

from __future__ import annotations

import json
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import numpy as np
import pytest
from matplotlib.figure import Figure

from ctdrill.app.reformat.draw import FONT_PT, draw_reformat
from ctdrill.app.reformat.overlay import body_overlay, drill_profile_mm, tube_overlay
from ctdrill.engine.path import plan_path
from ctdrill.engine.plans import plan_calibration
from ctdrill.imaging.phantom.mandible import make_mandible_phantom
from ctdrill.imaging.plan.load import load_plans
from ctdrill.imaging.sampling.reformat import cross_section, panorama
from ctdrill.imaging.volume import CTVolume, SeriesInfo


def flat_volume() -> CTVolume:
    aff = np.eye(4)
    aff[:3, 3] = (-20.0, -20.0, -20.0)
    hu = np.full((41, 41, 41), 300, np.int16)
    return CTVolume(hu=hu, affine_lps=aff, valid=None, info=SeriesInfo(series_uid="1"))


ARCH = np.array([[-15.0, 0.0, 0.0], [15.0, 0.0, 0.0]])  # along +x: normal +y


def test_tube_across_a_cross_section_is_a_disc_of_its_radius() -> None:
    vol = flat_volume()
    cs = cross_section(
        vol, ARCH, at_arc_mm=15.0, pixel_mm=0.5, width_mm=20.0, height_mm=20.0, slab_mm=0.0
    )
    # The plane is x = 0 (columns along +y, rows down -z); a canal along x through (0, 2, -3).
    canal = np.array([[-6.0, 2.0, -3.0], [0.0, 2.0, -3.0], [6.0, 2.0, -3.0]])
    tube = tube_overlay(cs, canal, 1.2, 2.0, "canal")
    h, w = cs.shape
    i, j = np.mgrid[0:h, 0:w]
    uv0 = cs.project(np.array([[0.0, 2.0, -3.0]]))[0][0]
    expect = np.hypot(j * 0.5 - uv0[0], i * 0.5 - uv0[1])
    reach = expect <= 4.2 - 1e-6  # the zone (3.2 mm) and two pixels beyond, for the contours
    np.testing.assert_allclose(tube.distance_mm[reach], expect[reach], atol=1e-9)
    assert np.all(np.isinf(tube.distance_mm[expect > 4.2 + 1e-6]))
    assert tube.visible and tube.caption() is None and tube.gap_mm == 0.0


def test_a_tube_drawn_again_on_the_same_reformat_is_the_one_computed() -> None:
    vol = flat_volume()
    cs = cross_section(
        vol, ARCH, at_arc_mm=15.0, pixel_mm=0.5, width_mm=20.0, height_mm=20.0, slab_mm=0.0
    )
    canal = np.array([[-6.0, 2.0, -3.0], [0.0, 2.0, -3.0], [6.0, 2.0, -3.0]])
    tube = tube_overlay(cs, canal, 1.2, 2.0, "canal")
    assert tube_overlay(cs, canal.copy(), 1.2, 2.0, "canal") is tube
    wider = tube_overlay(cs, canal, 1.5, 2.0, "canal")
    assert wider is not tube and wider.radius_mm == 1.5
    moved = canal + np.array([0.0, 0.5, 0.0])
    assert not np.array_equal(
        tube_overlay(cs, moved, 1.2, 2.0, "canal").distance_mm, tube.distance_mm
    )
    other = cross_section(
        vol, ARCH, at_arc_mm=15.0, pixel_mm=0.5, width_mm=20.0, height_mm=20.0, slab_mm=0.0
    )
    again = tube_overlay(other, canal, 1.2, 2.0, "canal")  # another image: computed, the same
    assert again is not tube
    np.testing.assert_array_equal(again.distance_mm, tube.distance_mm)
    assert not tube.distance_mm.flags.writeable
    assert all(not run.flags.writeable for run in tube.centre_runs_uv)


def test_tube_outside_the_slab_is_named_with_its_distance() -> None:
    vol = flat_volume()
    cs = cross_section(vol, ARCH, at_arc_mm=15.0, pixel_mm=0.5, slab_mm=2.0)
    # Parallel to the plane (along y), 6 mm in front of it: 6 - 1 (half slab) - 1.2 - 2.0.
    canal = np.array([[6.0, -5.0, 0.0], [6.0, 5.0, 0.0]])
    tube = tube_overlay(cs, canal, 1.2, 2.0, "left canal")
    assert not tube.visible
    assert tube.gap_mm == pytest.approx(1.8)
    assert tube.caption() == "left canal: 1.8 mm outside the slab (margin zone), not drawn"


def test_body_outline_on_a_cross_section_and_the_drill_profile() -> None:
    vol = flat_volume()
    entry, target = np.array([0.0, 1.0, 6.0]), np.array([0.0, 1.0, -4.0])
    cs = cross_section(vol, ARCH, axis=(entry, target), pixel_mm=0.5, slab_mm=1.0)
    s, r = drill_profile_mm(8.0, 2.0, 0.6)
    np.testing.assert_allclose(s, [0.0, 7.4, 8.0])
    np.testing.assert_allclose(r, [1.0, 1.0, 0.0])
    np.testing.assert_allclose(drill_profile_mm(0.3, 2.0, 0.6)[1], [0.5, 0.0])
    body = body_overlay(cs, entry, target - entry, s, r, "drill")
    assert body.visible
    centre_u, centre_v = 20.0, 20.0  # the axis midpoint is the image centre
    # Column direction +y; entry 5 mm above the centre; a 1 mm radius on both sides.
    u = body.outline_uv[:, 0]
    v = body.outline_uv[:, 1]
    np.testing.assert_allclose(sorted(set(np.round(u, 9))), [centre_u - 1, centre_u, centre_u + 1])
    assert v.min() == pytest.approx(centre_v - 5.0) and v.max() == pytest.approx(centre_v + 3.0)
    far = body_overlay(cs, entry + np.array([5.0, 0, 0]), target - entry, s, r, "drill")
    assert far.gap_mm == pytest.approx(5.0 - 0.5 - 1.0)
    assert far.caption() == "drill: 3.5 mm outside the slab, not drawn"


def test_draw_demo_panorama_and_cross_section(tmp_path: Path) -> None:
    ph = make_mandible_phantom()
    vol = CTVolume(hu=ph.hu, affine_lps=ph.affine_lps, valid=None, info=SeriesInfo(series_uid="1"))
    plan_file = tmp_path / "plan.json"
    plan_file.write_text(json.dumps(ph.plan))
    plans = load_plans(plan_file)
    plan = plans[0]
    assert plan.arch_lps is not None and plan.implant is not None
    pano = panorama(vol, plan.arch_lps, slab_mm=4.0)
    cs = cross_section(vol, plan.arch_lps, axis=(plan.entry_lps, plan.target_lps))
    path = plan_path(vol, plan, plan_calibration(plan))
    fig = Figure(figsize=(12, 8), dpi=100)
    ax1, ax2 = fig.add_subplot(1, 2, 1), fig.add_subplot(1, 2, 2)
    d1 = draw_reformat(ax1, pano, plans, paths=[path], cross_section_at_mm=cs.at_arc_mm)
    d2 = draw_reformat(ax2, cs, plans, paths=[path])
    fig.savefig(tmp_path / "demo.png")
    for d in (d1, d2):
        assert [t.visible for t in d.tubes] == [True]
        assert [b.visible for b in d.bodies] == [True, True]  # implant, drill
        assert d.captions == []
    # The vertical implant on the cross-section: apex at the target, platform its length
    # above, its diameter across.
    implant, drill = d2.bodies
    (u_t, v_t), (_u_e, v_e) = cs.project(np.stack([plan.target_lps, plan.entry_lps]))[0]
    spec = plan.implant
    assert implant.outline_uv[:, 1].max() == pytest.approx(v_t, abs=1e-9)
    assert implant.outline_uv[:, 1].min() == pytest.approx(v_t - spec.length_mm, abs=1e-9)
    half = implant.outline_uv[:, 0] - u_t
    assert half.max() == pytest.approx(spec.diameter_mm / 2, abs=1e-9)
    assert half.min() == pytest.approx(-spec.diameter_mm / 2, abs=1e-9)
    # The drill from the entry to its stop depth, its diameter across.
    assert drill.outline_uv[:, 1].min() == pytest.approx(v_e, abs=1e-9)
    assert drill.outline_uv[:, 1].max() == pytest.approx(v_e + path.stop_depth_mm, abs=1e-9)
    assert np.ptp(drill.outline_uv[:, 0]) == pytest.approx(plan.drill.diameter_mm, abs=1e-9)
    # The image covers its pixels' true millimetre extent, equal aspect.
    w_mm, h_mm = pano.extent_mm
    p = pano.pixel_mm
    assert ax1.get_images()[0].get_extent() == pytest.approx(
        [-p / 2, w_mm + p / 2, h_mm + p / 2, -p / 2]
    )
    assert ax1.get_aspect() == 1.0
    sizes = [t.get_fontsize() for ax in (ax1, ax2) for t in ax.texts]
    assert min(sizes) >= FONT_PT
    letters = [t.get_text() for t in ax1.texts]
    assert "R" in letters and "L" in letters and "S" in letters
    assert {t.get_text() for t in ax2.texts} >= {"B", "Li", "arch"}
    assert d1.scale_bar_mm == 10.0
