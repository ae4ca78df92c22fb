"""What the slice views draw over the image, headless: every trajectory of the plan (the
current one highlighted) as its drill (diameter, cone tip, down to the computed stop) and its
implant body, the landmarks with radius and margin, the dental arch, and the entry/target
handles of the trajectory being edited.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from ctdrill.app.gui import planning
from ctdrill.app.gui.implant_drag import grips_lps
from ctdrill.app.gui.problems import offending_implants
from ctdrill.app.gui.results import PathView
from ctdrill.app.gui.scene import LandmarkGeometry
from ctdrill.app.gui.sections import drill_profile
from ctdrill.imaging.plan.implants import implant_placement
from ctdrill.imaging.plan.landmarks import CanalLandmark
from ctdrill.imaging.plan.types import Plan


@dataclass(frozen=True, eq=False)
class BodyDrawing:
    """A solid of revolution: its axis from ``p0_lps`` along ``axis_lps`` and its radius
    profile ``(s_mm, r_mm)``."""

    p0_lps: np.ndarray
    axis_lps: np.ndarray
    s_mm: np.ndarray
    r_mm: np.ndarray


@dataclass(frozen=True, eq=False)
class TrajectoryDrawing:
    """One trajectory as the slice views draw it."""

    name: str
    entry_lps: np.ndarray
    target_lps: np.ndarray
    drill: BodyDrawing
    #: The drill is drawn to the computed stop (True) or to the planned depth (False).
    stopped: bool
    implant: BodyDrawing | None
    current: bool
    #: The implant has a plan problem: drawn red (:mod:`ctdrill.app.gui.problems`).
    offending: bool = False


@dataclass(frozen=True, eq=False)
class OverlayScene:
    """Everything drawn over a slice, in LPS mm."""

    trajectories: tuple[TrajectoryDrawing, ...] = ()
    landmarks: tuple[LandmarkGeometry, ...] = ()
    #: Draggable points of the trajectory being edited (``entry`` / ``target``, and the
    #: implant's ``platform``).
    handles: dict[str, np.ndarray] = field(default_factory=dict)
    stop_lps: np.ndarray | None = None
    #: (K, 3) dental arch (the plan's, or the points placed so far), or None.
    arch_lps: np.ndarray | None = None
    #: The trajectory being edited (its body is a grip too), or None.
    plan: Plan | None = None
    #: The traced canals' points: (landmark index, (N, 3) LPS), for picking.
    canals: tuple[tuple[int, np.ndarray], ...] = ()


def drill_drawing(plan: Plan, depth_mm: float) -> BodyDrawing:
    """The final drill of ``plan`` from the entry to its tip at ``depth_mm``: body then cone."""
    s, r = drill_profile(depth_mm, plan.drill.radius_mm, plan.drill.tip_length_mm)
    return BodyDrawing(p0_lps=plan.entry_lps, axis_lps=plan.direction, s_mm=s, r_mm=r)


def implant_drawing(plan: Plan) -> BodyDrawing | None:
    """The implant body placed on ``plan``'s trajectory (apex at the target), or None."""
    spec = plan.implant
    if spec is None:
        return None
    placement = implant_placement(plan)
    if placement is None:
        return None
    s, r = spec.profile_mm()
    return BodyDrawing(
        p0_lps=np.asarray(placement.platform_lps, dtype=np.float64),
        axis_lps=np.asarray(placement.axis_lps, dtype=np.float64),
        s_mm=np.asarray(s, dtype=np.float64),
        r_mm=np.asarray(r, dtype=np.float64),
    )


def trajectory_drawing(
    plan: Plan, view: PathView | None, *, current: bool, offending: bool = False
) -> TrajectoryDrawing:
    """``plan`` drawn with its drill to the stop of ``view`` (when computed for it), its
    implant red when ``offending``."""
    own = view is not None and view.plan is plan
    depth = view.curves.stop_depth_mm if own and view is not None else plan.planned_depth_mm
    return TrajectoryDrawing(
        name=plan.name,
        entry_lps=plan.entry_lps,
        target_lps=plan.target_lps,
        drill=drill_drawing(plan, float(depth)),
        stopped=own,
        implant=implant_drawing(plan),
        current=current,
        offending=offending,
    )


def overlay_scene(
    plans: Sequence[Plan],
    current: int,
    views: Sequence[PathView | None],
    *,
    draft: dict[str, np.ndarray] | None = None,
    arch_lps: np.ndarray | None = None,
) -> OverlayScene:
    """The overlays of a document holding ``plans`` (``current`` edited; ``views[i]`` the path
    result known for trajectory ``i``, or None); without a plan, the ``draft`` entry/target
    placed so far. ``arch_lps``: the arch (or the points of one being placed)."""
    arch = None if arch_lps is None else np.asarray(arch_lps, dtype=np.float64).reshape(-1, 3)
    if not plans:
        handles = {k: np.asarray(v, dtype=np.float64) for k, v in (draft or {}).items()}
        return OverlayScene(handles=handles, arch_lps=arch)
    plan, view = plans[current], views[current]
    own = view is not None and view.plan is plan
    stop = plan.point_at_depth_lps(view.curves.stop_depth_mm) if own and view else None
    red = offending_implants(plans, views)
    return OverlayScene(
        trajectories=tuple(
            trajectory_drawing(p, views[i], current=i == current, offending=red[i])
            for i, p in enumerate(plans)
        ),
        landmarks=planning.drawn_landmarks(plan, view),
        handles=grips_lps(plan),
        stop_lps=stop,
        arch_lps=arch,
        plan=plan,
        canals=canal_points(plan),
    )


def canal_points(plan: Plan) -> tuple[tuple[int, np.ndarray], ...]:
    """Every canal of ``plan`` as (landmark index, (N, 3) centre-line points, LPS)."""
    return tuple(
        (i, lm.points_lps) for i, lm in enumerate(plan.landmarks) if isinstance(lm, CanalLandmark)
    )
