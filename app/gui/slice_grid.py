"""The four slice views (axial, coronal, sagittal, along the drill) with their toolbar and
readout line, observing the document.

Each orthogonal view shows one plane of the volume; paging moves it through the volume's own
planes (:mod:`ctdrill.app.gui.slice_nav`), independently of the plan: a series opens with the
whole volume in view and the planes through the target (the middle planes without a plan);
"Centre on drill" (C) brings them back to the trajectory. The view along the drill turns about
the drill when paged. A plane is resliced in a worker thread (one runner per view) and each
canvas is drawn in an event-loop pass of its own. Grip drags, canal tracing and link clicks
become document edits through :class:`~ctdrill.app.gui.plan_editor.PlanEditor`; a target
placed with a right click through :func:`ctdrill.app.gui.planning.place_handle`; arch edits
go to ``Document.set_arch``.

Going to the site: a trajectory that appears or is selected puts every plane through its
target and centres each view on the implant, zoomed to :data:`SITE_FOV_MM`; a link click on
any view (the crosshair) puts the planes through the clicked point and centres the views on
it, keeping their zoom.
"""

from __future__ import annotations

from functools import partial

import numpy as np
from PySide6.QtCore import Signal
from PySide6.QtWidgets import QGridLayout, QHBoxLayout, QLabel, QVBoxLayout, QWidget

from ctdrill.app.gui.document import ViewContext
from ctdrill.app.gui.drag_sync import WithDrawnPosition
from ctdrill.app.gui.implant_drag import site_lps
from ctdrill.app.gui.overlay_pacing import OverlayPacing
from ctdrill.app.gui.plan_editor import PlanEditor
from ctdrill.app.gui.slice_edits import SliceEdits
from ctdrill.app.gui.slice_nav import (
    SliceStack,
    cursor_text,
    dragged_window,
    plane_center,
    slice_stack,
    window_text,
)
from ctdrill.app.gui.slice_scene import OverlayScene, overlay_scene
from ctdrill.app.gui.slice_toolbar import SliceToolbar
from ctdrill.app.gui.slice_view import SliceCanvas
from ctdrill.app.gui.slices import VIEWS, SliceImage, reslice, volume_center_lps
from ctdrill.app.gui.text_line import TextLine
from ctdrill.app.gui.workers import Runner, RunnerGroup
from ctdrill.imaging import CTVolume
from ctdrill.imaging.display import WINDOW_PRESETS
from ctdrill.imaging.plan.types import Plan

#: What the trajectory view says before a trajectory exists.
PLACE_HINT = "no trajectory yet:\nright-click the target,\nShift+right-click the entry"
#: Turn of the view along the drill per page step, degrees.
ROLL_STEP_DEG = 15.0
#: The orthogonal views (paged through the volume's planes).
ORTHO = ("axial", "coronal", "sagittal")
#: Field of view the slice views zoom to at an implant site, mm (an implant, its bone and
#: the canal below).
SITE_FOV_MM = 40.0


