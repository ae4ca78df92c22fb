"""The 3D view's mouse as camera moves (pure functions, closed forms)."""

from __future__ import annotations

import numpy as np
import pytest

from ctdrill.app.gui.camera import VIEW_ANGLE_DEG, CameraPose
from ctdrill.app.gui.interactor import (
    ORBIT_DEG_PER_VIEW,
    dolly,
    drag_zoom_factor,
    orbit,
    pan,
    wheel_factor,
)

POSE = CameraPose(np.array([0.0, -100.0, 0.0]), np.zeros(3), np.array([0.0, 0.0, 1.0]))


def test_a_drag_across_turns_the_camera_about_the_view_up_at_its_distance() -> None:
    # a drag to the right of 45/200 of the width: the camera goes 45 degrees to the left
    moved = orbit(POSE, 45.0 * 400 / ORBIT_DEG_PER_VIEW, 0.0, (400, 300))
    assert moved.distance_mm == pytest.approx(100.0)
    np.testing.assert_allclose(moved.focal_lps, 0.0, atol=1e-12)
    s = np.sqrt(0.5)
    np.testing.assert_allclose(moved.position_lps, [-100.0 * s, -100.0 * s, 0.0], atol=1e-9)
    np.testing.assert_allclose(moved.up, [0.0, 0.0, 1.0], atol=1e-12)


def test_a_drag_down_looks_from_above() -> None:
    moved = orbit(POSE, 0.0, 30.0 * 300 / ORBIT_DEG_PER_VIEW, (400, 300))
    elevation = np.degrees(np.arcsin(moved.position_lps[2] / moved.distance_mm))
    assert elevation == pytest.approx(30.0)
    assert moved.up @ moved.view_dir == pytest.approx(0.0, abs=1e-12)


def test_a_pan_moves_the_focal_plane_with_the_mouse() -> None:
    height = 300
    moved = pan(POSE, 10.0, -20.0, height)  # 10 px right, 20 px up
    mm_per_px = 2 * 100.0 * np.tan(np.radians(VIEW_ANGLE_DEG / 2)) / height
    # the scene follows the mouse: the camera goes left and down
    shift = moved.focal_lps - POSE.focal_lps
    np.testing.assert_allclose(shift, [-10.0 * mm_per_px, 0.0, -20.0 * mm_per_px], atol=1e-12)
    np.testing.assert_allclose(moved.position_lps - POSE.position_lps, shift, atol=1e-12)


def test_zoom_divides_the_distance_and_stops_short_of_the_focal_point() -> None:
    assert dolly(POSE, 2.0).distance_mm == pytest.approx(50.0)
    assert dolly(POSE, 1e9).distance_mm == pytest.approx(1.0)
    assert wheel_factor(120.0) == pytest.approx(1.1) and wheel_factor(-240.0) == pytest.approx(
        1.1**-2
    )
    assert drag_zoom_factor(-10.0) > 1.0 > drag_zoom_factor(10.0)
