"""The starting camera: outside the anatomy, the target at the focal point, the whole box in
view, looking from the buccal side of the entry; and the orientation marker's letters."""

from __future__ import annotations

import numpy as np
import pytest

from ctdrill.app.gui.camera import (
    CLEARANCE_MM,
    LETTER_COLOUR,
    ORIENTATION_LETTERS,
    TILT_DEG,
    VIEW_ANGLE_DEG,
    buccal_direction,
    fit_distance_mm,
    initial_camera,
    orientation_cube,
    scene_bounds,
)

#: A jaw-sized box, LPS mm: x (R -> L) -50..50, y (A -> P) -60..10, z -40..0.
JAW = (-50.0, 50.0, -60.0, 10.0, -40.0, 0.0)


def _corners(b: tuple[float, ...]) -> np.ndarray:
    return np.array([[x, y, z] for x in b[:2] for y in b[2:4] for z in b[4:]])


def _check_pose_sees_the_box(pose: object, bounds: tuple[float, ...]) -> None:
    pos = pose.position_lps  # type: ignore[attr-defined]
    focal = pose.focal_lps  # type: ignore[attr-defined]
    view = pose.view_dir  # type: ignore[attr-defined]
    rel = _corners(bounds) - pos
    # every corner is in front of the camera, within half the view angle of its axis
    cos = (rel @ -view) / np.linalg.norm(rel, axis=1)
    assert np.all(cos >= np.cos(np.deg2rad(VIEW_ANGLE_DEG / 2.0)) - 1e-9)
    # the camera stands outside the box, at least CLEARANCE_MM beyond it along the view
    assert (pos - focal) @ view >= np.max((_corners(bounds) - focal) @ view) + CLEARANCE_MM - 1e-9
    lo, hi = np.array(bounds[::2]), np.array(bounds[1::2])
    assert not np.all((pos >= lo) & (pos <= hi))
    up = pose.up  # type: ignore[attr-defined]
    assert abs(up @ view) < 1e-9 and up[2] > 0 and np.linalg.norm(up) == pytest.approx(1.0)


def test_a_molar_on_the_right_is_seen_from_the_right_cheek() -> None:
    entry = np.array([-35.0, -20.0, 0.0])  # patient right (x < 0), on the crest
    target = np.array([-35.0, -20.0, -12.0])  # straight down
    pose = initial_camera(JAW, entry, target)
    np.testing.assert_allclose(pose.focal_lps, target)
    # buccal = away from the box's centre (0, -25) through the entry: towards -x mostly
    horiz = pose.view_dir[:2] / np.linalg.norm(pose.view_dir[:2])
    want = np.array([-35.0, 5.0]) / np.hypot(35.0, 5.0)
    np.testing.assert_allclose(horiz, want, atol=1e-9)
    assert np.degrees(np.arcsin(pose.view_dir[2])) == pytest.approx(TILT_DEG)
    _check_pose_sees_the_box(pose, JAW)


def test_an_incisor_is_seen_from_the_front_and_the_arch_centre_decides_the_side() -> None:
    entry = np.array([0.0, -55.0, 0.0])
    target = np.array([0.0, -50.0, -12.0])  # tilted lingually
    pose = initial_camera(JAW, entry, target)
    assert pose.position_lps[1] < target[1]  # anterior of the target
    axis = (target - entry) / np.linalg.norm(target - entry)
    # the drill crosses the screen: it leaves the screen plane by no more than the tilt
    assert abs(pose.view_dir @ axis) <= np.sin(np.deg2rad(TILT_DEG)) + 1e-9
    _check_pose_sees_the_box(pose, JAW)
    # an arch centre behind the entry keeps the anterior side; one in front flips it
    front = initial_camera(JAW, entry, target, centre_lps=np.array([0.0, -80.0, 0.0]))
    assert front.position_lps[1] > target[1]


def test_without_a_trajectory_the_anatomy_is_seen_from_the_front() -> None:
    pose = initial_camera(JAW)
    np.testing.assert_allclose(pose.focal_lps, [0.0, -25.0, -20.0])
    assert pose.position_lps[1] < -60.0
    _check_pose_sees_the_box(pose, JAW)


def test_the_fitted_distance_is_tight() -> None:
    focal = np.array([10.0, -20.0, -5.0])
    view = np.array([0.0, -1.0, 0.0])
    d = fit_distance_mm(focal, view, JAW)
    rel = _corners(JAW) - (focal + d * view)
    cos = (rel @ -view) / np.linalg.norm(rel, axis=1)
    # at the fitted distance the widest corner sits exactly on the edge of the view cone
    assert np.min(cos) == pytest.approx(np.cos(np.deg2rad(VIEW_ANGLE_DEG / 2.0)), abs=1e-9)


