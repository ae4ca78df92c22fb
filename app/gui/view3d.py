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
from pyvistaqt import QtInteractor

from ctdrill.app.gui.camera import add_orientation_marker, apply_camera
from ctdrill.app.gui.document import ViewContext
from ctdrill.app.gui.planning import scene_input
from ctdrill.app.gui.results import PathView
from ctdrill.app.gui.scene import (
    BACKGROUND,
    SceneInput,
    add_bone,
    plan_actors,
    scene_camera,
    set_drill_depth,
)
from ctdrill.app.gui.suggesting import candidate_lines
from ctdrill.app.gui.surface import piece_count, surface_piece


class View3D(QWidget):
    """3D view of the bone surface, trajectories, implants, drill and landmarks.

    Signals
    -------
    surface_shown() : the last piece of the current bone surface has been drawn
        (:attr:`surface_shown_s` holds when).
    """

    surface_shown = Signal()

    def __init__(self, ctx: ViewContext, *, multi_samples: int = 0) -> None:
        """``multi_samples``: MSAA samples; 0 by default because on a software OpenGL (Mesa
        llvmpipe, Xvfb) 4x MSAA more than doubles the frame time (see docs/benchmarks.md)."""
        super().__init__()
        self.ctx = ctx
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        # No periodic re-render (pyvistaqt's default is 5 Hz even when nothing changes, ~50 ms a
        # frame on software GL): the view renders when the scene changes or the user interacts.
        plotter: Any = QtInteractor(self, multi_samples=multi_samples, auto_update=False)
        self.plotter = plotter
        layout.addWidget(plotter.interactor)
        plotter.set_background(BACKGROUND[0], top=BACKGROUND[1])
        add_orientation_marker(plotter)
        self.surface: pv.PolyData | None = None
        self.scene: SceneInput | None = None
        #: Every actor by name: the bone pieces (``bone``, ``bone:1``, ...) and the plan's.
        self.actors: dict[str, Any] = {}
        self._bone: dict[str, Any] = {}
        self._surface_gen = 0
        self._camera_for: tuple[float, ...] | None = None
        self.frames_drawn = 0
        self.last_frame_s = float("nan")  # perf_counter() at the end of the latest frame
        #: perf_counter() when the current surface's last piece was drawn (nan: not yet).
        self.surface_shown_s = float("nan")
        #: Point the camera at the trajectory on the next build (a newly opened plan).
        self.refocus_next = False
        doc = ctx.doc
        doc.surface_changed.connect(self._surface)
        doc.path_changed.connect(self._path)
        doc.live_depth_changed.connect(self.set_drill_depth)
        doc.suggestion_changed.connect(self._suggestion)

    # ------------------------------------------------------------------ document
    def _surface(self, surface: pv.PolyData | None) -> None:
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
                scene = scene_input(plan, view, candidate_lines(doc.suggestion, doc.adopted))
                self.show_scene(scene, refocus=self.refocus_next, render=False)
                self.refocus_next = False

        self.ctx.steps.push(build)  # the build and its frame: two passes
        self.ctx.steps.push(lambda: self.render_now() if current() else None)

    def _suggestion(self, _suggestion: object) -> None:
        doc = self.ctx.doc
        if doc.plan is None or self.scene is None:
            return
        plan, view = doc.plan, doc.path

        def build() -> None:
            if doc.plan is plan and doc.path is view:
                lines = candidate_lines(doc.suggestion, doc.adopted)
                self.show_scene(scene_input(plan, view, lines), render=False)

        self.ctx.steps.push(build)
        self.ctx.steps.push(self.render_now)

    # ------------------------------------------------------------------ bone surface
    def set_surface(self, surface: pv.PolyData | None, *, redraw: bool = True) -> None:
        """Use a new bone surface (new volume or preset): its pieces are added and drawn one
        per event-loop pass (``redraw`` is accepted for compatibility: the pieces always
        draw); the camera is re-aimed with the first piece."""
        self.surface = surface
        self._camera_for = None
        self._surface_gen += 1
        gen = self._surface_gen
        self.surface_shown_s = float("nan")
        n = 0 if surface is None else piece_count(surface)
        self.ctx.steps.push(lambda: self._drop_bone(gen))
        for index in range(n):
            self.ctx.steps.push(lambda i=index: self._add_piece(gen, i, n))  # type: ignore[misc]
        if n == 0:
            self.ctx.steps.push(lambda: self._surface_done(gen))

    def _drop_bone(self, gen: int) -> None:
        """Remove the previous surface's actors (the GPU buffers go with them)."""
        if gen != self._surface_gen:
            return
        for name, actor in self._bone.items():
            self.plotter.remove_actor(actor, render=False)
            self.actors.pop(name, None)
        self._bone = {}

    def _add_piece(self, gen: int, index: int, total: int) -> None:
        """Add piece ``index`` of the current surface and draw the frame that uploads it."""
        if gen != self._surface_gen or self.surface is None:
            return
        name = "bone" if index == 0 else f"bone:{index}"
        actor = add_bone(self.plotter, surface_piece(self.surface, index), name=name)
        self._bone[name] = actor
        self.actors[name] = actor
        if index == 0 and self._camera_for is None:
            self._aim(self.scene or scene_input(None, None))
        self.render_now()
        if index == total - 1:
            self._surface_done(gen)

    def _surface_done(self, gen: int) -> None:
        if gen == self._surface_gen:
            self.surface_shown_s = self.last_frame_s
            self.surface_shown.emit()

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
        for name, actor in list(self.actors.items()):
            if name not in self._bone:
                self.plotter.remove_actor(actor, render=False)
        self.actors = {**self._bone, **plan_actors(self.plotter, scene)}
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
        self.plotter.render()
        self.frames_drawn += 1
        self.last_frame_s = time.perf_counter()

    def grab_rgb(self) -> np.ndarray:
        """(H, W, 3) uint8 image of the render window, as displayed."""
        img = self.plotter.screenshot(return_img=True)
        return np.asarray(img)[..., :3]

    def close_plotter(self) -> None:
        """Release the render window (call before the widget is destroyed)."""
        self.plotter.close()
