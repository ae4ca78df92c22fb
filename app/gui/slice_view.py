"""One slice view: a matplotlib canvas showing a :class:`~ctdrill.app.gui.slices.SliceImage` with
the trajectory, the drill's stop point and the landmarks; entry and target can be dragged.

The widget only draws and reports: a finished drag of a handle, or a right click (target;
Shift + right click: entry) emits ``point_moved(name, lps)``, and a left click in canal-point
mode emits ``clicked(lps)``; the window decides what they change. The mouse wheel zooms about
the cursor (``zoom``); ``focus_on`` centres the field of view on a point.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from matplotlib.backend_bases import MouseEvent
from matplotlib.backends.backend_qtagg import FigureCanvasQTAgg
from matplotlib.figure import Figure
from PySide6.QtCore import Signal

from ctdrill.app.gui.scene import LandmarkGeometry
from ctdrill.app.gui.slices import SliceImage, polyline_in_plane, window_to_uint8
from ctdrill.app.gui.workers import StepQueue

#: Pick radius for dragging a handle, pixels.
PICK_PX = 10.0
#: Field of view of a slice view around the trajectory, and the closest zoom, mm.
DEFAULT_FOV_MM = 50.0
MIN_FOV_MM = 5.0
#: Zoom per wheel step.
WHEEL_ZOOM = 1.25
#: Overlays within this distance of the plane are drawn solid, mm.
SLAB_MM = 2.0
#: Landmark colour, and the colour of a landmark whose margin the planned path breaks.
LANDMARK_COLOUR = "#ffd030"
VIOLATED_COLOUR = "#ff3030"

_TITLES = {
    "axial": "axial (A up, L right)",
    "coronal": "coronal (S up, L right)",
    "sagittal": "sagittal (S up, P right)",
    "trajectory": "along the drill",
}


class SliceCanvas(FigureCanvasQTAgg):
    """A draggable-handle slice view."""

    point_moved = Signal(str, object)  # handle name ("entry" | "target"), (3,) LPS mm
    clicked = Signal(object)  # (3,) LPS mm on the plane

    def __init__(self, view: str, *, steps: StepQueue | None = None) -> None:
        """``steps``: if given, redraws requested with ``draw_idle`` are queued there (one
        canvas per event-loop pass) instead of matplotlib's own idle draw."""
        fig = Figure(figsize=(3.0, 3.0), dpi=80, facecolor="#101010")
        super().__init__(fig)
        self.view = view
        self._steps = steps
        self._draw_queued = False
        self.ax = fig.add_axes((0.0, 0.0, 1.0, 0.93))
        self.ax.set_facecolor("black")
        self.ax.set_axis_off()
        fig.text(0.01, 0.99, _TITLES.get(view, view), color="#e0e0e0", fontsize=8, va="top")
        self._note = fig.text(0.5, 0.5, "", color="#c0c0c0", fontsize=9, ha="center", wrap=True)
        self.image: SliceImage | None = None
        self._im: Any = None
        self._handles: dict[str, np.ndarray] = {}
        self._handle_artists: dict[str, Any] = {}
        self._drag: str | None = None
        self.add_points_mode = False
        #: Field of view (mm, square) and its centre (in-plane mm); None: the whole image.
        self.fov_mm: float | None = DEFAULT_FOV_MM
        self.center_uv: np.ndarray | None = None
        self.mpl_connect("button_press_event", self._press)
        self.mpl_connect("motion_notify_event", self._motion)
        self.mpl_connect("button_release_event", self._release)
        self.mpl_connect("scroll_event", self._scroll)

    # ------------------------------------------------------------------ drawing
    def draw_idle(self) -> None:
        """Redraw soon: via the shared step queue if any (each canvas draws in a pass of its
        own, so several views changed together never hold the UI thread back to back)."""
        if self._steps is None:
            super().draw_idle()
        elif not self._draw_queued:
            self._draw_queued = True
            self._steps.push(self._draw_now)

    def _draw_now(self) -> None:
        self._draw_queued = False
        self.draw()

    def set_note(self, text: str) -> None:
        """A line of text in the middle of the view (empty: none)."""
        self._note.set_text(text)
        self.draw_idle()

    def show_slice(self, image: SliceImage, *, level_hu: float, width_hu: float) -> None:
        """Replace the image (and keep the overlays until ``set_overlays``)."""
        self.image = image
        self._note.set_text("")
        grey = window_to_uint8(image.hu, level_hu=level_hu, width_hu=width_hu)
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

    def set_window(self, image: SliceImage, *, level_hu: float, width_hu: float) -> None:
        """Re-window the current image."""
        self.show_slice(image, level_hu=level_hu, width_hu=width_hu)
        self.draw_idle()

    def set_overlays(
        self,
        *,
        entry_lps: np.ndarray | None,
        target_lps: np.ndarray | None,
        stop_lps: np.ndarray | None,
        landmarks: tuple[LandmarkGeometry, ...],
    ) -> None:
        """Draw the trajectory, stop point, landmarks and the entry/target handles (either
        handle may be missing while the trajectory is being placed)."""
        img = self.image
        for artist in [*self.ax.lines, *self.ax.patches, *self.ax.collections]:
            artist.remove()
        self._handle_artists.clear()
        if img is None:
            return
        for lm in landmarks:
            colour = VIOLATED_COLOUR if lm.violated else LANDMARK_COLOUR
            uv, near = polyline_in_plane(img, lm.points_lps, slab_mm=SLAB_MM + lm.radius_mm)
            style = "-" if near.any() else ":"
            if len(uv) == 1:
                self.ax.plot(uv[:, 0], uv[:, 1], "o", color=colour, ms=5, zorder=3)
            else:
                self.ax.plot(uv[:, 0], uv[:, 1], style, color=colour, lw=1.2, zorder=3)
                if near.any():
                    self.ax.plot(uv[near, 0], uv[near, 1], "o", color=colour, ms=3, zorder=3)
        if entry_lps is not None and target_lps is not None:
            line = np.array([entry_lps, target_lps], dtype=np.float64)
            uv, near = polyline_in_plane(img, line, slab_mm=SLAB_MM)
            style = "-" if near.all() else "--"
            self.ax.plot(uv[:, 0], uv[:, 1], style, color="#4080ff", lw=1.5, zorder=4)
        if stop_lps is not None:
            suv, _ = img.to_plane_mm(np.asarray(stop_lps, dtype=np.float64))
            self.ax.plot([suv[0]], [suv[1]], "x", color="#ff40b0", ms=9, mew=2, zorder=5)
        given = {"entry": entry_lps, "target": target_lps}
        self._handles = {
            name: np.asarray(pt, dtype=np.float64) for name, pt in given.items() if pt is not None
        }
        colours = {"entry": "#40e0ff", "target": "#ff6060"}
        for name, pt in self._handles.items():
            huv, off = img.to_plane_mm(pt)
            alpha = 1.0 if abs(float(off)) <= SLAB_MM else 0.45
            (artist,) = self.ax.plot(
                [huv[0]],
                [huv[1]],
                "o",
                mfc="none",
                mec=colours[name],
                mew=2,
                ms=9,
                alpha=alpha,
                zorder=6,
            )
            self._handle_artists[name] = artist
        self.draw_idle()

    # ------------------------------------------------------------------ interaction
    def _event_uv(self, event: MouseEvent) -> np.ndarray | None:
        if event.inaxes is not self.ax or event.xdata is None or event.ydata is None:
            return None
        return np.array([float(event.xdata), float(event.ydata)])

    def handle_at(self, x_px: float, y_px: float) -> str | None:
        """The handle within ``PICK_PX`` of display point (x_px, y_px), if any."""
        if self.image is None:
            return None
        best, best_d = None, PICK_PX
        for name, pt in self._handles.items():
            uv, _ = self.image.to_plane_mm(pt)
            px = self.ax.transData.transform(uv)
            d = float(np.hypot(px[0] - x_px, px[1] - y_px))
            if d <= best_d:
                best, best_d = name, d
        return best

    def lps_for(self, name: str, uv_mm: np.ndarray) -> np.ndarray:
        """LPS of handle ``name`` moved to in-plane ``uv_mm``, keeping its distance off-plane."""
        assert self.image is not None
        _, off = self.image.to_plane_mm(self._handles[name])
        return np.asarray(self.image.to_lps(uv_mm) + float(off) * self.image.normal_lps)

    def _press(self, event: MouseEvent) -> None:
        uv = self._event_uv(event)
        if uv is None or self.image is None:
            return
        if event.button == 3:  # right click places the target; with Shift, the entry
            name = "entry" if event.key == "shift" else "target"
            self.point_moved.emit(name, self.image.to_lps(uv))
            return
        if event.button != 1:
            return
        if self.add_points_mode:
            self.clicked.emit(self.image.to_lps(uv))
            return
        self._drag = self.handle_at(float(event.x), float(event.y))

    def _scroll(self, event: MouseEvent) -> None:
        uv = self._event_uv(event)
        step = float(getattr(event, "step", 0.0) or 0.0)
        if step:
            self.zoom(WHEEL_ZOOM**step, uv)

    def _motion(self, event: MouseEvent) -> None:
        if self._drag is None:
            return
        uv = self._event_uv(event)
        if uv is None:
            return
        artist = self._handle_artists.get(self._drag)
        if artist is not None:
            artist.set_data([uv[0]], [uv[1]])
            self.draw_idle()

    def _release(self, event: MouseEvent) -> None:
        name, self._drag = self._drag, None
        if name is None:
            return
        uv = self._event_uv(event)
        if uv is None:
            return
        self.point_moved.emit(name, self.lps_for(name, uv))