def test_scene_bounds_hold_the_surface_and_every_point() -> None:
    b = scene_bounds((0.0, 1.0, 0.0, 1.0, 0.0, 1.0), [np.array([5.0, -2.0, 0.5])])
    assert b == (0.0, 5.0, -2.0, 1.0, 0.0, 1.0)
    assert scene_bounds(None, []) is None


def test_the_orientation_cube_is_lettered_in_white() -> None:
    cube = orientation_cube()
    assert {cube.GetXPlusFaceText(), cube.GetXMinusFaceText()} == {"L", "R"}
    assert (cube.GetYPlusFaceText(), cube.GetYMinusFaceText()) == ("P", "A")
    assert (cube.GetZPlusFaceText(), cube.GetZMinusFaceText()) == ("S", "I")
    assert cube.GetXPlusFaceText() == "L"  # LPS: +x is the patient's left
    for face in ORIENTATION_LETTERS:
        colour = getattr(cube, f"Get{face}FaceProperty")().GetColor()
        assert colour == pytest.approx(LETTER_COLOUR)


def _u_arch() -> np.ndarray:
    """A U-shaped arch, incisors anterior (y = -50), molars at y = 0, x from -30 to 30."""
    x = np.linspace(-30.0, 30.0, 61)
    return np.column_stack([x, -50.0 + x**2 / 18.0, np.full_like(x, -5.0)])


def test_the_buccal_side_is_out_of_the_arch() -> None:
    arch = _u_arch()
    front = buccal_direction(arch, np.array([0.0, -49.0, 0.0]))
    assert front is not None
    np.testing.assert_allclose(front, [0.0, -1.0, 0.0], atol=0.06)  # incisor: anterior
    right = buccal_direction(arch, np.array([-27.0, -9.0, 0.0]))
    assert right is not None and right[0] < -0.8 and right[2] == 0.0  # right molar: right
    # at x = -27 the arch's outward normal is (-dy/dx, 1) normalised, pointing right-front
    slope = -27.0 / 9.0
    want = np.array([slope, -1.0]) / np.hypot(slope, 1.0)
    np.testing.assert_allclose(right[:2], want, atol=0.02)
    # an arc of the arch alone (a partial arch) still knows its convex side
    arc = arch[40:55]
    part = buccal_direction(arc, arc[7] + np.array([0.0, 0.0, 3.0]))
    assert part is not None and part[0] > 0.8
    # a straight arch has no side
    line = np.array([[0.0, 0.0, 0.0], [10.0, 0.0, 0.0], [20.0, 0.0, 0.0]])
    assert buccal_direction(line, np.array([10.0, 0.0, 5.0])) is None


def test_the_camera_looks_from_the_arch_side_it_is_given() -> None:
    entry = np.array([-27.0, -9.0, 0.0])
    out = buccal_direction(_u_arch(), entry)
    pose = initial_camera(JAW, entry, entry - np.array([0.0, 0.0, 12.0]), outward_lps=out)
    assert out is not None
    horiz = pose.view_dir[:2] / np.linalg.norm(pose.view_dir[:2])
    np.testing.assert_allclose(horiz, out[:2] / np.linalg.norm(out[:2]), atol=1e-9)
    _check_pose_sees_the_box(pose, JAW)


def test_applying_a_pose_draws_no_frame() -> None:
    """The pose is set on the renderer: no frame is drawn (the frame is the render thread's
    to draw, once for every change sent)."""
    import pyvista as pv

    from ctdrill.app.gui.camera import CameraPose, apply_camera
    from ctdrill.app.gui.stage import Stage

    stage = Stage((64, 48))
    try:
        stage.add_mesh(pv.Sphere(radius=5.0), name="ball")
        stage.render()  # shown, as the window's view is before a surface comes
        frames: list[int] = []
        stage.window.AddObserver("StartEvent", lambda *_: frames.append(1))
        pose = CameraPose(
            position_lps=np.array([0.0, -80.0, 10.0]),
            focal_lps=np.array([1.0, 2.0, 3.0]),
            up=np.array([0.0, 0.0, 1.0]),
        )
        apply_camera(stage, pose)
        assert frames == []
        position, focal, up = (np.array(v) for v in stage.camera_position)
        assert np.allclose(position, pose.position_lps)
        assert np.allclose(focal, pose.focal_lps)
        # the up vector made orthogonal to the view: in the plane of the pose's up and view
        view = (pose.position_lps - pose.focal_lps) / pose.distance_mm
        assert abs(up @ view) < 1e-9 and abs(np.cross(view, pose.up) @ up) < 1e-9
        stage.render()
        assert frames == [1]  # the observer sees a frame when one is drawn
        assert np.allclose(stage.camera_position[0], pose.position_lps)  # kept: no reset
    finally:
        stage.close()
