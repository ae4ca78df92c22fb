"""Tracing nerve canals, headless: pure edits of a plan's canal landmarks.

Canals are traced by clicking along them on the panoramic, the cross-section or a slice view;
every edit returns a new plan (the document makes it one undoable step).

- **Which canal.** A click goes to the canal the user chose or, by default, to the canal of
  the side clicked: ``left mandibular canal`` when the point lies on the patient's left of the
  midline (+x in LPS), ``right mandibular canal`` otherwise. The midline is the middle of the
  dental arch (half its length along the panorama) when the arch is a whole one (its two ends
  behind its middle and on either side of it, :data:`FULL_ARCH_SIDE_MM` at least); with a
  partial arch or
  none it is x = 0, the scanner's axis, where a head lies centred in DICOM patient
  coordinates. A canal missing is created with the radius asked for.
- **Where in the canal.** A new point goes where it lengthens the centre line least: into
  the segment it lies beside, or before the first / after the last point (so a canal can be
  traced from either end, and a click on a cross-section between two points lands between
  them).
- Points are moved and deleted by index; deleting a canal's last point removes the canal.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any, cast

import numpy as np

from ctdrill.app.gui.planning import PlanEditError
from ctdrill.imaging.plan.landmarks import DEFAULT_CANAL_RADIUS_MM, CanalLandmark
from ctdrill.imaging.plan.types import Plan
from ctdrill.imaging.sampling.arch import ArchCurve

#: Largest canal radius the editor accepts, mm (the mandibular canal is 1-1.5 mm).
MAX_RADIUS_MM = 10.0
#: An arch is a whole one (across the midline) when both its ends lie at least this far
#: behind its middle (+y) and, in x, on either side of it, mm.
FULL_ARCH_SIDE_MM = 5.0
#: What a side's canal is called by default.
SIDE_NAMES = {"left": "left mandibular canal", "right": "right mandibular canal"}


def midline_x_mm(arch_lps: np.ndarray | None, fallback_x_mm: float = 0.0) -> float:
    """LPS x of the patient's midline: the middle (half its length) of a whole arch, else
    ``fallback_x_mm`` (the scanner's axis, x = 0)."""
    if arch_lps is not None and len(arch_lps) >= 2:
        curve = ArchCurve(np.asarray(arch_lps, dtype=np.float64))
        mid = curve.point_xy(np.array([0.5 * curve.length_mm]))[0]
        ends = np.asarray(arch_lps, dtype=np.float64)[[0, -1], :2] - mid
        across = (
            float(ends[:, 0].min())
            <= -FULL_ARCH_SIDE_MM
            <= FULL_ARCH_SIDE_MM
            <= float(ends[:, 0].max())
        )
        if across and float(ends[:, 1].min()) >= FULL_ARCH_SIDE_MM:
            return float(mid[0])
    return float(fallback_x_mm)


def side_of(point_lps: np.ndarray, midline_x: float) -> str:
    """``left`` or ``right``: the patient's side of ``point_lps`` (LPS +x is the left)."""
    return "left" if float(np.asarray(point_lps).reshape(3)[0]) > midline_x else "right"


def canal_index(plan: Plan, name: str) -> int | None:
    """Index of the canal landmark called ``name`` in ``plan.landmarks``, or None."""
    for i, lm in enumerate(plan.landmarks):
        if isinstance(lm, CanalLandmark) and lm.name == name:
            return i
    return None


def insertion_index(points_lps: np.ndarray, point_lps: np.ndarray) -> int:
    """Where ``point_lps`` goes in the polyline ``points_lps`` (N, 3): the index it takes
    (0: before the first point, N: after the last) so that the polyline grows least."""
    pts = np.asarray(points_lps, dtype=np.float64).reshape(-1, 3)
    p = np.asarray(point_lps, dtype=np.float64).reshape(3)
    if len(pts) == 0:
        return 0
    to_p = np.linalg.norm(pts - p, axis=1)
    best, cost = 0, float(to_p[0])
    if float(to_p[-1]) <= cost:  # a tie (one point): after it
        best, cost = len(pts), float(to_p[-1])
    if len(pts) > 1:
        seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
        grow = to_p[:-1] + to_p[1:] - seg
        k = int(np.argmin(grow))
        if float(grow[k]) < cost:
            best = k + 1
    return best


def _check_point(point_lps: np.ndarray) -> np.ndarray:
    p = np.asarray(point_lps, dtype=np.float64).reshape(3)
    if not np.all(np.isfinite(p)):
        raise PlanEditError("canal point: coordinates must be finite numbers (click on the image)")
    return p


def _check_radius(radius_mm: float) -> float:
    r = float(radius_mm)
    if not (np.isfinite(r) and 0.0 < r <= MAX_RADIUS_MM):
        raise PlanEditError(f"canal radius: must be > 0 and <= {MAX_RADIUS_MM:g} mm, got {r:g}")
    return r


def _canal(plan: Plan, index: int) -> CanalLandmark:
    if not 0 <= index < len(plan.landmarks):
        raise PlanEditError(f"landmarks[{index}]: the plan has {len(plan.landmarks)} landmarks")
    lm = plan.landmarks[index]
    if not isinstance(lm, CanalLandmark):
        raise PlanEditError(f"landmarks[{index}] ({lm.name!r}) is a {lm.kind}, not a canal")
    return lm


def _with(plan: Plan, index: int, landmark: CanalLandmark | None) -> Plan:
    lms = list(plan.landmarks)
    if landmark is None:
        del lms[index]
    else:
        lms[index] = landmark
    return replace(plan, landmarks=tuple(lms))


def trace(
    plan: Plan, point_lps: np.ndarray, *, name: str, radius_mm: float = DEFAULT_CANAL_RADIUS_MM
) -> tuple[Plan, int, int]:
    """Add ``point_lps`` to the canal ``name`` (created with ``radius_mm`` when missing) at
    :func:`insertion_index`. Returns the plan, the canal's landmark index and the point's."""
    p = _check_point(point_lps)
    name = name.strip()
    if not name:
        raise PlanEditError("canal: a name cannot be empty")
    index = canal_index(plan, name)
    if index is None:
        if any(lm.name == name for lm in plan.landmarks):
            raise PlanEditError(f"canal {name!r}: another landmark is called so")
        canal = CanalLandmark(name=name, points_lps=p[None], radius_mm=_check_radius(radius_mm))
        return replace(plan, landmarks=(*plan.landmarks, canal)), len(plan.landmarks), 0
    canal = _canal(plan, index)
    at = insertion_index(canal.points_lps, p)
    points = np.insert(canal.points_lps, at, p, axis=0)
    return _with(plan, index, replace(canal, points_lps=points)), index, at


def move_point(plan: Plan, landmark: int, point: int, point_lps: np.ndarray) -> Plan:
    """Canal ``landmark``'s point ``point`` moved to ``point_lps``."""
    canal = _canal(plan, landmark)
    if not 0 <= point < len(canal.points_lps):
        raise PlanEditError(f"canal {canal.name!r} has no point {point + 1}")
    points = canal.points_lps.copy()
    points[point] = _check_point(point_lps)
    return _with(plan, landmark, replace(canal, points_lps=points))


def delete_point(plan: Plan, landmark: int, point: int) -> Plan:
    """Canal ``landmark`` without its point ``point`` (without the canal when it was the
    last)."""
    canal = _canal(plan, landmark)
    if not 0 <= point < len(canal.points_lps):
        raise PlanEditError(f"canal {canal.name!r} has no point {point + 1}")
    if len(canal.points_lps) == 1:
        return _with(plan, landmark, None)
    points = np.delete(canal.points_lps, point, axis=0)
    return _with(plan, landmark, replace(canal, points_lps=points))


def set_radius(plan: Plan, landmark: int, radius_mm: float) -> Plan:
    """Canal ``landmark`` with the radius ``radius_mm``."""
    canal = _canal(plan, landmark)
    return _with(plan, landmark, replace(canal, radius_mm=_check_radius(radius_mm)))


def rename_landmark(plan: Plan, landmark: int, name: str) -> Plan:
    """Landmark ``landmark`` called ``name`` (stripped; unique among the landmarks)."""
    if not 0 <= landmark < len(plan.landmarks):
        raise PlanEditError(f"landmarks[{landmark}]: the plan has {len(plan.landmarks)} landmarks")
    name = name.strip()
    if not name:
        raise PlanEditError(f"landmarks[{landmark}]: a name cannot be empty")
    if any(lm.name == name for i, lm in enumerate(plan.landmarks) if i != landmark):
        raise PlanEditError(f"landmarks[{landmark}]: another landmark is called {name!r}")
    lms = list(plan.landmarks)
    lms[landmark] = replace(cast(Any, lms[landmark]), name=name)  # every kind is a dataclass
    return replace(plan, landmarks=tuple(lms))


def edit_name(op: str, canal: str) -> str:
    """What a canal edit is called in Edit > Undo."""
    return {
        "add": f"trace {canal!r}",
        "move": f"move a point of {canal!r}",
        "delete": f"delete a point of {canal!r}",
    }.get(op, f"edit {canal!r}")
