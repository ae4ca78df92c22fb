"""The embedded 3D view, observing the window's document: a plain ``QWidget`` showing the frames
its render thread (:mod:`ctdrill.app.gui.render_thread`: an off-screen EGL render window, every
VTK actor of the view built, changed and drawn there) hands back as images. No OpenGL widget is
in the window, so Qt composes the window's updates without OpenGL, and no frame holds the UI
thread.

A new bone surface (computed in a worker: every slice, full resolution) is handed to the render
thread in pieces (:func:`ctdrill.app.gui.surface.surface_piece`); its actors stay while the
plan's actors are rebuilt when the path result for the plan arrives (or fails: the landmarks are
then drawn as unknown) and when suggested axes arrive (the best feasible ones drawn as numbered
lines); the drill follows the live depth of a rehearsal. The camera starts where
:func:`ctdrill.app.gui.scene.scene_camera` says; the mouse turns, pans and zooms it
(:mod:`ctdrill.app.gui.interactor`), R (or a double click) puts it back."""

from __future__ import annotations

import time
from typing import TYPE_CHECKING, Any

import numpy as np
from PySide6.QtCore import Signal

from ctdrill.app.gui.compute import volume_surface
from ctdrill.app.gui.document import ViewContext
from ctdrill.app.gui.frame_view import FrameView
from ctdrill.app.gui.meshes import landmark_meshes
from ctdrill.app.gui.planning import landmark_geometries, scene_input
from ctdrill.app.gui.results import PathView
from ctdrill.app.gui.scene import BACKGROUND, SceneInput, scene_camera
from ctdrill.app.gui.scene_plans import plans_scene
from ctdrill.app.gui.suggesting import candidate_lines
from ctdrill.app.gui.surface import MAX_TRIANGLES, piece_count, surface_piece
from ctdrill.app.gui.view3d_actors import SceneActors
from ctdrill.app.gui.workers import Runner

if TYPE_CHECKING:
    import pyvista as pv

    from ctdrill.imaging.plan.types import Plan

#: The longest a frame of the 3D view should take on its render thread, s (the pace at which
#: the camera follows the mouse and a rehearsal's drill moves).
FRAME_BUDGET_S = 0.1
#: Render on a thread of the view's own (False: on the UI thread, as where EGL is missing).
THREADED = True
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