class SliceGrid(SliceEdits, QWidget):
    """Four :class:`SliceCanvas` in a 2 x 2 grid, a toolbar and a readout line."""

    slices_updated = Signal()  # every canvas shows the latest planes

    def __init__(self, ctx: ViewContext) -> None:
        super().__init__()
        self.ctx = ctx
        self.canvases: dict[str, SliceCanvas] = {v: SliceCanvas(v, steps=ctx.steps) for v in VIEWS}
        self.slices: dict[str, SliceImage] = {}
        self.window_level = WINDOW_PRESETS["bone"]
        self.stacks: dict[str, SliceStack] = {}
        #: Position of each orthogonal plane along its LPS axis, mm.
        self.positions: dict[str, float] = {}
        self.roll_deg = 0.0
        #: Arch points placed while fewer than two (no arch in the plan yet).
        self.arch_draft: np.ndarray | None = None
        self._keys: dict[str, tuple[object, ...] | None] = dict.fromkeys(VIEWS)
        #: Views paged while their previous plane was still being resliced.
        self._pending: set[str] = set()
        self._had_plan = False
        self._current = 0
        self._cursor_text = ""
        #: Where each view centres once its next plane is shown: (LPS point, field of view
        #: in mm or None to keep the zoom).
        self._focus: dict[str, tuple[np.ndarray, float | None]] = {}
        #: Canvases whose overlays wait for their drawing step (one step each, coalesced).
        self._overlays_due: set[str] = set()
        self.editor = PlanEditor(ctx)
        self.toolbar = SliceToolbar(self)
        #: The readout line: window/level, then HU and position at the cursor.
        self.wl_label = QLabel("")
        # the cursor's readout changes with every mouse move (a drag too): a line that repaints
        # itself only (a QLabel would re-lay out, and repaint, the whole window each time)
        self.readout = TextLine("")
        self._cursor_follows = WithDrawnPosition(ctx.doc.live, self._cursor)  # one update
        for label in (self.wl_label, self.readout):
            label.setStyleSheet("font-family: monospace")
        wl_width = self.wl_label.fontMetrics().horizontalAdvance("W 99999 L -9999 ")
        # a fixed size: a new window/level text asks no layout for room
        self.wl_label.setFixedSize(wl_width, self.wl_label.fontMetrics().height())
        grid = QGridLayout()
        grid.setContentsMargins(0, 0, 0, 0)
        grid.setSpacing(2)
        self.runners: dict[str, Runner] = {}
        for n, v in enumerate(VIEWS):
            canvas = self.canvases[v]
            grid.addWidget(canvas, n // 2, n % 2)
            canvas.point_moved.connect(self._handle_moved)
            self.editor.connect(canvas)
            canvas.paged.connect(partial(self.page, v))
            canvas.window_dragged.connect(self._window_dragged)
            canvas.cursor_moved.connect(self._cursor_follows)
            canvas.centre_requested.connect(self.centre_on_drill)
            canvas.arch_edited.connect(self._arch_edit)
            self.runners[v] = Runner(partial(self._sliced, v), self._slice_failed, parent=self)
            canvas.before_draw = partial(self._overlays_if_due, v)
        self.pacing = OverlayPacing(ctx, self.canvases, lambda v: self.draw_overlays(only=v), self)
        box = QVBoxLayout(self)
        box.setContentsMargins(0, 0, 0, 0)
        box.setSpacing(2)
        box.addWidget(self.toolbar)
        box.addLayout(grid, 1)
        line = QHBoxLayout()
        line.setContentsMargins(2, 0, 2, 0)
        line.addWidget(self.wl_label)
        line.addWidget(self.readout, 1)
        box.addLayout(line)
        self._show_readout("")
        doc = ctx.doc
        doc.volume_changed.connect(self._volume_changed)
        doc.plan_changed.connect(self._plan_changed)
        doc.path_changed.connect(lambda _view: self.draw_overlays())
        doc.live.crosshair_changed.connect(self.go_to)

    @property
    def runner(self) -> RunnerGroup:
        """Every view's runner, as one (``cancel``, ``busy``)."""
        return RunnerGroup(dict(self.runners))

    # ------------------------------------------------------------------ planes
    def _volume_changed(self, volume: CTVolume) -> None:
        self.runner.cancel()  # planes of the previous series are dropped
        self._pending.clear()
        self._keys = dict.fromkeys(VIEWS)  # a new volume may reuse a freed one's id
        self.stacks = {v: slice_stack(volume, v) for v in ORTHO}
        self.positions = {v: float(s.positions_mm[s.count // 2]) for v, s in self.stacks.items()}
        self.roll_deg = 0.0
        self.arch_draft = None
        plan = self.ctx.doc.plan
        if plan is not None:
            self._through(plan.target_lps)
        for canvas in self.canvases.values():  # the whole volume in view
            canvas.fov_mm, canvas.center_uv = None, None
        self._had_plan = plan is not None
        self._current = self.ctx.doc.current
        self.reslice()

    def _plan_changed(self, plan: Plan | None) -> None:
        current = self.ctx.doc.current
        appeared = plan is not None and not self._had_plan
        if plan is not None and self.stacks and (appeared or current != self._current):
            self._through(plan.target_lps)  # a trajectory appeared or was selected: show it
            self.focus_all(site_lps(plan), SITE_FOV_MM)
        self._had_plan, self._current = plan is not None, current
        self.reslice()

    def focus_all(self, point_lps: np.ndarray, fov_mm: float | None = None) -> None:
        """Centre every view on ``point_lps`` once its next plane is shown (``fov_mm``: zoom
        to that field of view; None keeps the zoom)."""
        for view in VIEWS:
            self._focus[view] = (np.asarray(point_lps, dtype=np.float64), fov_mm)

    def _apply_focus(self, view: str, image: SliceImage) -> None:
        focus = self._focus.pop(view, None)
        if focus is None:
            return
        canvas = self.canvases[view]
        point, fov = focus
        canvas.center_uv = np.asarray(image.to_plane_mm(point)[0], dtype=np.float64)
        if fov is not None:
            canvas.fov_mm = fov

    def go_to(self, point_lps: np.ndarray | None) -> None:
        """Link the views at ``point_lps`` (the crosshair): every orthogonal plane through
        it, every view centred on it (keeping its zoom) with the cross drawn."""
        for canvas in self.canvases.values():
            canvas.crosshair_lps = point_lps
        if point_lps is None or not self.stacks:
            self.draw_overlays()
            return
        self._through(point_lps)
        self.focus_all(point_lps)
        self.reslice()

    def _through(self, point_lps: np.ndarray) -> None:
        for v in ORTHO:
            self.positions[v] = float(np.asarray(point_lps)[self.stacks[v].axis])

    def plane_params(self, view: str) -> tuple[np.ndarray, np.ndarray | None] | None:
        """(centre, axis) of the plane ``view`` shows now, or None (no trajectory view)."""
        volume, plan = self.ctx.doc.volume, self.ctx.doc.plan
        if volume is None:
            return None
        if view == "trajectory":
            return None if plan is None else (plan.target_lps, plan.direction)
        return plane_center(volume_center_lps(volume), view, self.positions[view]), None

    def reslice(self, views: tuple[str, ...] = VIEWS) -> None:
        """Reslice the views whose plane moved (in the background); redraw the others'
        overlays."""
        volume = self.ctx.doc.volume
        if volume is None:
            return
        scene: OverlayScene | None = None  # the plan's overlays, built once for every view
        for view in views:
            params = self.plane_params(view)
            if params is None:
                self._keys[view] = None
                self.slices.pop(view, None)
                self.ctx.steps.push(partial(self._no_plane, view))
                continue
            center, axis = params
            roll = self.roll_deg if view == "trajectory" else 0.0
            key = (id(volume), view, *np.round(center, 9), roll)
            if axis is not None:
                key = (*key, *np.round(axis, 12))
            if key == self._keys[view]:
                image = self.slices.get(view)
                if image is not None and view in self._focus:
                    self._apply_focus(view, image)
                    self.canvases[view].show_slice(
                        image, level_hu=self.window_level[0], width_hu=self.window_level[1]
                    )
                scene = self._scene() if scene is None else scene
                self.draw_overlays(only=view, draw=self.pacing.draws_now(view), scene=scene)
                continue
            if self.runners[view].busy:  # one plane at a time per view: the latest one next
                self._pending.add(view)
                continue
            self._keys[view] = key

            def job(
                view: str = view,
                c: np.ndarray = center,
                a: np.ndarray | None = axis,
                r: float = roll,
            ) -> SliceImage:
                return reslice(volume, view, c, axis_lps=a, roll_deg=r)  # type: ignore[arg-type]

            self.runners[view].submit(job)

    def _no_plane(self, view: str) -> None:
        if self._keys[view] is None:
            self.canvases[view].set_note(PLACE_HINT)
            self._maybe_updated()

    def _sliced(self, view: str, image: SliceImage) -> None:
        self.slices[view] = image
        self.ctx.steps.push(partial(self._show, view, image))
        if view in self._pending:  # paged on meanwhile: reslice where the view is now
            self._pending.discard(view)
            self.reslice((view,))

    def _slice_failed(self, exc: BaseException, tb: str) -> None:
        self._keys = dict.fromkeys(VIEWS)
        self._pending.clear()
        self.ctx.status(f"error: the slice views could not be drawn: {exc}")

    def _show(self, view: str, image: SliceImage) -> None:
        if self.slices.get(view) is not image:
            return
        canvas = self.canvases[view]
        level, width = self.window_level
        self._apply_focus(view, image)
        canvas.show_slice(image, level_hu=level, width_hu=width)
        canvas.set_position_text(self.position_text(view))
        self.overlays_now(only=view)  # a drawing step already: the overlays with the image
        self._maybe_updated()

    def _maybe_updated(self) -> None:
        if not any(r.busy for r in self.runners.values()):
            self.ctx.steps.push(self._emit_updated)

    def _emit_updated(self) -> None:
        if not any(r.busy for r in self.runners.values()):
            self.slices_updated.emit()

    def position_text(self, view: str) -> str:
        """The readout of a view's plane position."""
        if view == "trajectory":
            return f"turned {self.roll_deg:+.0f}° about the drill"
        stack = self.stacks.get(view)
        return "" if stack is None else stack.describe(self.positions[view])

    def page(self, view: str, steps: int) -> None:
        """Move ``view``'s plane ``steps`` planes on (the drill view: turn it)."""
        if self.ctx.doc.volume is None:
            return
        if view == "trajectory":
            self.roll_deg = (self.roll_deg + ROLL_STEP_DEG * steps + 180.0) % 360.0 - 180.0
        else:
            self.positions[view] = self.stacks[view].step(self.positions[view], steps)
        self.reslice((view,))

    def centre_on_drill(self) -> None:
        """Bring every plane back to the trajectory (through the target, centred on it)."""
        plan = self.ctx.doc.plan
        if plan is None or not self.stacks:
            self.ctx.status("no trajectory to centre on")
            return
        self._through(plan.target_lps)
        self.roll_deg = 0.0
        self.focus_all((plan.entry_lps + plan.target_lps) / 2.0)
        self.reslice()

    # ------------------------------------------------------------------ overlays
    def draw_overlays(
        self, only: str | None = None, *, draw: bool = True, scene: OverlayScene | None = None
    ) -> None:
        """Overlay the plan (or the points placed so far; ``scene``: the document's, built
        already) on every canvas (or on ``only``): each hit-tests the new scene at once and
        draws it in a step of its own (an edit returns at once; the plan, then its path, before
        the step: one draw); with ``draw`` False it only hit-tests it (its drawing waits for the
        path: ``OverlayPacing``).

        The canal tubes are computed where they are drawn (kept for the next draw): computed
        in a worker while the path was planned, they slowed the path's worker and the UI
        thread more than they saved (a canal click settled 5-12 ms later), each thread waiting
        for the interpreter lock the others held."""
        scene = self._scene() if scene is None else scene
        for name, canvas in self.canvases.items():
            if only is not None and name != only:
                continue
            canvas.take_scene(scene)
            if draw and name not in self._overlays_due:
                self._overlays_due.add(name)
                self.ctx.steps.push(partial(self._overlay_step, name))

    def _overlay_step(self, name: str) -> None:
        if name in self._overlays_due:
            self._overlays_due.discard(name)
            canvas = self.canvases[name]
            canvas.set_overlays(canvas.scene)
            canvas.draw_idle(next_step=True)  # this view whole before the next one starts

    def _overlays_if_due(self, name: str) -> None:
        """A queued draw of ``name`` runs: its overlays due go with it (drawn once)."""
        if name in self._overlays_due:
            self._overlays_due.discard(name)
            self.canvases[name].set_overlays(self.canvases[name].scene)  # joins this draw

    def overlays_now(self, only: str | None = None) -> None:
        """Draw the overlays at once (on every canvas, or on ``only``)."""
        scene = self._scene()
        for name, canvas in self.canvases.items():
            if only is None or name == only:
                self._overlays_due.discard(name)
                canvas.set_overlays(scene)

    def _scene(self) -> OverlayScene:
        doc = self.ctx.doc
        plans, current = doc.plans, doc.current
        views = [doc.path if i == current else doc.cached_path(p) for i, p in enumerate(plans)]
        arch = self.arch_draft if self.arch_draft is not None else doc.arch_lps
        return overlay_scene(plans, current, views, draft=doc.draft, arch_lps=arch)

    # ------------------------------------------------------------------ window, cursor
    def set_window_preset(self, label: str) -> None:
        """Apply a window/level preset to the slice views."""
        self.set_window(*WINDOW_PRESETS[label])

    def set_window(self, level_hu: float, width_hu: float) -> None:
        """Apply a window/level to the slice views."""
        self.window_level = (float(level_hu), float(width_hu))
        for name, img in self.slices.items():
            self.canvases[name].set_window(img, level_hu=level_hu, width_hu=width_hu)
        self._show_readout(None)

    def _window_dragged(self, dx_px: float, dy_px: float) -> None:
        self.set_window(*dragged_window(*self.window_level, dx_px, dy_px))

    def _cursor(self, point_lps: np.ndarray | None) -> None:
        volume = self.ctx.doc.volume
        if point_lps is None or volume is None:
            self._show_readout("")
        else:
            self._show_readout(cursor_text(volume, point_lps))

    def _show_readout(self, cursor: str | None) -> None:
        if cursor is None:
            cursor = self._cursor_text
        self._cursor_text = cursor
        level, width = self.window_level
        self.wl_label.setText(window_text(level, width))
        self.readout.setText(cursor or "move over a slice for the HU and position")
