"""Overlays (canal zones, bodies) and the shared drawing of a reformat."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")

import numpy as np
import pytest
from matplotlib.figure import Figure

from ctdrill.app.reformat import draw as draw_module
from ctdrill.app.reformat.draw import FONT_PT, draw_reformat
from ctdrill.app.reformat.overlay import body_overlay, drill_profile_mm, tube_overlay
from ctdrill.imaging.phantom.mandible import make_mandible_phantom
from ctdrill.imaging.plan.read import read_plans
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


def _stand_in_implant(plan: Any) -> tuple[np.ndarray, ...] | None:
    """A 4 x 10 mm tapered implant, apex at the target (planmodel's placement rule)."""
    axis = (plan.target_lps - plan.entry_lps) / np.linalg.norm(plan.target_lps - plan.entry_lps)
    s = np.array([0.0, 9.0, 10.0])
    r = np.array([2.0, 1.6, 0.0])
    return (plan.target_lps - 10.0 * axis, axis, s, r, "stand-in 4x10")  # type: ignore[return-value]


def test_draw_demo_panorama_and_cross_section(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(draw_module, "implant_body", _stand_in_implant)
    ph = make_mandible_phantom()
    vol = CTVolume(hu=ph.hu, affine_lps=ph.affine_lps, valid=None, info=SeriesInfo(series_uid="1"))
    plan_file = tmp_path / "plan.json"
    import json

    plan_file.write_text(json.dumps(ph.plan))
    plans = read_plans(plan_file)
    g = ph.geometry
    ang = np.linspace(-0.45, 0.45, 15)
    arch = np.stack(
        [
            g.arch_centre_xy_lps[0] + g.arch_radius_mm * np.cos(ang),
            g.arch_centre_xy_lps[1] + g.arch_radius_mm * np.sin(ang),
            np.full(15, -33.0),
        ],
        1,
    )
    pano = panorama(vol, arch, slab_mm=4.0)
    plan = plans[0]
    cs = cross_section(vol, arch, axis=(plan.entry_lps, plan.target_lps))
    fig = Figure(figsize=(12, 8), dpi=100)
    ax1, ax2 = fig.add_subplot(1, 2, 1), fig.add_subplot(1, 2, 2)
    d1 = draw_reformat(ax1, pano, plans, cross_section_at_mm=cs.at_arc_mm)
    d2 = draw_reformat(ax2, cs, plans)
    fig.savefig(tmp_path / "demo.png")
    for d in (d1, d2):
        assert [t.visible for t in d.tubes] == [True]
        assert [b.visible for b in d.bodies] == [True]
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
