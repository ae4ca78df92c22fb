"""The 3D view's mouse, as camera moves: pure functions of a :class:`CameraPose` and the drag in
pixels (the view sends the pose to its render thread). As VTK's trackball camera: the left
button turns the camera around the focal point, the middle button (or shift + left) pans,
the right button and the wheel zoom."""

from __future__ import annotations

import numpy as np

from ctdrill.app.gui.camera import VIEW_ANGLE_DEG, CameraPose

#: Degrees turned per pixel dragged across the view's width or height, times that size
#: (VTK's trackball: 20 degrees per view size, times its motion factor 10).
ORBIT_DEG_PER_VIEW = 200.0
#: Zoom per wheel notch (120 eighths of a degree): the distance to the focal point divided by it.
WHEEL_ZOOM = 1.1
#: Zoom per pixel dragged up with the right button (down: away), as a power.
DRAG_ZOOM_PER_PX = 1.01
#: Closest the camera comes to the focal point, mm.
MIN_DISTANCE_MM = 1.0


def _rotate(vec: np.ndarray, axis: np.ndarray, angle_rad: float) -> np.ndarray:
    """``vec`` turned by ``angle_rad`` about unit ``axis`` (Rodrigues)."""
    k = axis / np.linalg.norm(axis)
    c, s = np.cos(angle_rad), np.sin(angle_rad)
    return np.asarray(vec * c + np.cross(k, vec) * s + k * (k @ vec) * (1.0 - c))


def _frame(pose: CameraPose) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(view from focal to camera, unit; up, unit and orthogonal to it; right, unit)."""
    view = pose.view_dir
    up = pose.up - (pose.up @ view) * view
    up = up / np.linalg.norm(up)
    right = np.cross(up, view)  # the screen's +x: view points at the viewer
    return view, up, right


def orbit(pose: CameraPose, dx_px: float, dy_px: float, size_px: tuple[int, int]) -> CameraPose:
    """The camera turned around the focal point by a drag of (``dx_px`` right, ``dy_px``
    down) on a view of ``size_px`` (width, height): azimuth about the view-up, then elevation
    about the screen's horizontal, as VTK's trackball camera (the scene follows the mouse)."""
    w, h = max(size_px[0], 1), max(size_px[1], 1)
    azimuth = np.deg2rad(-ORBIT_DEG_PER_VIEW * dx_px / w)
    elevation = np.deg2rad(-ORBIT_DEG_PER_VIEW * dy_px / h)  # dragged down: from above
    _view, up, right = _frame(pose)
    offset = pose.position_lps - pose.focal_lps
    offset = _rotate(offset, up, azimuth)
    right = _rotate(right, up, azimuth)
    offset = _rotate(offset, right, elevation)
    new_up = _rotate(up, right, elevation)
    return CameraPose(pose.focal_lps + offset, pose.focal_lps.copy(), new_up)


def pan(
    pose: CameraPose,
    dx_px: float,
    dy_px: float,
    height_px: int,
    *,
    view_angle_deg: float = VIEW_ANGLE_DEG,
) -> CameraPose:
    """The camera and its focal point moved so the focal plane follows a drag of (``dx_px``
    right, ``dy_px`` down) on a view ``height_px`` high."""
    _view, up, right = _frame(pose)
    mm_per_px = 2.0 * pose.distance_mm * np.tan(np.deg2rad(view_angle_deg) / 2.0)
    mm_per_px /= max(height_px, 1)
    shift = (-dx_px * right + dy_px * up) * mm_per_px
    return CameraPose(pose.position_lps + shift, pose.focal_lps + shift, pose.up.copy())


def dolly(pose: CameraPose, factor: float) -> CameraPose:
    """The camera ``factor`` times nearer the focal point (> 1: zoom in), never nearer than
    :data:`MIN_DISTANCE_MM`."""
    dist = max(pose.distance_mm / float(factor), MIN_DISTANCE_MM)
    return CameraPose(pose.focal_lps + pose.view_dir * dist, pose.focal_lps.copy(), pose.up.copy())


def wheel_factor(angle_delta: float) -> float:
    """The zoom of a wheel turn of ``angle_delta`` eighths of a degree (120 a notch; > 0 is
    away from the user: zoom in)."""
    return float(WHEEL_ZOOM ** (angle_delta / 120.0))


def drag_zoom_factor(dy_px: float) -> float:
    """The zoom of a right-button drag of ``dy_px`` down (up zooms in)."""
    return float(DRAG_ZOOM_PER_PX ** (-dy_px))
