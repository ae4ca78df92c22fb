"""The embedded 3D view: a ``pyvistaqt.QtInteractor`` drawn by
:func:`ctdrill.app.gui.scene.build_scene`, observing the window's document.

A new bone surface (computed in a worker: every slice, full resolution) is handed to VTK in
pieces (:func:`ctdrill.app.gui.surface.surface_piece`), one piece added and drawn per event-loop
pass, so no pass uploads millions of triangles at once; its actors stay while the plan's actors
are rebuilt when the path result for the plan arrives (or fails: the landmarks are then drawn as
unknown) and when suggested axes arrive (the best feasible ones drawn as numbered lines), each
build and its frame in an event-loop pass of its own; the drill follows the live depth of a
rehearsal. The camera starts where :func:`ctdrill.app.gui.scene.scene_camera` says."""

from __future__ import annotations

import time
from typing import Any

import numpy as np
import pyvista as pv
from PySide6.QtCore import Signal
from PySide6.QtWidgets import QVBoxLayout, QWidget

from ctdrill.app.gui.camera import add_orientation_marker, apply_camera
from ctdrill.app.gui.compute import volume_surface
from ctdrill.app.gui.document import ViewContext
from ctdrill.app.gui.interactor import Interactor
from ctdrill.app.gui.planning import scene_input
from ctdrill.app.gui.results import PathView
from ctdrill.app.gui.scene import (
    BACKGROUND,
    Kept,
    SceneInput,
    add_bone,
    plan_actors,
    scene_camera,
    set_drill_depth,
)
from ctdrill.app.gui.scene_plans import plans_scene
from ctdrill.app.gui.suggesting import candidate_lines
from ctdrill.app.gui.surface import MAX_TRIANGLES, piece_count, surface_piece
from ctdrill.app.gui.workers import Runner

#: The longest a frame of the 3D view should hold the UI thread, s.
FRAME_BUDGET_S = 0.1
#: The refined surface is asked for only when it may have this many times more triangles.
REFINE_GAIN = 1.5
#: Share of the frame budget left for the surface that the refinement plans to use.
REFINE_SAFETY = 0.7


def refine_budget(n_triangles: int, frame_without_s: float, frame_with_s: float) -> int | None:
    """Triangles a frame of :data:`FRAME_BUDGET_S` affords, from two measured frames of the
    view (without and with a surface of ``n_triangles``): the surface's cost per triangle is
    their difference (at least 10 % of the frame with it, so noise never promises too much),
    and :data:`REFINE_SAFETY` of the room left is used (frame times vary with the load); None
    when that is less than :data:`REFINE_GAIN` times ``n_triangles`` (no refinement worth it),
    at most :data:`MAX_TRIANGLES`."""
    if n_triangles <= 0 or not (np.isfinite(frame_without_s) and np.isfinite(frame_with_s)):
        return None
    per_tri = max(frame_with_s - frame_without_s, 0.1 * frame_with_s) / n_triangles
    room = FRAME_BUDGET_S - min(frame_without_s, frame_with_s)
    if per_tri <= 0.0 or room <= 0.0:
        return None
    budget = int(min(MAX_TRIANGLES, REFINE_SAFETY * room / per_tri))
    return budget if budget >= REFINE_GAIN * n_triangles else None


