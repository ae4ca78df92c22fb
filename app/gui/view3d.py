"""The embedded 3D view: a ``pyvistaqt.QtInteractor`` drawn by
:func:`ctdrill.app.gui.scene.build_scene`, observing the window's document.

The scene is rebuilt when a new bone surface arrives, when the path result for the plan
arrives (or fails: the landmarks are then drawn as unknown) and when suggested axes arrive
(the best feasible ones drawn as numbered lines), each build and its frame in an event-loop
pass of its own; the drill follows the live depth of a rehearsal."""

from __future__ import annotations

import time
from typing import Any

import numpy as np
import pyvista as pv
from PySide6.QtWidgets import QVBoxLayout, QWidget
from pyvistaqt import QtInteractor

from ctdrill.app.gui.document import ViewContext
from ctdrill.app.gui.planning import scene_input
from ctdrill.app.gui.results import PathView
from ctdrill.app.gui.scene import SceneInput, build_scene, focus_camera, set_drill_depth
from ctdrill.app.gui.suggesting import candidate_lines


class View3D(QWidget):
    """3D view of the bone surface, trajectory, drill and landmarks."""

    def __init__(self, ctx: ViewContext, *, multi_samples: int = 0) -> None:
        """``multi_samples``: MSAA samples; 0 by default because on a software OpenGL (Mesa
        llvmpipe, Xvfb) 4x MSAA more than doubles the frame time (see docs/benchmarks.md)."""
        super().__init__()
        self.ctx = ctx
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        # No periodic re-render (pyvistaqt's default is 5 Hz even when nothing changes, ~50 ms a
        # frame on software GL): the view renders when the scene changes or the user interacts.
        self.plotter: Any = QtInteractor(self, multi_samples=multi_samples, auto_update=False)
        layout.addWidget(self.plotter.interactor)
        self.surface: pv.PolyData | None = None
        self.scene: SceneInput | None = None
        self.actors: dict[str, Any] = {}
        self._camera_for: tuple[float, ...] | None = None
        self.frames_drawn = 0
        self.last_frame_s = float("nan")  # perf_counter() at the end of the latest frame
        #: Point the camera at the trajectory on the next build (a newly opened plan).
        self.refocus_next = False
        doc = ctx.doc
        doc.surface_changed.connect(self._surface)
        doc.path_changed.connect(self._path)
        doc.live_depth_changed.connect(self.set_drill_depth)
        doc.suggestion_changed.connect(self._suggestion)

    # ------------------------------------------------------------------ document
    def _surface(self, surface: pv.PolyData | None) -> None:
        self.set_surface(surface, redraw=False)
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

    def set_surface(self, surface: pv.PolyData | None, *, redraw: bool = True) -> None:
        """Use a new bone surface (new volume or preset); redraws a shown scene if ``redraw``."""
        self.surface = surface
        self._camera_for = None
        if redraw and self.scene is not None:
            self.show_scene(self.scene)

    def show_scene(self, scene: SceneInput, *, refocus: bool = False, render: bool = True) -> None:
        """Rebuild the scene; the camera is focused on the trajectory the first time.

        With ``render`` False the frame is left to a later :meth:`render_now` (the window
        draws it in its own event-loop pass)."""
        self.scene = scene
        cam = self.plotter.camera_position
        self.actors = build_scene(self.plotter, scene, surface=self.surface)
        key = (len(self.actors),)
        if refocus or self._camera_for is None:
            bounds = None
            if self.surface is not None and self.surface.n_points > 0:
                bounds = tuple(self.surface.bounds)
            if scene.entry_lps is not None and scene.target_lps is not None:
                focus_camera(self.plotter, scene.entry_lps, scene.target_lps, bounds=bounds)
                self._camera_for = key
            elif bounds is not None:  # no trajectory: look at the anatomy's centre
                c = np.array(bounds).reshape(3, 2).mean(axis=1)
                focus_camera(self.plotter, c, c - np.array([0.0, 0.0, 1.0]), bounds=bounds)
                self.plotter.reset_camera()  # same direction, the whole anatomy in view
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
