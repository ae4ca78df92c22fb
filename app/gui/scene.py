"""The 3D scene, built on a :class:`ctdrill.app.gui.stage.Stage` (the window's on its render
thread, the report's and the tests' on theirs), so the window, the screenshot, the report and
the tests draw the same.

Geometry is in the world frame (LPS, mm). The bone surface (:func:`bone_surface`, defined in
:mod:`ctdrill.app.gui.surface`) is drawn as one actor or several pieces (``bone:<n>``) that keep
their GPU buffers while the plan's actors (``plan_actors``) are rebuilt on a plan change (those
whose mesh and style are unchanged kept as they are).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import partial
from typing import Any

import numpy as np
import pyvista as pv

from ctdrill.app.gui.camera import (
    CameraPose,
    add_orientation_marker,
    buccal_direction,
    initial_camera,
    scene_bounds,
)
from ctdrill.app.gui.meshes import drill_mesh, implant_mesh, landmark_meshes, sphere_mesh, unit
from ctdrill.app.gui.surface import bone_surface as bone_surface

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
#: Implant bodies: the current trajectory's, and the others' (dimmer).
IMPLANT_COLOUR = (0.30, 0.80, 0.95)
OTHER_IMPLANT_COLOUR = (0.45, 0.55, 0.70)
OTHER_TRAJECTORY_COLOUR = (0.55, 0.65, 0.90)
LANDMARK_BODY_RGB = (0.95, 0.85, 0.20)
STOP_RGB = (0.9, 0.15, 0.6)
#: Background gradient (bottom, top): dark, so labels are white.
BACKGROUND = ("#1e2430", "#46526a")


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
class ImplantGeometry:
    """An implant body as drawn: its profile (``ImplantSpec.profile_mm()``: radius ``r_mm``
    at ``s_mm`` from the platform) placed with the platform at ``platform_lps`` and the apex
    along unit ``axis_lps``; ``current`` marks the selected trajectory's, ``offending`` one
    with a plan problem (drawn red, :mod:`ctdrill.app.gui.problems`)."""

    name: str
    platform_lps: np.ndarray
    axis_lps: np.ndarray
    s_mm: np.ndarray
    r_mm: np.ndarray
    current: bool = True
    offending: bool = False


@dataclass(frozen=True, eq=False)
class TrajectoryLine:
    """Another trajectory of the plan (not the selected one): a line from entry to target."""

    name: str
    entry_lps: np.ndarray
    target_lps: np.ndarray
    diameter_mm: float


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
    arch_lps: np.ndarray | None = None  # (K, 3) dental arch: the camera looks from outside it
    implants: tuple[ImplantGeometry, ...] = field(default=())  # every trajectory's implant
    others: tuple[TrajectoryLine, ...] = field(default=())  # the plan's other trajectories


def implant_colour(implant: ImplantGeometry) -> tuple[float, float, float]:
    """An implant's colour: red with a plan problem, else the current or the other colour."""
    if implant.offending:
        return CLEARANCE_COLOURS["violated"]
    return IMPLANT_COLOUR if implant.current else OTHER_IMPLANT_COLOUR


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


def add_bone(stage: Any, surface: pv.PolyData, *, name: str = "bone", opacity: float = 0.45) -> Any:
    """Add ``surface`` (with its own ``Normals``: none are recomputed) as a bone actor without
    rendering; the GPU upload happens at the next render."""
    from vtkmodules.vtkRenderingCore import vtkActor, vtkPolyDataMapper

    mapper = vtkPolyDataMapper()
    mapper.SetInputData(surface)
    mapper.ScalarVisibilityOff()
    mapper.SetStatic(True)  # no pipeline checks per frame: the data never changes
    actor = vtkActor()
    actor.SetMapper(mapper)
    prop = actor.GetProperty()
    prop.SetColor(*BONE_COLOUR)
    prop.SetOpacity(opacity)
    prop.SetInterpolationToGouraud()
    prop.SetAmbient(0.15)
    prop.SetDiffuse(0.75)
    prop.SetSpecular(0.15)
    stage.add_actor(actor, name=name)
    return actor