class View3D(FrameView):
    """3D view of the bone surface, trajectories, implants, drill and landmarks.

    Signals
    -------
    surface_shown() : the frame with the last piece of the current bone surface is on the
        screen (:attr:`surface_shown_s` holds when).
    surface_settled() : no finer surface will follow (:attr:`settled_s` holds when).

    The series opens with a coarse surface (``compute.FIRST_TRIANGLES``); once it is drawn,
    the frame it took (on the render thread) says how many triangles a frame of
    :data:`FRAME_BUDGET_S` affords, and a worker contours the finest surface within that
    (every voxel when it fits), which then replaces the coarse one piece by piece.

    :attr:`busy` is True while a frame or a scene change sent to the render thread is not on
    the screen yet; :attr:`frames_drawn`, :attr:`last_frame_s` (perf_counter() when the latest
    frame reached the view) and :attr:`last_render_s` (its render, on the render thread, s)
    count and time the frames.
    """

    surface_shown = Signal()
    surface_settled = Signal()

    def __init__(self, ctx: ViewContext, *, multi_samples: int = 0) -> None:
        """``multi_samples``: MSAA samples; 0 by default because on a software OpenGL (Mesa
        llvmpipe, Xvfb) 4x MSAA more than doubles the frame time (see docs/benchmarks.md)."""
        super().__init__(background=BACKGROUND[0], threaded=THREADED)
        self.ctx = ctx
        self._vtk = SceneActors()
        vtk, samples = self._vtk, int(multi_samples)

        def setup(stage: Any) -> None:
            stage.window.SetMultiSamples(samples)
            vtk.setup(stage)

        self.rt.submit(setup, frame=False)
        self.surface: pv.PolyData | None = None
        self.scene: SceneInput | None = None
        self._surface_gen = 0
        self._camera_for: tuple[float, ...] | None = None
        #: perf_counter() when the current surface's last piece was drawn (nan: not yet).
        self.surface_shown_s = float("nan")
        self.settled_s = float("nan")
        self._refined_gen = 0  # the surface generation a refinement was installed as
        self._refiner = Runner(self._refined, self._refine_failed, parent=self)
        self._refining_for = 0
        #: Point the camera at the trajectory on the next build (a newly opened plan).
        self.refocus_next = False
        self._site = (0, 0)  # (trajectories, current) last seen
        doc = ctx.doc
        doc.surface_changed.connect(self._surface)
        doc.path_changed.connect(self._path)
        doc.live_depth_changed.connect(self.set_drill_depth)
        doc.suggestion_changed.connect(self._suggestion)
        doc.plans_changed.connect(self._plans)
        doc.plan_changed.connect(self.prefetch)

    @property
    def actors(self) -> dict[str, Any]:
        """Every actor shown, by name (the bone pieces and the plan's), as the render thread
        last left them (read only: they belong to the render thread)."""
        return self._vtk.shown

    def reset_camera(self) -> None:
        """The starting camera of the scene shown (:func:`scene_camera`)."""
        self._aim(self.scene or scene_input(None, None))

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
        # the scene is sent at once (well under a millisecond here): its actors are built and
        # drawn on the render thread while the slices redraw, the frame being the longest
        # part of a plan edit's answer (a drawing step would wait behind the window's paints)
        self.show_scene(self._plans_scene(view), refocus=self.refocus_next)
        self.refocus_next = False

    def _plans_scene(self, view: PathView | None) -> SceneInput:
        """The document's trajectories with ``view`` (the current one's path result), the
        suggested axes and the other trajectories' known results."""
        doc = self.ctx.doc
        lines = candidate_lines(doc.suggestion, doc.adopted)
        views = [doc.cached_path(p) for p in doc.plans]
        return plans_scene(doc.plans, doc.current, view, lines, views)

    def prefetch(self, plan: Plan | None) -> None:
        """A plan edit (not a drag's move): its landmarks' tubes are made on the render thread
        while its path is planned (:func:`~ctdrill.app.gui.meshes.landmark_meshes` keeps
        them), so the path result's scene is drawn without making them then, when the
        render thread would wait for the interpreter lock behind the slices' redraws."""
        if plan is None or self.ctx.doc.live.dragging:
            return

        def make(_stage: Any) -> None:
            for lm in landmark_geometries(plan):
                landmark_meshes(lm)

        self.rt.submit(make, key="prefetch", frame=False)

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
                self.show_scene(self._plans_scene(view))

        self.ctx.steps.push(build)

    # ------------------------------------------------------------------ bone surface
    def set_surface(
        self, surface: pv.PolyData | None, *, redraw: bool = True, refined: bool = False
    ) -> None:
        """Use a new bone surface (new volume or preset): its pieces are sent to the render
        thread (``redraw`` is accepted for compatibility: the pieces always draw); the camera
        is re-aimed with the first piece, unless ``refined`` (a finer surface of the same
        volume, which is never refined again)."""
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
        vtk = self._vtk
        if refined:  # the coarse surface stays until the finer one is all in
            self.rt.submit(lambda _stage: vtk.keep_old(), frame=False)
        else:
            self.rt.submit(vtk.drop_bone, frame=False)
        if surface is not None and n and self._camera_for is None:
            self._aim(self.scene or scene_input(None, None))
        for index in range(n):
            self._add_piece(gen, index, n)
        if n == 0:
            self.rt.submit(None, frame=False, then=lambda _r: self._surface_done(gen))

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
        self.surface_shown_s = float("nan")
        self.settled_s = float("nan")
        self.rt.submit(self._vtk.drop_bone)

    def _add_piece(self, gen: int, index: int, total: int) -> None:
        """Send piece ``index`` of the current surface: it is cut, added and drawn on the
        render thread (skipped there when a newer surface came meanwhile)."""
        surface, vtk = self.surface, self._vtk
        if surface is None:
            return
        last = index == total - 1

        def add(stage: Any) -> None:
            if gen == self._surface_gen:
                piece = surface_piece(surface, index)
                vtk.add_piece(stage, f"bone:{gen}:{index}", piece, last=last)

        then = (lambda _r: self._surface_done(gen)) if last else None
        self.rt.submit(add, then=then)

    def _surface_done(self, gen: int) -> None:
        if gen != self._surface_gen:
            return
        self.surface_shown_s = self.last_frame_s
        self.surface_shown.emit()
        if self._refined_gen == gen or not self._refinable():
            self._settle()
            return
        self._time_frames(gen)

    def _refinable(self) -> bool:
        surf = self.surface
        if surf is None or surf.n_cells == 0 or self.ctx.doc.volume is None:
            return False
        if "iso_hu" not in surf.field_data or "block" not in surf.field_data:
            return False
        return tuple(int(b) for b in surf.field_data["block"]) != (1, 1, 1)

    def _time_frames(self, gen: int) -> None:
        """Time two frames on the render thread, with the bone hidden and shown; then ask for
        the finer surface the frame budget affords."""
        vtk, rt = self._vtk, self.rt

        def both(stage: Any) -> tuple[float, float]:
            vtk.set_bone_visible(False)
            without = rt.render_once(stage)
            vtk.set_bone_visible(True)
            return without, rt.render_once(stage)

        self.rt.submit(both, frame=False, then=lambda r: self._frames_timed(gen, r))

    def _frames_timed(self, gen: int, times: tuple[float, float] | None) -> None:
        if gen != self._surface_gen:
            return
        without_s, with_s = times if times is not None else (float("nan"), float("nan"))
        self.last_render_s = with_s
        budget = refine_budget(
            self.surface.n_cells if self.surface is not None else 0, without_s, with_s
        )
        volume = self.ctx.doc.volume
        if budget is None or volume is None or self.surface is None:
            if self.surface is not None:
                block = "x".join(str(int(b)) for b in self.surface.field_data["block"])
                self.ctx.status(
                    f"3D: bone surface of {self.surface.n_cells:,} triangles on {block} voxel "
                    f"blocks; a frame takes {1e3 * with_s:.0f} ms here, so no "
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
            self.set_camera(pose)
        if scene.entry_lps is not None and scene.target_lps is not None:
            self._camera_for = (1.0,)

    def show_scene(self, scene: SceneInput, *, refocus: bool = False, render: bool = True) -> None:
        """Replace the plan's actors by those of ``scene`` (the bone stays; built on the render
        thread, the latest scene sent winning); the camera is aimed the first time a
        trajectory is shown on this surface, or when ``refocus``.

        With ``render`` False the frame is left to a later :meth:`render_now`."""
        self.scene = scene
        vtk = self._vtk
        self.rt.submit(lambda stage: vtk.show_plan(stage, scene), key="plan", frame=False)
        if refocus or self._camera_for is None:
            self._aim(scene)
        if render:
            self.render_now()

    def set_drill_depth(self, depth_mm: float) -> None:
        """Put the drill tip at ``depth_mm`` along the planned axis (live rehearsal)."""
        if self.scene is None or self.scene.entry_lps is None:
            return
        axis = np.asarray(self.scene.target_lps) - np.asarray(self.scene.entry_lps)
        axis = axis / np.linalg.norm(axis)
        vtk = self._vtk
        self.rt.submit(lambda _stage: vtk.set_drill(axis, depth_mm), key="drill")
