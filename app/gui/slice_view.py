"""One slice view: a matplotlib canvas showing a :class:`~ctdrill.app.gui.slices.SliceImage`
with its orientation letters, the plane's position, and the plan drawn over it
(:mod:`ctdrill.app.gui.slice_overlays`).

Drawing keeps the slice image as a background: a draw that only the overlays need (a plan
edit, its path, an undo) restores it and draws the overlays over it, the same pixels
(:mod:`ctdrill.app.gui.kept_background`).

The widget only draws and reports; the grid (:mod:`ctdrill.app.gui.slice_grid`) decides what a
report changes. Controls (docs/slice_views.md):

- wheel, PageUp/PageDown, Up/Down: ``paged(steps)`` (the next or previous plane);
- Ctrl+wheel, +/-: zoom about the cursor (or the centre); C: ``centre_requested``;
- right-drag: ``window_dragged(dx_px, dy_px)`` (window/level); a right *click* places the
  target (Shift: the entry), ``point_moved``;
- mouse over the image: ``cursor_moved(lps)`` (None when it leaves the image);
- the grips, the canal tracing, the measuring tools and the link click of
  :class:`~ctdrill.app.gui.map_canvas.MapCanvas`; ``arch`` (axial view):
  ``arch_edited(op, index, lps)``.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable
from typing import Any

import numpy as np
from matplotlib.backend_bases import MouseEvent
from matplotlib.figure import Figure
from PySide6.QtCore import Qt, Signal
from PySide6.QtGui import QKeyEvent, QPaintEvent, QWheelEvent

from ctdrill.app.gui.canvas_text import POINT_IN, PaintedText, paint_texts
from ctdrill.app.gui.kept_background import KeptBackground
from ctdrill.app.gui.map_canvas import MapCanvas, modifiers
from ctdrill.app.gui.sections import revolved_section
from ctdrill.app.gui.slice_nav import orientation_letters
from ctdrill.app.gui.slice_overlays import SLAB_MM, draw_scene, plane_of
from ctdrill.app.gui.slice_scene import OverlayScene, trajectory_drawing
from ctdrill.app.gui.slices import SliceImage, window_to_uint8
from ctdrill.app.gui.workers import StepQueue
from ctdrill.imaging.plan.types import Plan

#: The closest zoom, mm of field of view.
MIN_FOV_MM = 5.0
#: Zoom per wheel step or +/- key.
WHEEL_ZOOM = 1.25
#: A right-button press that moves more than this is a window/level drag, not a click, px.
DRAG_PX = 4.0

_TITLES = {
    "axial": "axial",
    "coronal": "coronal",
    "sagittal": "sagittal",
    "trajectory": "along the drill",
}
_PAGE_KEYS = {
    Qt.Key.Key_PageUp: 1,
    Qt.Key.Key_Up: 1,
    Qt.Key.Key_PageDown: -1,
    Qt.Key.Key_Down: -1,
}
#: Qt object names of the views (an outside script finds them by name).
OBJECT_NAMES = {
    "axial": "view:axial",
    "coronal": "view:coronal",
    "sagittal": "view:sagittal",
    "trajectory": "view:drill",
}


class SliceMap:
    """A slice plane as a :class:`~ctdrill.app.gui.map_ghost.PlaneMap`."""

    def __init__(self, image: SliceImage) -> None:
        self.image = image

    def to_lps(self, uv_mm: np.ndarray) -> np.ndarray:
        return self.image.to_lps(uv_mm)

    def to_uv(self, points_lps: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self.image.to_plane_mm(points_lps)


class SliceCanvas(MapCanvas):
    """A slice view with grips, paging, zoom, window/level drag and tools."""

    point_moved = Signal(str, object)  # handle name ("entry" | "target"), (3,) LPS mm
    paged = Signal(int)  # planes to step (+: towards larger coordinates)
    window_dragged = Signal(float, float)  # screen px since the last report (x right, y down)
    centre_requested = Signal()
    arch_edited = Signal(str, int, object)  # "add" | "move" | "delete", vertex, LPS or None

    def __init__(self, view: str, *, steps: StepQueue | None = None) -> None:
        """``steps``: if given, redraws requested with ``draw_idle`` are queued there (one
        canvas per event-loop pass) instead of matplotlib's own idle draw."""
        fig = Figure(figsize=(3.0, 3.0), dpi=80, facecolor="#101010")
        super().__init__(fig)
        self.setObjectName(OBJECT_NAMES.get(view, f"view:{view}"))
        self.setFocusPolicy(Qt.FocusPolicy.StrongFocus)
        self.view = view
        self.on_plane_mm = SLAB_MM
        self._steps = steps
        self._draw_queued = False
        #: Called by a queued draw right before it draws (the grid brings the overlays due
        #: up to date, so a draw queued before a new path result shows it: one draw, not two).
        self.before_draw: Callable[[], None] | None = None
        self.ax = fig.add_axes((0.0, 0.04, 1.0, 0.90))
        self.ax.set_facecolor("black")
        self.ax.set_axis_off()
        # the labels: painted by Qt over the canvas (canvas_text), never drawn by Agg
        self._title = PaintedText(0.01, 0.995, _TITLES.get(view, view), va="top", bold=True)
        self._position = PaintedText(0.01, 0.005, va="bottom")
        self._letters = {
            "left": PaintedText(0.01, 0.49, ha="left", va="center"),
            "right": PaintedText(0.99, 0.49, ha="right", va="center"),
            "top": PaintedText(0.5, 0.94, ha="center", va="bottom"),
            "bottom": PaintedText(0.5, 0.045, ha="center", va="bottom"),
        }
        self._note = PaintedText(0.5, 0.5, colour="#c0c0c0", ha="center", wrap=True)
        self.image: SliceImage | None = None
        self._im: Any = None
        self.scene = OverlayScene()
        self._right: tuple[float, float, bool, bool] | None = None  # x, y, shift, dragging
        #: Field of view (mm, square) and its centre (in-plane mm); None: the whole image.
        self.fov_mm: float | None = None
        self.center_uv: np.ndarray | None = None
        #: The image kept as the background of the overlays' draws.
        self.kept = KeptBackground()
        self.mpl_connect("axes_leave_event", self._left)

    @property
    def add_points_mode(self) -> bool:
        """Left clicks add canal points (the ``canal`` mode)."""
        return self.mode == "canal"

    @add_points_mode.setter
    def add_points_mode(self, on: bool) -> None:
        self.mode = "canal" if on else "navigate"

    # ------------------------------------------------------------------ drawing
    def draw_idle(self, *, next_step: bool = False) -> None:
        """Queue a redraw (on the step queue when given: the canvases' expensive Agg draws
        never hold the UI thread back to back); ``next_step``: as the next step, before those
        queued (the view just changed shows it before the other views' work)."""
        if self._steps is None:
            super().draw_idle()
        elif next_step:
            self._draw_queued = True
            self._steps.push(self._draw_now, first=True)
        elif not self._draw_queued:
            self._draw_queued = True
            self._steps.push(self._draw_now)

    def _draw_now(self) -> None:
        if not self._draw_queued:  # drawn already (queued twice: next, then at the end)
            return
        if self.before_draw is not None:  # overlays that changed since the draw was queued
            self.before_draw()
        self._draw_queued = False
        self.draw()

    def draw(self) -> None:
        """Agg-draw the view, its image from the kept background when it still stands
        (:class:`~ctdrill.app.gui.kept_background.KeptBackground`), and ask Qt to paint it."""
        if self._is_drawing:
            return
        self._is_drawing = True
        try:
            self.kept.draw(self, self.ax, self._im, super().draw)
        finally:
            self._is_drawing = False
        self.update()

    def set_note(self, text: str) -> None:
        """A line of text in the middle of the view (empty: none)."""
        self._note.set_text(text)
        self.update()

    def set_position_text(self, text: str) -> None:
        """The plane's position readout (bottom left)."""
        self._position.set_text(text)
        self.update()

    def paintEvent(self, event: QPaintEvent) -> None:
        """The canvas (and a dragged plan's outline), then the labels over it."""
        super().paintEvent(event)
        px_per_pt = float(self.figure.dpi) * POINT_IN / float(self.device_pixel_ratio)
        paint_texts(
            self, [self._title, self._position, *self._letters.values(), self._note], px_per_pt
        )

    def position_text(self) -> str:
        """The plane's position readout as shown."""
        return str(self._position.get_text())

    def letters(self) -> dict[str, str]:
        """The orientation letters shown at the image's edges."""
        return {k: str(t.get_text()) for k, t in self._letters.items()}

    def show_slice(self, image: SliceImage, *, level_hu: float, width_hu: float) -> None:
        """Replace the image (and keep the overlays until ``set_overlays``)."""
        self.image = image
        self.plane_map = SliceMap(image)
        self._note.set_text("")
        for side, text in orientation_letters(image.u_lps, image.v_lps).items():
            self._letters[side].set_text(text)
        grey = window_to_uint8(image.hu, level_hu=level_hu, width_hu=width_hu)
        self.kept.image_version += 1  # the kept background is of the previous image
        if self._im is None:
            self._im = self.ax.imshow(
                grey,
                cmap="gray",
                vmin=0,
                vmax=255,
                extent=image.extent_mm,
                origin="upper",
                interpolation="bilinear",
                zorder=0,
            )
        else:
            self._im.set_data(grey)
            self._im.set_extent(image.extent_mm)
        self._apply_view()

    def set_window(self, image: SliceImage, *, level_hu: float, width_hu: float) -> None:
        """Re-window the current image."""
        self.show_slice(image, level_hu=level_hu, width_hu=width_hu)
        self.draw_idle()

    def focus_on(self, point_lps: np.ndarray) -> None:
        """Centre the view on ``point_lps`` (projected into the plane), keeping the zoom."""
        if self.image is None:
            return
        uv, _ = self.image.to_plane_mm(np.asarray(point_lps, dtype=np.float64))
        self.center_uv = np.asarray(uv, dtype=np.float64)
        self._apply_view()
        self.draw_idle()

    def zoom(self, factor: float, about_uv: np.ndarray | None = None) -> None:
        """Zoom in (``factor`` > 1) or out about ``about_uv`` (in-plane mm; default the
        centre); the field of view stays between ``MIN_FOV_MM`` and the whole image."""
        if self.image is None:
            return
        full = self._full_fov_mm()
        (x0, x1), (y0, y1) = self.ax.get_xlim(), self.ax.get_ylim()
        old = max(abs(x1 - x0), abs(y0 - y1))  # what is shown now
        new = float(np.clip(old / factor, MIN_FOV_MM, full))
        center = np.array([(x0 + x1) / 2.0, (y0 + y1) / 2.0])
        if about_uv is not None:
            about = np.asarray(about_uv, dtype=np.float64)
            center = about + (center - about) * (new / old)
        self.center_uv = center
        self.fov_mm = None if new >= full else new
        self._apply_view()
        self.draw_idle()

    def _full_fov_mm(self) -> float:
        assert self.image is not None
        left, right, bottom, top = self.image.extent_mm
        return max(right - left, bottom - top)

    def _apply_view(self) -> None:
        """Set the axes limits from the centre and field of view (the whole image if None)."""
        if self.image is None:
            return
        left, right, bottom, top = self.image.extent_mm
        if self.fov_mm is None or self.center_uv is None or self.fov_mm >= self._full_fov_mm():
            self.ax.set_xlim(left, right)
            self.ax.set_ylim(bottom, top)
            return
        half = self.fov_mm / 2.0
        cu, cv = float(self.center_uv[0]), float(self.center_uv[1])
        self.ax.set_xlim(cu - half, cu + half)
        self.ax.set_ylim(cv + half, cv - half)  # rows grow downwards

    def take_scene(self, scene: OverlayScene) -> None:
        """Hit-test against ``scene`` from now on (its grips and canal points); drawing it is
        :meth:`set_overlays`, which may follow in a later step."""
        self.scene = scene
        self.grips = dict(scene.handles)
        self.grip_plan = scene.plan
        self.canals = list(scene.canals)

    def set_overlays(self, scene: OverlayScene) -> None:
        """Draw ``scene`` (every trajectory, landmarks, arch, handles) and the tools' marks."""
        self.take_scene(scene)
        for artist in [*self.ax.lines, *self.ax.patches, *self.ax.collections, *self.ax.texts]:
            artist.remove()
        if self.image is not None:
            draw_scene(self.ax, self.image, scene, arch=self.view == "axial")
            self.tools.draw()
            self.draw_crosshair()
        self.draw_idle()

    def arch_points(self) -> np.ndarray | None:
        """The arch the arch tool edits (the axial view's), or None elsewhere."""
        if self.view != "axial":
            return None
        arch = self.scene.arch_lps
        return np.empty((0, 3)) if arch is None else arch

    def emit_arch_edit(self, op: str, index: int, point_lps: np.ndarray | None) -> None:
        """Report an arch edit (the grid turns it into ``Document.set_arch``)."""
        self.arch_edited.emit(op, index, point_lps)

    def ghost_lines(self, plan: Plan) -> list[np.ndarray]:
        """The dragged trajectory's drill and implant outlines and axis on this plane."""
        if self.image is None:
            return []
        plane = plane_of(self.image)
        drawing = trajectory_drawing(plan, None, current=True)
        out = []
        for body in (drawing.drill, drawing.implant):
            if body is not None:
                for poly in revolved_section(
                    plane, body.p0_lps, body.axis_lps, body.s_mm, body.r_mm
                ):
                    out.append(np.vstack([poly, poly[:1]]))
        uv, _ = self.image.to_plane_mm(np.stack([plan.entry_lps, plan.target_lps]))
        out.append(uv)
        return out

    # ------------------------------------------------------------------ keys and wheel
    def keyPressEvent(self, event: QKeyEvent) -> None:
        key = Qt.Key(event.key())
        if key in _PAGE_KEYS:
            self.paged.emit(_PAGE_KEYS[key])
        elif key in (Qt.Key.Key_Plus, Qt.Key.Key_Equal):
            self.zoom(WHEEL_ZOOM)
        elif key == Qt.Key.Key_Minus:
            self.zoom(1.0 / WHEEL_ZOOM)
        elif key == Qt.Key.Key_C:
            self.centre_requested.emit()
        elif key in (Qt.Key.Key_Delete, Qt.Key.Key_Backspace, Qt.Key.Key_Escape):
            self.delete_under_cursor()
        else:
            super().keyPressEvent(event)

    def wheelEvent(self, event: QWheelEvent) -> None:
        steps = round(event.angleDelta().y() / 120.0)
        if steps == 0:
            return
        if event.modifiers() & Qt.KeyboardModifier.ControlModifier:
            x, y = self.mouseEventCoords(event)
            uv = np.asarray(self.ax.transData.inverted().transform((x, y)), dtype=np.float64)
            self.zoom(WHEEL_ZOOM**steps, uv)
        else:
            self.paged.emit(int(steps))

    # ------------------------------------------------------------------ mouse
    def _left(self, _event: object) -> None:
        with contextlib.suppress(RuntimeError):  # the window is closing: nobody to tell
            self.cursor_moved.emit(None)

    def right_press(self, event: MouseEvent, uv: np.ndarray) -> None:
        """A right press: a window/level drag or, released in place, a click."""
        shift, _ctrl = modifiers(event)
        self._right = (float(event.x), float(event.y), shift, False)

    def motion_hook(self, event: MouseEvent, uv: np.ndarray | None) -> bool:
        """A right-button drag adjusts the window/level (nothing else sees it)."""
        if self._right is None:
            return False
        x0, y0, shift, dragging = self._right
        dx, dy = float(event.x) - x0, float(event.y) - y0
        if dragging or np.hypot(dx, dy) > DRAG_PX:
            self._right = (float(event.x), float(event.y), shift, True)
            self.window_dragged.emit(dx, -dy)  # matplotlib's y grows upwards
        return True

    def right_release(self, event: MouseEvent, uv: np.ndarray | None) -> None:
        """A right click places the target (Shift: the entry); in a tool it removes."""
        if self._right is None:
            return
        _x, _y, shift, dragging = self._right
        self._right = None
        if dragging or uv is None or self.image is None:
            return
        if self.mode != "navigate":
            super().right_release(event, uv)
            return
        self.point_moved.emit("entry" if shift else "target", self.image.to_lps(uv))