def build_scene(
    stage: Any,
    scene: SceneInput,
    *,
    surface: pv.PolyData | None = None,
    bone_opacity: float = 0.45,
    show_axes: bool = True,
) -> dict[str, Any]:
    """Clear ``stage`` and draw the bone surface, the orientation marker and
    :func:`plan_actors` of ``scene``, unlit (each colour flat, exactly as chosen: the report's
    images, whose colours are read as the clearance states).

    Parameters
    ----------
    stage : a :class:`~ctdrill.app.gui.stage.Stage`; cleared first.
    scene : plan geometry and results.
    surface : the bone surface (``bone_surface``), computed once per volume and preset.
    bone_opacity : 0..1; translucent by default so the canal and the drill inside show.

    Returns
    -------
    Actors by name: ``bone`` and those of :func:`plan_actors`.
    """
    stage.clear()
    stage.unlit()
    stage.set_background(color=BACKGROUND[0], top=BACKGROUND[1])
    actors: dict[str, Any] = {}
    if surface is not None and surface.n_points > 0:
        actors["bone"] = add_bone(stage, surface, opacity=bone_opacity)
    actors.update(plan_actors(stage, scene))
    if show_axes:
        add_orientation_marker(stage)
    return actors


#: The plan's actors shown, by name: what each draws (its key) and the actor.
Kept = dict[str, tuple[tuple[Any, ...], Any]]


def _mesh_actor(
    stage: Any,
    kept: Kept | None,
    out: dict[str, Any],
    name: str,
    shape: tuple[Any, ...],
    mesh: Any,
    **style: Any,
) -> None:
    """``out[name]``: the actor ``kept`` holds for ``name`` when it draws the same ``shape``
    (the mesh's inputs; arrays by value) in the same ``style``, else ``mesh()`` added with
    ``style`` (and kept)."""
    key = tuple(
        np.asarray(p, dtype=np.float64).tobytes() if isinstance(p, np.ndarray) else p for p in shape
    ) + tuple(sorted(style.items()))
    old = None if kept is None else kept.get(name)
    if old is not None and old[0] == key:
        out[name] = old[1]
        return
    out[name] = stage.add_mesh(mesh(), name=name, **style)
    if kept is not None:
        kept[name] = (key, out[name])


def plan_actors(stage: Any, scene: SceneInput, kept: Kept | None = None) -> dict[str, Any]:
    """Add the plan's actors of ``scene`` (no render, nothing removed).

    ``kept``: the actors of the scene shown, with what each draws; one whose mesh and style
    are unchanged is kept instead of built and added again (a canal point, an undo or a new
    stop changes one or two of them). Updated in place to the returned actors; the caller
    removes the others.

    Returns
    -------
    Actors by name (``trajectory``, ``target``, ``drill``, ``stop``, ``landmark:<name>``,
    ``margin:<name>``, ``implant:<i>``, ``other:<i>``, ``candidate:<rank>``,
    ``candidate-labels``), for live updates (``set_drill_depth``) and removal.
    """
    actors: dict[str, Any] = {}
    if scene.entry_lps is not None and scene.target_lps is not None:
        _trajectory_actors(stage, scene, scene.entry_lps, scene.target_lps, kept, actors)
    for lm in scene.landmarks:
        if len(lm.points_lps) == 0:
            continue
        colour = CLEARANCE_COLOURS[clearance_state(lm.clearance_mm, lm.margin_mm, lm.violated)]
        shape = (lm.points_lps, lm.radius_mm, lm.margin_mm, lm.cloud)
        meshes: list[Any] = []

        def mesh(i: int, lm: LandmarkGeometry = lm, meshes: list[Any] = meshes) -> Any:
            if not meshes:  # body and envelope made together, once
                meshes.extend(landmark_meshes(lm))
            return meshes[i]

        body, env = partial(mesh, 0), partial(mesh, 1)
        _mesh_actor(
            stage, kept, actors, f"landmark:{lm.name}", shape, body, color=LANDMARK_BODY_RGB
        )
        if not lm.cloud:  # a surface cloud has no envelope
            margin = f"margin:{lm.name}"
            _mesh_actor(stage, kept, actors, margin, shape, env, color=colour, opacity=0.3)
    for i, imp in enumerate(scene.implants):
        body_of = (imp.platform_lps, imp.axis_lps, imp.s_mm, imp.r_mm)
        _mesh_actor(
            stage,
            kept,
            actors,
            f"implant:{i}",
            body_of,
            partial(implant_mesh, *body_of),
            color=implant_colour(imp),
            opacity=0.85 if imp.current else 0.6,
            specular=0.5,
        )
    for i, other in enumerate(scene.others):
        _mesh_actor(
            stage,
            kept,
            actors,
            f"other:{i}",
            (other.entry_lps, other.target_lps, other.diameter_mm),
            lambda o=other: pv.Line(o.entry_lps, o.target_lps).tube(
                radius=max(o.diameter_mm / 2.0, 0.2)
            ),
            color=OTHER_TRAJECTORY_COLOUR,
            opacity=0.7,
        )
    actors.update(_candidate_actors(stage, scene.candidates))
    if kept is not None:  # what is not drawn now is not kept
        for name in [n for n in kept if n not in actors]:
            del kept[name]
    return actors


