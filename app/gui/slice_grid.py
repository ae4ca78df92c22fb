"""The four slice views (axial, coronal, sagittal, along the drill), observing the document.

The planes are resliced in a worker thread when the series or the trajectory's target and
direction change (else only the overlays are redrawn); each canvas is then drawn in an
event-loop pass of its own. A handle dragged or placed on a canvas becomes a plan edit through
:func:`ctdrill.app.gui.planning.place_handle`; without a plan, the first two points placed
make the trajectory (no trajectory is guessed for a new series).
"""

from __future__ import annotations

from functools import partial

import numpy as np
from PySide6.QtCore import Signal
from PySide6.QtWidgets import QGridLayout, QWidget

from ctdrill.app.gui import compute, planning
from ctdrill.app.gui.document import ViewContext
from ctdrill.app.gui.scene import LandmarkGeometry
from ctdrill.app.gui.slice_view import SliceCanvas
from ctdrill.app.gui.slices import VIEWS, WINDOW_PRESETS, SliceImage
from ctdrill.app.gui.workers import Runner

#: What the trajectory view says before a trajectory exists.
PLACE_HINT = "no trajectory yet:\nright-click the target,\nShift+right-click the entry"


class SliceGrid(QWidget):
    """Four :class:`SliceCanvas` in a 2 x 2 grid."""

    slices_updated = Signal()  # every canvas shows the latest planes

    def __init__(self, ctx: ViewContext) -> None:
        super().__init__()
        self.ctx = ctx
        self.canvases: dict[str, SliceCanvas] = {v: SliceCanvas(v, steps=ctx.steps) for v in VIEWS}
        self.slices: dict[str, SliceImage] = {}
        self.window_level = WINDOW_PRESETS["bone"]
        self._key: tuple[object, ...] | None = None
        grid = QGridLayout(self)
        grid.setContentsMargins(0, 0, 0, 0)
        grid.setSpacing(2)
        for n, v in enumerate(VIEWS):
            grid.addWidget(self.canvases[v], n // 2, n % 2)
            self.canvases[v].point_moved.connect(self._handle_moved)
            self.canvases[v].clicked.connect(self._canal_click)
        self.runner = Runner(self._sliced, self._slice_failed, parent=self)
        doc = ctx.doc
        doc.volume_changed.connect(self._reslice)
        doc.plan_changed.connect(self._reslice)
        doc.path_changed.connect(lambda _view: self.draw_overlays())

    # ------------------------------------------------------------------ document
    def _reslice(self, *_args: object) -> None:
        volume, plan = self.ctx.doc.volume, self.ctx.doc.plan
        if volume is None:
            return
        key = compute.slice_key(volume, plan)
        if key == self._key:  # the planes did not move: only the overlays change
            self.draw_overlays()
            return
        self._key = key
        self.runner.submit(lambda: compute.slice_views(volume, plan))

    def _sliced(self, slices: dict[str, SliceImage]) -> None:
        self.slices = slices
        for name in VIEWS:  # one canvas per event-loop pass
            self.ctx.steps.push(partial(self._show, slices, name))
        self.ctx.steps.push(lambda: self.slices_updated.emit() if slices is self.slices else None)

    def _slice_failed(self, exc: BaseException, tb: str) -> None:
        self._key = None
        self.ctx.status(f"error: the slice views could not be drawn: {exc}")

    def _show(self, slices: dict[str, SliceImage], name: str) -> None:
        if slices is not self.slices:
            return
        canvas = self.canvases[name]
        if name not in slices:
            canvas.set_note(PLACE_HINT)
            return
        level, width = self.window_level
        canvas.show_slice(slices[name], level_hu=level, width_hu=width)
        plan = self.ctx.doc.plan
        if plan is not None:  # the trajectory in the middle of the field of view
            canvas.focus_on((plan.entry_lps + plan.target_lps) / 2.0)
        else:
            canvas.fov_mm = None  # no trajectory: the whole plane
        self.draw_overlays(only=name)

    def draw_overlays(self, only: str | None = None) -> None:
        """Overlay the plan (or the points placed so far) on every canvas (or on ``only``)."""
        doc = self.ctx.doc
        plan, view = doc.plan, doc.path
        lms: tuple[LandmarkGeometry, ...]
        if plan is None:
            entry, target = doc.draft.get("entry"), doc.draft.get("target")
            stop, lms = None, ()
        else:
            entry, target = plan.entry_lps, plan.target_lps
            own = view is not None and view.plan is plan
            stop = plan.point_at_depth_lps(view.curves.stop_depth_mm) if own and view else None
            lms = planning.drawn_landmarks(plan, view)
        for name, canvas in self.canvases.items():
            if only is None or name == only:
                canvas.set_overlays(
                    entry_lps=entry, target_lps=target, stop_lps=stop, landmarks=lms
                )

    # ------------------------------------------------------------------ edits
    def _handle_moved(self, name: str, point_lps: np.ndarray) -> None:
        doc = self.ctx.doc
        try:
            placed = planning.place_handle(doc.plan, doc.draft, name, point_lps)
        except ValueError as exc:
            doc.edit_refused.emit(f"error: {exc}")
            self.draw_overlays()
            return
        if isinstance(placed, dict):
            doc.set_draft_point(name, placed[name])
        elif not doc.set_plan(placed):
            self.draw_overlays()  # refused (locked): the handle goes back

    def _canal_click(self, point_lps: np.ndarray) -> None:
        doc = self.ctx.doc
        if doc.plan is None:
            doc.edit_refused.emit("place the trajectory before the canal")
        else:
            doc.set_plan(planning.add_canal_point(doc.plan, point_lps))

    def set_canal_mode(self, on: bool) -> None:
        """Left clicks append canal points (True) or drag handles."""
        for canvas in self.canvases.values():
            canvas.add_points_mode = on

    def set_window_preset(self, label: str) -> None:
        """Apply a window/level preset to the slice views."""
        self.window_level = WINDOW_PRESETS[label]
        level, width = self.window_level
        for name, img in self.slices.items():
            self.canvases[name].set_window(img, level_hu=level, width_hu=width)
