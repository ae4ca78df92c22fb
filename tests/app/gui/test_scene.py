"""3D scene geometry (exact) and an off-screen render that must show something."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from ctdrill.app.gui.camera import apply_camera
from ctdrill.app.gui.meshes import drill_mesh, landmark_meshes
from ctdrill.app.gui.scene import (
    CLEARANCE_COLOURS,
    Kept,
    LandmarkGeometry,
    SceneInput,
    bone_surface,
    build_scene,
    clearance_state,
    plan_actors,
    scene_camera,
    set_drill_depth,
)
from ctdrill.app.gui.screenshot import region_stats
from ctdrill.app.gui.stage import Stage
from tests.app.gui.phantom import BAR_SEMI_YZ, ORIGIN_LPS, SPACING_MM, phantom_volume


def test_bone_surface_sits_on_the_phantom_bar() -> None:
    vol = phantom_volume()
    surf = bone_surface(vol.hu, vol.affine_lps, iso_hu=300.0, max_dim=200)
    b = surf.bounds
    # The bar's outer ellipse: y +-8, z +-11 mm (iso-surface within half a voxel).
    assert b[2] == pytest.approx(-BAR_SEMI_YZ[0], abs=SPACING_MM)
    assert b[3] == pytest.approx(BAR_SEMI_YZ[0], abs=SPACING_MM)
    assert b[4] == pytest.approx(-BAR_SEMI_YZ[1], abs=SPACING_MM)
    assert b[5] == pytest.approx(BAR_SEMI_YZ[1], abs=SPACING_MM)
    # Closed at the volume's ends (x), by the air padding.
    assert b[0] == pytest.approx(ORIGIN_LPS[0], abs=SPACING_MM)


def test_bone_surface_follows_a_rotated_affine() -> None:
    vol = phantom_volume()
    rot = np.eye(4)
    rot[:3, :3] = [[0, -1, 0], [1, 0, 0], [0, 0, 1]]  # 90 degrees about S
    surf = bone_surface(vol.hu, rot @ vol.affine_lps, iso_hu=300.0, max_dim=200)
    b = surf.bounds  # the bar now runs along y; its y half-width is along x
    assert b[0] == pytest.approx(-BAR_SEMI_YZ[0], abs=SPACING_MM)
    assert b[1] == pytest.approx(BAR_SEMI_YZ[0], abs=SPACING_MM)


def test_bone_surface_strides_big_volumes_and_is_empty_without_bone() -> None:
    vol = phantom_volume()
    coarse = bone_surface(vol.hu, vol.affine_lps, iso_hu=300.0, max_dim=25)
    fine = bone_surface(vol.hu, vol.affine_lps, iso_hu=300.0, max_dim=200)
    assert 0 < coarse.n_points < fine.n_points / 4
    assert bone_surface(vol.hu, vol.affine_lps, iso_hu=5000.0).n_points == 0


def test_drill_mesh_has_its_tip_at_the_entry_and_the_drill_radius() -> None:
    entry = np.array([1.0, 2.0, 3.0])
    target = np.array([1.0, 5.0, -1.0])
    axis = (target - entry) / 5.0
    mesh = drill_mesh(entry, target, diameter_mm=2.0, tip_length_mm=0.6, shank_mm=20.0)
    rel = np.asarray(mesh.points) - entry
    along = rel @ axis
    perp = np.linalg.norm(rel - along[:, None] * axis, axis=1)
    assert along.max() == pytest.approx(0.0, abs=1e-5)
    assert along.min() == pytest.approx(-20.6, abs=1e-5)
    assert perp.max() == pytest.approx(1.0, abs=1e-5)


def test_clearance_states() -> None:
    assert clearance_state(None, 2.0) == "unknown"  # not computed is never shown as safe
    assert CLEARANCE_COLOURS["unknown"] != CLEARANCE_COLOURS["safe"]
    assert clearance_state(5.0, 2.0, violated=True) == "violated"
    assert clearance_state(3.0, 2.0) == "safe"
    assert clearance_state(2.5, 2.0) == "close"
    assert clearance_state(1.99, 2.0) == "violated"


def test_landmark_envelope_is_the_radius_plus_the_margin() -> None:
    lm = LandmarkGeometry("c", np.array([[-10.0, 0, 0], [10.0, 0, 0]]), 1.2, 2.0)
    body, env = landmark_meshes(lm)
    assert env is not None
    assert np.abs(np.asarray(body.points)[:, 1:]).max() == pytest.approx(1.2, rel=1e-3)
    assert np.abs(np.asarray(env.points)[:, 1:]).max() == pytest.approx(3.2, rel=1e-3)


def test_off_screen_scene_draws_and_the_drill_moves() -> None:
    vol = phantom_volume()
    entry, target = np.array([0.0, 0.0, 12.0]), np.array([0.0, 0.0, 0.0])
    lm = LandmarkGeometry("canal", np.array([[-20.0, 0, -4], [20.0, 0, -4]]), 1.2, 2.0, 1.0)
    scene = SceneInput(entry, target, 2.0, 0.6, 9.0, (lm,))
    plotter = Stage((400, 300))
    try:
        actors = build_scene(plotter, scene, surface=bone_surface(vol.hu, vol.affine_lps))
        assert {"bone", "trajectory", "drill", "stop", "landmark:canal", "margin:canal"} <= set(
            actors
        )
        pose = scene_camera(scene, None)
        assert pose is not None
        apply_camera(plotter, pose)
        before = np.array(actors["drill"].GetBounds())
        set_drill_depth(actors, np.array([0.0, 0.0, -1.0]), 5.0)
        after = np.array(actors["drill"].GetBounds())
        assert after[4] == pytest.approx(before[4] - 5.0)
        img = plotter.screenshot()
        assert region_stats(img).drawn
    finally:
        plotter.close()


def test_a_scene_without_a_trajectory_draws_the_anatomy_and_unknown_landmarks() -> None:
    vol = phantom_volume()
    lm = LandmarkGeometry("canal", np.array([[-20.0, 0, -4], [20.0, 0, -4]]), 1.2, 2.0, None)
    scene = SceneInput(None, None, 0.0, 0.0, None, (lm,))
    plotter = Stage((300, 200))
    try:
        actors = build_scene(plotter, scene, surface=bone_surface(vol.hu, vol.affine_lps))
        assert {"bone", "landmark:canal", "margin:canal"} <= set(actors)
        assert not {"trajectory", "drill", "stop", "target"} & set(actors)
        colour = actors["margin:canal"].GetProperty().GetColor()
        assert colour == pytest.approx(CLEARANCE_COLOURS["unknown"], abs=1 / 255)
    finally:
        plotter.close()


def test_a_rebuild_keeps_the_unchanged_actors_and_redraws_the_changed() -> None:
    entry, target = np.array([0.0, 0.0, 12.0]), np.array([0.0, 0.0, 0.0])
    canal = np.array([[-20.0, 0, -4], [20.0, 0, -4]])
    lm = LandmarkGeometry("canal", canal, 1.2, 2.0, 3.5)
    scene = SceneInput(entry, target, 2.0, 0.6, 9.0, (lm,))
    plotter = Stage((200, 150))
    try:
        kept: Kept = {}
        first = plan_actors(plotter, scene, kept)
        assert set(kept) == set(first)
        # the same scene built from equal (not identical) arrays: every actor kept
        again = plan_actors(plotter, replace(scene, entry_lps=entry.copy()), kept)
        assert all(again[n] is first[n] for n in first)
        # a canal point added and the margin now broken: the canal's two actors and the
        # stop are new, the rest kept; the drill, moved by a rehearsal, is back at the plan
        first["drill"].SetPosition(0.0, 0.0, -3.0)
        lm2 = LandmarkGeometry("canal", np.vstack([canal, [[25.0, 0, -4]]]), 1.2, 2.0, 0.5)
        edited = plan_actors(plotter, replace(scene, landmarks=(lm2,), stop_depth_mm=8.0), kept)
        changed = {n for n in first if edited[n] is not first[n]}
        assert changed == {"landmark:canal", "margin:canal", "stop"}
        assert edited["drill"].GetPosition() == (0.0, 0.0, 0.0)
        colour = edited["margin:canal"].GetProperty().GetColor()
        assert colour == pytest.approx(CLEARANCE_COLOURS["violated"], abs=1 / 255)
        # the canal removed: no longer returned nor kept
        gone = plan_actors(plotter, replace(scene, landmarks=()), kept)
        assert not {"landmark:canal", "margin:canal"} & (set(gone) | set(kept))
    finally:
        plotter.close()


def test_sphere_mesh_is_pyvistas_sphere() -> None:
    """The cached unit sphere scaled and moved gives pyvista's ``Sphere`` of that radius and
    centre: the same faces and normals, the points to float32 rounding."""
    import pyvista as pv

    from ctdrill.app.gui.meshes import sphere_mesh

    for radius, centre in ((0.5, (1.0, -2.0, 30.0)), (1.15, (32.0, 10.0, -41.0))):
        ours = sphere_mesh(radius, np.array(centre))
        theirs = pv.Sphere(radius=radius, center=centre)
        np.testing.assert_array_equal(ours.faces, theirs.faces)
        np.testing.assert_allclose(ours.points, theirs.points, rtol=0, atol=4e-6 * 50.0)
        np.testing.assert_allclose(
            ours.point_data["Normals"], theirs.point_data["Normals"], rtol=0, atol=1e-6
        )
    first = sphere_mesh(1.0, np.zeros(3))
    sphere_mesh(2.0, np.full(3, 5.0))  # another made from the same cached sphere
    np.testing.assert_array_equal(sphere_mesh(1.0, np.zeros(3)).points, first.points)
