"""Plan edits the window offers, as pure functions on the frozen
``ctdrill.imaging.plan.types.Plan``.

Each edit returns a new plan (never mutates) and raises :class:`PlanEditError` with a message
naming the field when the result would not be a usable plan.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ctdrill.app.errors import AppInputError
from ctdrill.app.gui.scene import LandmarkGeometry
from ctdrill.imaging.plan.landmarks import (
    CanalLandmark,
    Landmark,
)
from ctdrill.imaging.plan.types import Plan

#: Shortest trajectory the editor accepts, mm.
MIN_DEPTH_MM = 0.5


class PlanEditError(AppInputError):
    """An edit that would make the plan unusable (the message says which field and why)."""


def move_handle(plan: Plan, name: str, point_lps: np.ndarray) -> Plan:
    """Move ``entry`` or ``target`` to ``point_lps`` (3,) LPS mm."""
    pt = np.asarray(point_lps, dtype=np.float64).reshape(3)
    if not np.all(np.isfinite(pt)):
        raise PlanEditError(f"{name}: coordinates must be finite numbers")
    if name == "entry":
        new = replace(plan, entry_lps=pt)
    elif name == "target":
        new = replace(plan, target_lps=pt)
    else:
        raise PlanEditError(f"unknown handle {name!r}: use 'entry' or 'target'")
    if new.planned_depth_mm < MIN_DEPTH_MM:
        raise PlanEditError(
            f"{name}: entry and target would be {new.planned_depth_mm:.2f} mm apart; "
            f"keep them at least {MIN_DEPTH_MM} mm apart"
        )
    return new


def set_landmark_margin(plan: Plan, index: int, margin_mm: float | None) -> Plan:
    """Give landmark ``index`` its own margin (None: use the plan's)."""
    if margin_mm is not None and (not np.isfinite(margin_mm) or margin_mm < 0):
        raise PlanEditError(f"landmarks[{index}].margin_mm: must be >= 0, got {margin_mm}")
    lms = list(plan.landmarks)
    lms[index] = lms[index].with_margin(margin_mm)
    return replace(plan, landmarks=tuple(lms))


def add_canal_point(
    plan: Plan, point_lps: np.ndarray, *, name: str = "canal", radius_mm: float = 1.2
) -> Plan:
    """Append a point to the canal called ``name`` (creating it if missing).

    A new point goes at whichever end of the centreline is nearer, so the polyline is built in
    order when the points are clicked along the canal from either end.
    """
    pt = np.asarray(point_lps, dtype=np.float64).reshape(1, 3)
    lms = list(plan.landmarks)
    for i, lm in enumerate(lms):
        if isinstance(lm, CanalLandmark) and lm.name == name:
            pts = lm.points_lps
            if np.linalg.norm(pts[0] - pt[0]) < np.linalg.norm(pts[-1] - pt[0]) and len(pts) > 1:
                new_pts = np.vstack([pt, pts])
            else:
                new_pts = np.vstack([pts, pt])
            lms[i] = replace(lm, points_lps=new_pts)
            return replace(plan, landmarks=tuple(lms))
    lms.append(CanalLandmark(name=name, points_lps=pt, radius_mm=radius_mm))
    return replace(plan, landmarks=tuple(lms))


def remove_landmark(plan: Plan, index: int) -> Plan:
    """Drop landmark ``index``."""
    lms = list(plan.landmarks)
    del lms[index]
    return replace(plan, landmarks=tuple(lms))


def default_plan(center_lps: np.ndarray, *, depth_mm: float = 10.0) -> Plan:
    """A vertical (superior to inferior) trajectory of ``depth_mm`` centred on ``center_lps``,
    for a series opened without a plan."""
    c = np.asarray(center_lps, dtype=np.float64).reshape(3)
    half = np.array([0.0, 0.0, depth_mm / 2.0])
    return Plan(entry_lps=c + half, target_lps=c - half, name="new plan")


def landmark_points_lps(landmark: Landmark) -> np.ndarray:
    """(N, 3) points that draw a landmark: its polyline, its point(s) or its surface cloud."""
    drawing = landmark.drawing()
    parts = [*drawing.polylines_lps, drawing.points_lps, drawing.surface_lps]
    return np.concatenate([p for p in parts if len(p)] or [np.empty((0, 3))])


def landmark_geometries(
    plan: Plan, clearance_mm: np.ndarray | None = None
) -> tuple[LandmarkGeometry, ...]:
    """What to draw for each landmark, with its minimum clearance along the stopped path.

    ``clearance_mm`` is (L,) per landmark (in plan order) or None when not computed yet (a
    result for another landmark list is ignored).
    Mask landmarks are drawn as their boundary points (point cloud), without a tube.
    """
    if clearance_mm is not None and len(clearance_mm) != len(plan.landmarks):
        clearance_mm = None
    out = []
    for i, lm in enumerate(plan.landmarks):
        clear = None if clearance_mm is None else float(clearance_mm[i])
        out.append(
            LandmarkGeometry(
                name=lm.name,
                points_lps=landmark_points_lps(lm),
                radius_mm=float(lm.radius_mm),
                margin_mm=plan.landmark_margin_mm(lm),
                clearance_mm=clear,
                kind=lm.kind,
                cloud=len(lm.drawing().surface_lps) > 0,
            )
        )
    return tuple(out)