def _candidate_actors(stage: Any, lines: Sequence[CandidateLine]) -> dict[str, Any]:
    """Suggested axes: a thin tube each (the adopted one thinner: the drill shows it) and
    their ranks at the targets."""
    actors: dict[str, Any] = {}
    for line in lines:
        colour = CANDIDATE_COLOURS[min(line.slot, len(CANDIDATE_COLOURS) - 1)]
        tube = pv.Line(line.entry_lps, line.target_lps).tube(radius=0.08 if line.adopted else 0.18)
        name = f"candidate:{line.rank}"
        actors[name] = stage.add_mesh(tube, color=colour, name=name)
    if lines:
        actors["candidate-labels"] = stage.add_point_labels(
            np.array([line.target_lps for line in lines]),
            [str(line.rank) for line in lines],
            font_size=14,
            text_color=(1.0, 1.0, 1.0),
            name="candidate-labels",
        )
    return actors


def _trajectory_actors(
    stage: Any,
    scene: SceneInput,
    entry_lps: np.ndarray,
    target_lps: np.ndarray,
    kept: Kept | None = None,
    actors: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """The trajectory line, target, drill and stop point of ``scene``, added to ``actors``
    (``kept``: as in :func:`plan_actors`)."""
    entry = np.asarray(entry_lps, dtype=np.float64)
    target = np.asarray(target_lps, dtype=np.float64)
    actors = {} if actors is None else actors
    axis = unit(target - entry)
    line = lambda: pv.Line(entry - axis * 10.0, target).tube(radius=0.15)  # noqa: E731
    _mesh_actor(stage, kept, actors, "trajectory", (entry, target), line, color=TRAJECTORY_COLOUR)
    ball = lambda: sphere_mesh(0.5, target)  # noqa: E731
    _mesh_actor(stage, kept, actors, "target", (target,), ball, color=TRAJECTORY_COLOUR)
    size = (scene.diameter_mm, scene.tip_length_mm)
    _mesh_actor(
        stage,
        kept,
        actors,
        "drill",
        (entry, target, *size),
        lambda: drill_mesh(entry, target, diameter_mm=size[0], tip_length_mm=size[1]),
        color=DRILL_COLOUR,
        specular=0.6,
        smooth_shading=True,
    )
    actors["drill"].SetPosition(0.0, 0.0, 0.0)  # at the plan (a rehearsal moves it)
    if scene.stop_depth_mm is not None:
        stop = entry + axis * scene.stop_depth_mm
        radius = max(scene.diameter_mm / 2.0, 0.4) * 1.15
        _mesh_actor(
            stage,
            kept,
            actors,
            "stop",
            (stop, radius),
            lambda: sphere_mesh(radius, stop),
            color=STOP_RGB,
            opacity=0.6,
        )
    return actors


def set_drill_depth(actors: dict[str, Any], axis_lps: np.ndarray, depth_mm: float) -> None:
    """Move the drill actor so its tip sits at ``depth_mm`` along the (unit) drill axis."""
    actor = actors.get("drill")
    if actor is None:
        return
    offset = np.asarray(axis_lps, dtype=np.float64) * float(depth_mm)
    actor.SetPosition(*offset.tolist())


def scene_camera(scene: SceneInput, surface: pv.PolyData | None) -> CameraPose | None:
    """The starting camera of ``scene`` (:func:`ctdrill.app.gui.camera.initial_camera`): the
    bone surface, the trajectory and the landmarks in view, looking at the target from the
    buccal side (out of the dental arch at the entry when the scene has an arch, else away
    from the anatomy's centre); None when there is nothing to look at."""
    surface_bounds = None
    if surface is not None and surface.n_points > 0:
        surface_bounds = tuple(surface.bounds)
    points = [lm.points_lps for lm in scene.landmarks]
    points += [p for o in scene.others for p in (o.entry_lps, o.target_lps)]
    if scene.entry_lps is not None and scene.target_lps is not None:
        points += [scene.entry_lps, scene.target_lps]
    bounds = scene_bounds(surface_bounds, points)
    if bounds is None:
        return None
    outward = None
    if scene.arch_lps is not None and len(scene.arch_lps) >= 2 and scene.entry_lps is not None:
        outward = buccal_direction(scene.arch_lps, scene.entry_lps)
    return initial_camera(bounds, scene.entry_lps, scene.target_lps, outward_lps=outward)
