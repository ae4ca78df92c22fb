"""The 3D scene, built on any pyvista plotter (on screen: ``QtInteractor``; off screen:
``pyvista.Plotter(off_screen=True)``), so the window, the screenshot and the tests draw the same.

Geometry is computed in the world frame (LPS, mm). The bone surface is a marching-cubes contour
in *index* space on a strided copy of the volume, mapped to LPS with the full affine, so oblique
and sheared (gantry-tilt) series land where they are.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pyvista as pv

from ctdrill.hu import AIR_HU

#: Bone iso-surface presets, HU.
SURFACE_PRESETS: dict[str, float] = {
    "CT bone (300 HU)": 300.0,
    "CBCT bone (500 HU)": 500.0,
    "cortical (1000 HU)": 1000.0,
    "soft tissue (-300 HU)": -300.0,
}

#: Colours (RGB 0..1) by clearance state.
CLEARANCE_COLOURS: dict[str, tuple[float, float, float]] = {
    "safe": (0.20, 0.70, 0.30),
    "close": (0.95, 0.65, 0.10),
    "violated": (0.90, 0.15, 0.15),
    "unknown": (0.55, 0.55, 0.58),
}

BONE_COLOUR = (0.86, 0.80, 0.66)
TRAJECTORY_COLOUR = (0.15, 0.45, 0.95)
DRILL_COLOUR = (0.75, 0.75, 0.80)


@dataclass(frozen=True, eq=False)
class LandmarkGeometry:
    """A landmark as drawn: a centreline (or one point) with its radius and safety margin."""

    name: str
    points_lps: np.ndarray  # (N, 3) LPS mm; N == 1 for a point landmark
    radius_mm: float
    margin_mm: float
    clearance_mm: float | None = None  # minimum clearance along the stopped path, if known
    kind: str = "canal"  # the landmark's kind, a label only
    cloud: bool = False  # points on the landmark's surface: drawn as a cloud, no envelope
    violated: bool = False  # the planned path breaks this landmark's margin


#: Colours (RGB 0..1) of suggested axes, best first (then the last one repeats).
CANDIDATE_COLOURS: tuple[tuple[float, float, float], ...] = (
    (0.10, 0.85, 0.45),
    (0.20, 0.80, 0.85),
    (0.55, 0.70, 0.95),
    (0.80, 0.60, 0.95),
    (0.95, 0.60, 0.75),
)


@dataclass(frozen=True, eq=False)
class CandidateLine:
    """A suggested axis drawn as a thin line from its entry to its target, labelled ``rank``
    and coloured by ``slot`` (its place among the lines shown, 0 first)."""

    entry_lps: np.ndarray
    target_lps: np.ndarray
    rank: int
    adopted: bool = False
    slot: int = 0


@dataclass(frozen=True, eq=False)
class SceneInput:
    """Everything the 3D view shows, in LPS mm."""

    entry_lps: np.ndarray | None  # None (with target): no trajectory placed yet
    target_lps: np.ndarray | None
    diameter_mm: float
    tip_length_mm: float
    stop_depth_mm: float | None = None
    landmarks: tuple[LandmarkGeometry, ...] = field(default=())
    candidates: tuple[CandidateLine, ...] = field(default=())


def clearance_state(clearance_mm: float | None, margin_mm: float, violated: bool = False) -> str:
    """``unknown`` (not computed: never shown as safe), ``violated`` (below the margin, or
    the planned path breaks it), ``close`` (within 1 mm of it) or ``safe``."""
    if violated:
        return "violated"
    if clearance_mm is None:
        return "unknown"
    if clearance_mm >= margin_mm + 1.0:
        return "safe"
    if clearance_mm >= margin_mm:
        return "close"
    return "violated"


def bone_surface(
    hu: np.ndarray,
    affine_lps: np.ndarray,
    *,
    iso_hu: float = 300.0,
    max_dim: int = 160,
    valid: np.ndarray | None = None,
    outside_hu: float = AIR_HU,
    index_to_lps: Callable[[np.ndarray], np.ndarray] | None = None,
) -> pv.PolyData:
    """Iso-surface of the CT at ``iso_hu``, LPS mm.

    Parameters
    ----------
    hu : (slices, rows, cols) CT numbers.
    affine_lps : (4, 4) index (i=col, j=row, k=slice) to LPS mm.
    iso_hu : contour level.
    max_dim : the volume is strided so that no axis has more than this many samples.
    valid : optional (slices, rows, cols) mask; padding (False) counts as ``outside_hu``.
    index_to_lps : maps (N, 3) index coordinates to LPS mm (``CTVolume.index_to_lps``: exact
        for irregular slice positions); default the affine.

    Returns
    -------
    Triangle surface with point normals; empty when nothing crosses ``iso_hu``.
    """
    shape = np.asarray(hu.shape[:3])
    stride = max(1, int(np.ceil(shape.max() / max_dim)))
    sub = np.asarray(hu[::stride, ::stride, ::stride], dtype=np.float32)
    if valid is not None:
        sub = np.where(valid[::stride, ::stride, ::stride], sub, np.float32(outside_hu))
    # Close the surface at the volume border: pad with air.
    sub = np.pad(sub, 1, mode="constant", constant_values=np.float32(outside_hu))
    nk, nj, ni = sub.shape
    grid = pv.ImageData(dimensions=(ni, nj, nk))
    grid.point_data["hu"] = sub.ravel(order="C")  # i fastest, as VTK stores points
    surf = grid.contour([iso_hu], scalars="hu", method="flying_edges")
    if surf.n_points == 0:
        return pv.PolyData()
    ijk = (np.asarray(surf.points, dtype=np.float64) - 1.0) * stride
    if index_to_lps is not None:
        surf.points = np.asarray(index_to_lps(ijk), dtype=np.float64)
    else:
        aff = np.asarray(affine_lps, dtype=np.float64)
        surf.points = ijk @ aff[:3, :3].T + aff[:3, 3]
    surf = surf.triangulate()
    return surf.compute_normals(cell_normals=False, split_vertices=False, auto_orient_normals=False)


def drill_mesh(
    entry_lps: np.ndarray,
    target_lps: np.ndarray,
    *,
    diameter_mm: float,
    tip_length_mm: float,
    shank_mm: float = 20.0,
    resolution: int = 32,
) -> pv.PolyData:
    """The drill with its tip point at the entry (depth 0): a cone of length ``tip_length_mm``
    behind which a cylinder of ``diameter_mm`` runs back ``shank_mm`` out of the patient.

    Translate it by ``depth_mm * axis`` to put the tip at depth ``depth_mm``.
    """
    entry = np.asarray(entry_lps, dtype=np.float64)
    axis = _unit(np.asarray(target_lps, dtype=np.float64) - entry)
    radius = diameter_mm / 2.0
    tip_len = max(tip_length_mm, 1e-3)
    cone = pv.Cone(
        center=entry - axis * tip_len / 2.0,
        direction=axis,
        height=tip_len,
        radius=radius,
        resolution=resolution,
        capping=True,
    )
    cyl = pv.Cylinder(
        center=entry - axis * (tip_len + shank_mm / 2.0),
        direction=axis,
        radius=radius,
        height=shank_mm,
        resolution=resolution,
        capping=True,
    )
    out: pv.PolyData = (cone + cyl).extract_surface(algorithm=None)
    return out


def landmark_meshes(landmark: LandmarkGeometry) -> tuple[pv.PolyData, pv.PolyData | None]:
    """(body, margin envelope): the canal tube (or point sphere) and the tube grown by the
    margin; a surface cloud (a mask landmark's) is drawn as points, without an envelope."""
    pts = np.atleast_2d(np.asarray(landmark.points_lps, dtype=np.float64))
    outer = landmark.radius_mm + landmark.margin_mm
    if landmark.cloud:
        return pv.PolyData(pts), None
    if len(pts) == 1:
        body = pv.Sphere(radius=max(landmark.radius_mm, 0.3), center=pts[0])
        env = pv.Sphere(radius=max(outer, 0.3), center=pts[0])
        return body, env
    line = pv.lines_from_points(pts)
    body = line.tube(radius=max(landmark.radius_mm, 0.2), n_sides=24, capping=True)
    env = line.tube(radius=max(outer, 0.2), n_sides=24, capping=True)
    return body, env


def _unit(vec: np.ndarray) -> np.ndarray:
    n = float(np.linalg.norm(vec))
    if n == 0.0:
        raise ValueError("entry and target coincide: the trajectory has no direction")
    return np.asarray(vec, dtype=np.float64) / n


def build_scene(
    plotter: Any,
    scene: SceneInput,
    *,
    surface: pv.PolyData | None = None,
    bone_opacity: float = 0.45,
    show_axes: bool = True,
) -> dict[str, Any]:
    """Draw the bone surface, trajectory, drill, landmarks and stop point on ``plotter``.

    Parameters
    ----------
    plotter : a ``pyvista.Plotter`` or ``pyvistaqt.QtInteractor``; cleared first.
    scene : plan geometry and results.
    surface : the bone surface (``bone_surface``), computed once per volume and preset.
    bone_opacity : 0..1; translucent by default so the canal and the drill inside show.

    Returns
    -------
    Actors by name (``bone``, ``trajectory``, ``drill``, ``stop``, ``landmark:<name>``,
    ``margin:<name>``, ``candidate:<rank>``, ``candidate-labels``), for live updates
    (``set_drill_depth``).
    """
    plotter.clear()
    plotter.set_background(color="#1e2430", top="#46526a")
    actors: dict[str, Any] = {}
    if surface is not None and surface.n_points > 0:
        actors["bone"] = plotter.add_mesh(
            render=False,
            mesh=surface,
            color=BONE_COLOUR,
            smooth_shading=True,
            opacity=bone_opacity,
            ambient=0.15,
            diffuse=0.75,
            specular=0.15,
            name="bone",
        )
    if scene.entry_lps is not None and scene.target_lps is not None:
        actors.update(_trajectory_actors(plotter, scene, scene.entry_lps, scene.target_lps))
    for lm in scene.landmarks:
        if len(lm.points_lps) == 0:
            continue
        body, env = landmark_meshes(lm)
        colour = CLEARANCE_COLOURS[clearance_state(lm.clearance_mm, lm.margin_mm, lm.violated)]
        actors[f"landmark:{lm.name}"] = plotter.add_mesh(
            render=False, mesh=body, color=(0.95, 0.85, 0.20), name=f"landmark:{lm.name}"
        )
        if env is not None:
            actors[f"margin:{lm.name}"] = plotter.add_mesh(
                render=False, mesh=env, color=colour, opacity=0.3, name=f"margin:{lm.name}"
            )
    actors.update(_candidate_actors(plotter, scene.candidates))
    if show_axes:
        plotter.add_axes(xlabel="L", ylabel="P", zlabel="S")
    return actors


def _candidate_actors(plotter: Any, lines: Sequence[CandidateLine]) -> dict[str, Any]:
    """Suggested axes: a thin tube each (the adopted one thinner: the drill shows it) and
    their ranks at the targets."""
    actors: dict[str, Any] = {}
    for line in lines:
        colour = CANDIDATE_COLOURS[min(line.slot, len(CANDIDATE_COLOURS) - 1)]
        tube = pv.Line(line.entry_lps, line.target_lps).tube(radius=0.08 if line.adopted else 0.18)
        name = f"candidate:{line.rank}"
        actors[name] = plotter.add_mesh(render=False, mesh=tube, color=colour, name=name)
    if lines:
        actors["candidate-labels"] = plotter.add_point_labels(
            np.array([line.target_lps for line in lines]),
            [str(line.rank) for line in lines],
            font_size=14,
            text_color="white",
            shape_opacity=0.0,
            show_points=False,
            always_visible=True,
            render=False,
            name="candidate-labels",
        )
    return actors


def _trajectory_actors(
    plotter: Any, scene: SceneInput, entry_lps: np.ndarray, target_lps: np.ndarray
) -> dict[str, Any]:
    """The trajectory line, target, drill and stop point of ``scene``."""
    entry = np.asarray(entry_lps, dtype=np.float64)
    target = np.asarray(target_lps, dtype=np.float64)
    actors: dict[str, Any] = {}
    axis = _unit(target - entry)
    path = pv.Line(entry - axis * 10.0, target)
    actors["trajectory"] = plotter.add_mesh(
        render=False, mesh=path.tube(radius=0.15), color=TRAJECTORY_COLOUR, name="trajectory"
    )
    actors["target"] = plotter.add_mesh(
        render=False,
        mesh=pv.Sphere(radius=0.5, center=target),
        color=TRAJECTORY_COLOUR,
        name="target",
    )
    drill = drill_mesh(
        entry, target, diameter_mm=scene.diameter_mm, tip_length_mm=scene.tip_length_mm
    )
    actors["drill"] = plotter.add_mesh(
        render=False,
        mesh=drill,
        color=DRILL_COLOUR,
        specular=0.6,
        smooth_shading=True,
        name="drill",
    )
    if scene.stop_depth_mm is not None:
        stop = entry + axis * scene.stop_depth_mm
        actors["stop"] = plotter.add_mesh(
            render=False,
            mesh=pv.Sphere(radius=max(scene.diameter_mm / 2.0, 0.4) * 1.15, center=stop),
            color=(0.9, 0.15, 0.6),
            opacity=0.6,
            name="stop",
        )
    return actors


def set_drill_depth(actors: dict[str, Any], axis_lps: np.ndarray, depth_mm: float) -> None:
    """Move the drill actor so its tip sits at ``depth_mm`` along the (unit) drill axis."""
    actor = actors.get("drill")
    if actor is None:
        return
    offset = np.asarray(axis_lps, dtype=np.float64) * float(depth_mm)
    actor.SetPosition(*offset.tolist())


def focus_camera(
    plotter: Any,
    entry_lps: np.ndarray,
    target_lps: np.ndarray,
    *,
    distance_mm: float | None = None,
    bounds: Sequence[float] | None = None,
) -> float:
    """Look at the trajectory's midpoint from the side of the drill, superior up.

    The view direction is perpendicular to the drill axis (the drill runs across the screen) and
    tilted 25 degrees from above; the distance defaults to 8 x the trajectory length, at least
    90 mm, and, given the anatomy's ``bounds`` (xmin, xmax, ymin, ymax, zmin, zmax), at least
    20 mm beyond them along the view direction, so the camera never sits inside the bone.
    Returns the distance, mm.
    """
    entry = np.asarray(entry_lps, dtype=np.float64)
    target = np.asarray(target_lps, dtype=np.float64)
    axis = _unit(target - entry)
    mid = (entry + target) / 2.0
    length = float(np.linalg.norm(target - entry))
    dist = distance_mm if distance_mm is not None else max(90.0, 8.0 * length)
    up = np.array([0.0, 0.0, 1.0])
    side = np.cross(axis, up)
    if np.linalg.norm(side) < 1e-6:  # vertical drill: look from anterior (-P)
        side = np.array([0.0, -1.0, 0.0])
    side = side / np.linalg.norm(side)
    if side[1] > 0:  # prefer looking from the front of the patient
        side = -side
    view_dir = side * np.cos(np.deg2rad(25.0)) + up * np.sin(np.deg2rad(25.0))
    view_dir /= np.linalg.norm(view_dir)
    if distance_mm is None and bounds is not None:
        corners = np.array([[x, y, z] for x in bounds[:2] for y in bounds[2:4] for z in bounds[4:]])
        dist = max(dist, float(np.max((corners - mid) @ view_dir)) + 20.0)
    plotter.camera_position = [tuple(mid + view_dir * dist), tuple(mid), (0.0, 0.0, 1.0)]
    plotter.reset_camera_clipping_range()
    return dist
