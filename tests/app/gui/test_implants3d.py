"""Implant bodies in 3D: the solid of revolution of ImplantSpec.profile_mm() placed by
implant_placement, for every trajectory of a plan file (the selected one highlighted)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from ctdrill.app.gui.meshes import implant_mesh, revolution_mesh
from ctdrill.app.gui.scene_plans import implant_geometry, plans_scene
from ctdrill.imaging.plan.implants import ImplantSpec, implant_placement
from ctdrill.imaging.plan.load import load_plans

ROOT = Path(__file__).resolve().parents[3]
RES = 40


def _polygon_area(r: float, n: int = RES) -> float:
    return 0.5 * n * r * r * np.sin(2.0 * np.pi / n)


def _frusta_volume(s: np.ndarray, r: np.ndarray) -> float:
    """Volume of stacked frusta of regular n-gons (exact for the mesh's rings)."""
    a = np.array([_polygon_area(x) for x in r])
    h = np.diff(s)
    return float(np.sum(h / 3.0 * (a[:-1] + a[1:] + np.sqrt(a[:-1] * a[1:]))))


@pytest.mark.parametrize("apex", ["flat", "round"])
def test_the_body_is_the_closed_solid_of_its_profile(apex: str) -> None:
    spec = ImplantSpec("t", 4.1, 11.5, 3.0 if apex == "flat" else 3.4, apex)
    s, r = spec.profile_mm()
    base = np.array([3.0, -2.0, 10.0])
    axis = np.array([0.3, 0.2, -1.0])
    unit = axis / np.linalg.norm(axis)
    mesh = implant_mesh(base, axis, s, r, resolution=RES)
    assert mesh.n_open_edges == 0  # closed: a solid
    assert mesh.volume == pytest.approx(_frusta_volume(s, r), rel=1e-9)
    rel = np.asarray(mesh.points) - base
    along = rel @ unit
    radial = np.linalg.norm(rel - along[:, None] * unit, axis=1)
    assert along.min() == pytest.approx(0.0, abs=1e-9)
    assert along.max() == pytest.approx(spec.length_mm, abs=1e-9)
    # every point is on a ring of the profile (s_m, r_m), or the centre of an end cap
    ring = (np.abs(along[:, None] - s[None, :]) < 1e-9) & (np.abs(radial[:, None] - r) < 1e-9)
    cap = (radial < 1e-9) & ((along < 1e-9) | (along > spec.length_mm - 1e-9))
    assert np.all(ring.any(axis=1) | cap)
    assert ring.any(axis=0).all()  # and every ring of the profile is there
    assert radial.max() == pytest.approx(spec.diameter_mm / 2.0)


def test_a_profile_must_be_a_profile() -> None:
    with pytest.raises(ValueError, match="profile"):
        revolution_mesh(np.zeros(3), np.array([0, 0, 1.0]), np.array([0.0, 2.0, 1.0]), np.ones(3))
    with pytest.raises(ValueError, match="profile"):
        revolution_mesh(np.zeros(3), np.array([0, 0, 1.0]), np.array([0.0]), np.array([1.0]))


def test_every_trajectory_gets_its_implant_and_the_selected_one_is_marked() -> None:
    demo = load_plans(ROOT / "assets" / "demo" / "plan.json")
    plan = demo[0]
    assert plan.implant is not None and plan.arch_lps is not None
    other = replace(
        plan,
        name="second",
        entry_lps=plan.entry_lps + np.array([8.0, 0.0, 0.0]),
        target_lps=plan.target_lps + np.array([8.0, 0.0, 0.0]),
        implant=ImplantSpec("narrow", 3.3, 10.0, 2.8, "flat"),
    )
    no_implant = replace(plan, name="third", implant=None)
    scene = plans_scene((plan, other, no_implant), 1, None)
    assert [g.name for g in scene.implants] == [plan.implant.name, "narrow"]
    assert [g.current for g in scene.implants] == [False, True]
    np.testing.assert_allclose(scene.entry_lps, other.entry_lps)  # the selected one in full
    assert [o.name for o in scene.others] == [plan.name, "third"]
    np.testing.assert_allclose(scene.arch_lps, other.arch_lps)
    place = implant_placement(other)
    geom = implant_geometry(other)
    assert place is not None and geom is not None
    np.testing.assert_allclose(geom.platform_lps, place.platform_lps)
    np.testing.assert_allclose(geom.axis_lps, place.axis_lps)
    # the apex at the target
    np.testing.assert_allclose(geom.platform_lps + 10.0 * geom.axis_lps, other.target_lps)
    assert implant_geometry(no_implant) is None


def test_no_plans_is_the_anatomy_alone() -> None:
    scene = plans_scene((), 0, None)
    assert scene.entry_lps is None and scene.implants == () and scene.others == ()


def test_a_plan_is_drawn_with_its_implant_in_the_off_screen_render() -> None:
    from ctdrill.app.gui.compute import volume_surface
    from ctdrill.app.gui.offscreen import render_offscreen
    from ctdrill.imaging import load_series

    demo = load_plans(ROOT / "assets" / "demo" / "plan.json")
    vol = load_series(ROOT / "assets" / "demo" / "ct")
    surf = volume_surface(vol)
    with_implant = render_offscreen(surf, plans_scene(demo, 0, None), size_px=(320, 240))
    bare = tuple(replace(p, implant=None) for p in demo)
    without = render_offscreen(surf, plans_scene(bare, 0, None), size_px=(320, 240))
    rgb_w, rgb_wo = with_implant.astype(int), without.astype(int)

    def cyan(rgb: np.ndarray) -> int:
        return int(np.sum((rgb[..., 1] - rgb[..., 0] > 60) & (rgb[..., 2] - rgb[..., 0] > 60)))

    assert cyan(rgb_w) > cyan(rgb_wo) + 100