class View3D(QWidget):
    """3D view of the bone surface, trajectories, implants, drill and landmarks.

    Signals
    -------
    surface_shown() : the last piece of the current bone surface has been drawn
        (:attr:`surface_shown_s` holds when).
    surface_settled() : no finer surface will follow (:attr:`settled_s` holds when).

    The series opens with a coarse surface (``compute.FIRST_TRIANGLES``); once it is drawn,
    the frame it took says how many triangles a frame of :data:`FRAME_BUDGET_S` affords, and
    a worker contours the finest surface within that (every voxel when it fits), which then
    replaces the coarse one piece by piece.
    """

    surface_shown = Signal()
    surface_settled = Signal()

    def __init__(self, ctx: ViewContext, *, multi_samples: int = 0) -> None:
        """``multi_samples``: MSAA samples; 0 by default because on a software OpenGL (Mesa
        llvmpipe, Xvfb) 4x MSAA more than doubles the frame time (see docs/benchmarks.md)."""
        super().__init__()
        self.ctx = ctx
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        # No periodic re-render (pyvistaqt's default is 5 Hz even when nothing changes, ~50 ms a
        # frame on software GL): the view renders when the scene changes or the user interacts.
        plotter: Any = Interactor(self, multi_samples=multi_samples, auto_update=False)
        self.plotter = plotter
        layout.addWidget(plotter.interactor)
        plotter.set_background(BACKGROUND[0], top=BACKGROUND[1])
        add_orientation_marker(plotter)
        self.surface: pv.PolyData | None = None
        self.scene: SceneInput | None = None
        #: The plan's actors shown, with what each draws (a rebuild keeps the unchanged).
        self._kept: Kept = {}
        #: Every actor by name: the bone pieces (``bone:<surface>:<piece>``, the current
        #: surface's first also as ``bone``) and the plan's.
        self.actors: dict[str, Any] = {}
        self._bone: dict[str, Any] = {}  # the current surface's pieces, by name
        self._old_bone: dict[str, Any] = {}  # the coarser surface a refined one replaces
        self._surface_gen = 0
        self._camera_for: tuple[float, ...] | None = None
        self.frames_drawn = 0
        self.last_frame_s = float("nan")  # perf_counter() at the end of the latest frame
        #: perf_counter() when the current surface's last piece was drawn (nan: not yet).
        self.surface_shown_s = float("nan")
        self.settled_s = float("nan")
        self.last_render_s = float("nan")  # duration of the latest frame
        self._refined_gen = 0  # the surface generation a refinement was installed as
        self._refiner = Runner(self._refined, self._refine_failed, parent=self)
        self._refining_for = 0
        self._frame_without_s = float("nan")
        #: Point the camera at the trajectory on the next build (a newly opened plan).
        self.refocus_next = False
        self._site = (0, 0)  # (trajectories, current) last seen
        doc = ctx.doc
        doc.surface_changed.connect(self._surface)
        doc.path_changed.connect(self._path)
        doc.live_depth_changed.connect(self.set_drill_depth)
        doc.suggestion_changed.connect(self._suggestion)
        doc.plans_changed.connect(self._plans)

    # ------------------------------------------------------------------ document
    def _surface(self, surface: pv.PolyData | None) -> None:
        if surface is None and self.ctx.doc.volume is not None:
            self.surface_follows()
        else:
            self.set_surface(surface)
        if self.ctx.doc.plan is None:  # no trajectory yet: the anatomy alone
            self.ctx.steps.push(lambda: self.show_scene(scene_input(None, None)))

    def _path(self, view: PathView | None) -> None:
        doc = self.ctx.doc
        if view is None and not doc.path_error:
            return  # reset on a plan edit: the result follows
        plan = doc.plan

        def current() -> bool:
            return doc.plan is plan and doc.path is view

        def build() -> None:
            if current():
                lines = candidate_lines(doc.suggestion, doc.adopted)
                views = [doc.cached_path(p) for p in doc.plans]
                scene = plans_scene(doc.plans, doc.current, view, lines, views)
                self.show_scene(scene, refocus=self.refocus_next, render=False)
                self.refocus_next = False

        self.ctx.steps.push(build)  # the build and its frame: two passes
        self.ctx.steps.push(lambda: self.render_now() if current() else None)

    def _plans(self, plans: tuple[object, ...]) -> None:
        """Every trajectory removed: the anatomy alone (otherwise the current one's path
        result rebuilds the scene, with every trajectory). A trajectory added or selected:
        the camera goes to it with that result."""
        site = (len(plans), self.ctx.doc.current)
        if plans and site != self._site and len(plans) >= self._site[0]:
            self.refocus_next = self._site[0] > 0  # not on opening: the case is framed then
        self._site = site
        if not plans and self.scene is not None and self.scene.entry_lps is not None:
            self.ctx.steps.push(lambda: self.show_scene(scene_input(None, None)))

    def _suggestion(self, _suggestion: object) -> None:
        doc = self.ctx.doc
        if doc.plan is None or self.scene is None:
            return
        plan, view = doc.plan, doc.path

        def build() -> None:
            if doc.plan is plan and doc.path is view:
                lines = candidate_lines(doc.suggestion, doc.adopted)
                views = [doc.cached_path(p) for p in doc.plans]
                scene = plans_scene(doc.plans, doc.current, view, lines, views)
                self.show_scene(scene, render=False)

        self.ctx.steps.push(build)
        self.ctx.steps.push(self.render_now)

    # ------------------------------------------------------------------ bone surface
    def set_surface(
        self, surface: pv.PolyData | None, *, redraw: bool = True, refined: bool = False
    ) -> None:
        """Use a new bone surface (new volume or preset): its pieces are added and drawn one
        per event-loop pass (``redraw`` is accepted for compatibility: the pieces always
        draw); the camera is re-aimed with the first piece, unless ``refined`` (a finer
        surface of the same volume, which is never refined again)."""
        self.surface = surface
        self._refiner.cancel()
        if not refined:
            self._camera_for = None
        self._surface_gen += 1
        if refined:
            self._refined_gen = self._surface_gen
        gen = self._surface_gen
        self.surface_shown_s = float("nan")
        self.settled_s = float("nan")
        n = 0 if surface is None else piece_count(surface)
        if refined:  # the coarse surface stays until the finer one is all in
            self._old_bone, self._bone = {**self._old_bone, **self._bone}, {}
        else:
            self.ctx.steps.push(lambda: self._drop_bone(gen))
        for index in range(n):
            self.ctx.steps.push(lambda i=index: self._add_piece(gen, i, n))  # type: ignore[misc]
        if n == 0:
            self.ctx.steps.push(lambda: self._surface_done(gen))

    def surface_is_shown(self) -> bool:
        """The current bone surface is drawn whole, or none is coming (no series, or its
        contour failed)."""
        shown = np.isfinite(self.surface_shown_s) or np.isfinite(self.settled_s)
        return bool(shown) or self.ctx.doc.volume is None

    def surface_failed(self) -> None:
        """The series' bone surface could not be contoured: no surface follows (the window
        says why); the view is settled without it."""
        self._settle()

    def surface_follows(self) -> None:
        """A new series opened whose bone surface is still being contoured: the previous
        surface goes (nothing is shown or settled until the new one arrives)."""
        self.surface = None
        self._refiner.cancel()
        self._camera_for = None
        self._surface_gen += 1
        gen = self._surface_gen
        self.surface_shown_s = float("nan")
        self.settled_s = float("nan")
        self.ctx.steps.push(lambda: self._drop_bone(gen))

    def _drop_bone(self, gen: int) -> None:
        """Remove the previous surfaces' actors (the GPU buffers go with them)."""
        if gen != self._surface_gen:
            return
        self._drop_old()
        for name, actor in self._bone.items():
            self.plotter.remove_actor(actor, render=False)
            self.actors.pop(name, None)
        self._bone = {}
        self.actors.pop("bone", None)

    def _drop_old(self) -> None:
        for name, actor in self._old_bone.items():
            self.plotter.remove_actor(actor, render=False)
            self.actors.pop(name, None)
        self._old_bone = {}

    def _add_piece(self, gen: int, index: int, total: int) -> None:
        """Add piece ``index`` of the current surface and draw the frame that uploads it."""
        if gen != self._surface_gen or self.surface is None:
            return
        name = f"bone:{gen}:{index}"
        actor = add_bone(self.plotter, surface_piece(self.surface, index), name=name)
        self._bone[name] = actor
        self.actors[name] = actor
        if index == 0:
            self.actors["bone"] = actor  # the surface's first piece, by its short name
            if self._camera_for is None:
                self._aim(self.scene or scene_input(None, None))
        if index == total - 1:
            self._drop_old()
        self.render_now()
        if index == total - 1:
            self._surface_done(gen)

    def _surface_done(self, gen: int) -> None:
        if gen != self._surface_gen:
            return
        self.surface_shown_s = self.last_frame_s
        self.surface_shown.emit()
        if self._refined_gen == gen or not self._refinable():
            self._settle()
            return
        # Two frames, each in its own pass: without the bone, then with it.
        self.ctx.steps.push(lambda: self._time_frame(gen, bone=False))
        self.ctx.steps.push(lambda: self._time_frame(gen, bone=True))

    def _refinable(self) -> bool:
        surf = self.surface
        if surf is None or surf.n_cells == 0 or self.ctx.doc.volume is None:
            return False
        if "iso_hu" not in surf.field_data or "block" not in surf.field_data:
            return False
        return tuple(int(b) for b in surf.field_data["block"]) != (1, 1, 1)

    def _time_frame(self, gen: int, *, bone: bool) -> None:
        """Time one frame with the bone hidden (``bone`` False) or shown; after both, ask for
        the finer surface the frame budget affords."""
        if gen != self._surface_gen:
            return
        for actor in self._bone.values():
            actor.SetVisibility(bone)
        self.render_now()
        if not bone:
            self._frame_without_s = self.last_render_s
            return
        budget = refine_budget(
            self.surface.n_cells if self.surface is not None else 0,
            self._frame_without_s,
            self.last_render_s,
        )
        volume = self.ctx.doc.volume
        if budget is None or volume is None or self.surface is None:
            if self.surface is not None:
                block = "x".join(str(int(b)) for b in self.surface.field_data["block"])
                self.ctx.status(
                    f"3D: bone surface of {self.surface.n_cells:,} triangles on {block} voxel "
                    f"blocks; a frame takes {1e3 * self.last_render_s:.0f} ms here, so no "
                    f"finer one within {1e3 * FRAME_BUDGET_S:.0f} ms"
                )
            self._settle()
            return
        iso = float(self.surface.field_data["iso_hu"][0])
        self._refining_for = gen
        self.ctx.status(f"3D: contouring a finer bone surface (up to {budget:,} triangles) ...")
        self._refiner.submit(lambda: volume_surface(volume, iso_hu=iso, max_triangles=budget))

    def _refined(self, surface: pv.PolyData) -> None:
        if self._refining_for != self._surface_gen:
            return
        old = self.surface
        if old is not None and surface.n_cells <= old.n_cells:
            self._settle()
            return
        self.ctx.status(
            f"3D: bone surface of {surface.n_cells:,} triangles "
            f"(voxel blocks {tuple(int(b) for b in surface.field_data['block'])})"
        )
        self.set_surface(surface, refined=True)

    def _refine_failed(self, exc: BaseException, _tb: str) -> None:
        self.ctx.status(f"3D: the finer bone surface failed: {exc}")
        self._settle()

    def _settle(self) -> None:
        self.settled_s = time.perf_counter()
        self.surface_settled.emit()

    # ------------------------------------------------------------------ plan
    def _aim(self, scene: SceneInput) -> None:
        pose = scene_camera(scene, self.surface)
        if pose is not None:
            apply_camera(self.plotter, pose)
        if scene.entry_lps is not None and scene.target_lps is not None:
            self._camera_for = (1.0,)

    def show_scene(self, scene: SceneInput, *, refocus: bool = False, render: bool = True) -> None:
        """Replace the plan's actors by those of ``scene`` (the bone stays); the camera is
        aimed the first time a trajectory is shown on this surface, or when ``refocus``.

        With ``render`` False the frame is left to a later :meth:`render_now` (the window
        draws it in its own event-loop pass)."""
        self.scene = scene
        cam = self.plotter.camera_position
        bone = {**self._old_bone, **self._bone}
        first = {"bone": self.actors["bone"]} if "bone" in self.actors else {}
        plan = plan_actors(self.plotter, scene, self._kept)  # the unchanged ones kept
        kept = {id(a) for a in plan.values()}
        for name, actor in list(self.actors.items()):
            if name not in bone and name != "bone" and id(actor) not in kept:
                self.plotter.remove_actor(actor, render=False)
        self.actors = {**bone, **first, **plan}
        if refocus or self._camera_for is None:
            self._aim(scene)
        else:
            self.plotter.camera_position = cam
        if render:
            self.render_now()

    def set_drill_depth(self, depth_mm: float) -> None:
        """Put the drill tip at ``depth_mm`` along the planned axis (live rehearsal)."""
        if self.scene is None or self.scene.entry_lps is None:
            return
        axis = np.asarray(self.scene.target_lps) - np.asarray(self.scene.entry_lps)
        axis = axis / np.linalg.norm(axis)
        set_drill_depth(self.actors, axis, depth_mm)
        self.render_now()

    def render_now(self) -> None:
        """Draw one frame now."""
        t0 = time.perf_counter()
        self.plotter.render()
        self.frames_drawn += 1
        self.last_frame_s = time.perf_counter()
        self.last_render_s = self.last_frame_s - t0

    def grab_rgb(self) -> np.ndarray:
        """(H, W, 3) uint8 image of the render window, as displayed."""
        img = self.plotter.screenshot(return_img=True)
        return np.asarray(img)[..., :3]

    def close_plotter(self) -> None:
        """Release the render window (call before the widget is destroyed)."""
        self.plotter.close()
