"""A matplotlib canvas whose image maps to the patient: the interactions the slice views, the
panoramic and the cross-section share.

The image is drawn in millimetres (``uv``: along its columns and down its rows); a
:class:`PlaneMap` maps ``uv`` to LPS and back (a slice plane, the panoramic's curved curtain, a
cross-section plane). On top of that mapping the canvas offers, in widget pixels,
:meth:`MapCanvas.pixel_to_lps` and :meth:`MapCanvas.lps_to_pixel`, and these mouse tools
(:attr:`MapCanvas.mode`):

- ``navigate``: a press on a grip of the current trajectory (entry, target, platform, or the
  body) starts a drag (``grip_dragged`` on every move and at the release; Shift and Ctrl
  choose the kind of drag, :mod:`ctdrill.app.gui.implant_drag`); a click elsewhere links the
  views there (``linked``);
- ``canal``: a click traces a canal point (``canal_edited("add", ...)``), a press on a traced
  point drags it (``"move"``), a right click or Delete on it removes it (``"delete"``);
- ``distance`` and ``angle`` (:mod:`ctdrill.app.gui.slice_tools`), and ``arch`` on the axial
  slice view.

While something is dragged only its outline (the **ghost**) is redrawn, over a bitmap of the
image kept at the press (matplotlib blitting): a move costs a few milliseconds, not a redraw.
"""

from __future__ import annotations

import contextlib
from typing import Any, Protocol

import numpy as np
from matplotlib.backend_bases import MouseEvent
from matplotlib.backends.backend_qtagg import FigureCanvasQTAgg
from matplotlib.lines import Line2D
from PySide6.QtCore import Qt, Signal

from ctdrill.app.gui.implant_drag import body_hit, drag_mode, grips_lps
from ctdrill.app.gui.slice_tools import PICK_PX, ToolState
from ctdrill.imaging.plan.types import Plan

#: A press this close to the implant (or drill) body, beyond its radius, grabs it, mm.
BODY_REACH_MM = 0.5
#: A press that moves less than this before its release is a click, display pixels.
CLICK_PX = 4.0
GHOST_COLOUR = "#ffffff"
CROSSHAIR_COLOUR = "#b0ff40"
#: Half length of the crosshair's arms, mm.
CROSSHAIR_MM = 6.0


class PlaneMap(Protocol):
    """Image millimetres (uv) <-> LPS of one view's image."""

    def to_lps(self, uv_mm: np.ndarray) -> np.ndarray:
        """(..., 2) uv mm -> (..., 3) LPS mm on the image's surface (NaN off it)."""
        ...

    def to_uv(self, points_lps: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(..., 3) LPS -> (..., 2) uv mm and (...) offset from the surface, mm."""
        ...


def modifiers(event: MouseEvent) -> tuple[bool, bool]:
    """(shift, ctrl) held during a mouse event, read from the Qt event itself."""
    gui = getattr(event, "guiEvent", None)
    if gui is not None and hasattr(gui, "modifiers"):
        mods = gui.modifiers()
        return (
            bool(mods & Qt.KeyboardModifier.ShiftModifier),
            bool(mods & Qt.KeyboardModifier.ControlModifier),
        )
    keys = getattr(event, "modifiers", None) or ()
    return "shift" in keys, "ctrl" in keys


class MapCanvas(FigureCanvasQTAgg):
    """A canvas with an image in uv mm mapped to LPS (``plane_map``) and the shared tools.

    Subclasses create :attr:`ax`, set :attr:`plane_map` when an image is shown, fill
    :attr:`grips`, :attr:`grip_plan` and :attr:`canals` when they draw the plan, and give
    :meth:`ghost_lines` (the outline of a dragged plan on their image).
    """

    grip_dragged = Signal(str, str, object, object, bool)  # grip, mode, from, to (LPS), final
    canal_edited = Signal(str, int, int, object)  # op, landmark, point, LPS (None: delete)
    linked = Signal(object)  # (3,) LPS clicked: move the other views there
    cursor_moved = Signal(object)  # (3,) LPS under the cursor, or None
    placed = Signal(str, object)  # "entry" | "target", (3,) LPS: a right-click placed it
    told = Signal(str)  # why a right-click did nothing (for the status bar)

    ax: Any

    def __init__(self, figure: Any) -> None:
        super().__init__(figure)
        self.plane_map: PlaneMap | None = None
        #: ``navigate``, ``canal``, ``distance``, ``angle`` or ``arch``.
        self.mode = "navigate"
        #: Report drags on every move (True) or only at the release (the older behaviour).
        self.live_drag = True
        #: Offset from the image's surface within which points are on it (picking), mm.
        self.on_plane_mm = 2.0
        #: The current trajectory's point grips (LPS) and the trajectory itself (the body).
        self.grips: dict[str, np.ndarray] = {}
        self.grip_plan: Plan | None = None
        #: Traced canals: (landmark index, (N, 3) LPS points).
        self.canals: list[tuple[int, np.ndarray]] = []
        self.crosshair_lps: np.ndarray | None = None
        self.tools = ToolState(self)
        self._drag: tuple[Any, ...] | None = (
            None  # ("grip", name, mode, lps0, uv0) | ("canal", ...)
        )
        self._click: tuple[float, float, np.ndarray] | None = None
        self._ghost: list[Any] = []
        self._ghost_bg: Any = None
        self._hover_px: tuple[float, float] | None = None
        self.mpl_connect("button_press_event", self._press)
        self.mpl_connect("motion_notify_event", self._motion)
        self.mpl_connect("button_release_event", self._release)
        self.mpl_connect("draw_event", self._drawn)

    # ------------------------------------------------------------------ mapping
    def display_of(self, uv_mm: np.ndarray) -> np.ndarray:
        """Display (matplotlib) pixel position of uv mm."""
        return np.asarray(self.ax.transData.transform(np.asarray(uv_mm, dtype=np.float64)))

    def uv_of_display(self, x_px: float, y_px: float) -> np.ndarray:
        """uv mm at a display (matplotlib) pixel."""
        return np.asarray(self.ax.transData.inverted().transform((x_px, y_px)), dtype=np.float64)

    def pixel_to_lps(self, x: float, y: float) -> np.ndarray | None:
        """(3,) LPS mm at widget pixel ``(x, y)`` (Qt: from the top left), or None off the
        image."""
        if self.plane_map is None:
            return None
        ratio = self.devicePixelRatioF()
        xd, yd = float(x) * ratio, (self.height() - float(y)) * ratio
        if not self.ax.bbox.contains(xd, yd):
            return None
        lps = np.asarray(self.plane_map.to_lps(self.uv_of_display(xd, yd)), dtype=np.float64)
        return lps if np.all(np.isfinite(lps)) else None

    def lps_to_pixel(self, lps: np.ndarray) -> tuple[float, float] | None:
        """Widget pixel ``(x, y)`` where LPS point ``lps`` is drawn, or None when it does not
        fall on the image (off its surface by more than :attr:`on_plane_mm`, or outside the
        axes)."""
        if self.plane_map is None:
            return None
        uv, off = self.plane_map.to_uv(np.asarray(lps, dtype=np.float64).reshape(1, 3))
        if not (np.all(np.isfinite(uv)) and abs(float(off[0])) <= self.on_plane_mm):
            return None
        xd, yd = self.display_of(uv[0])
        if not self.ax.bbox.contains(xd, yd):
            return None
        ratio = self.devicePixelRatioF()
        return float(xd / ratio), float(self.height() - yd / ratio)

    def _event_uv(self, event: MouseEvent) -> np.ndarray | None:
        if event.inaxes is not self.ax or event.xdata is None or event.ydata is None:
            return None
        return np.array([float(event.xdata), float(event.ydata)])

    def _lps(self, uv: np.ndarray) -> np.ndarray | None:
        if self.plane_map is None:
            return None
        lps = np.asarray(self.plane_map.to_lps(uv), dtype=np.float64)
        return lps if np.all(np.isfinite(lps)) else None

    # ------------------------------------------------------------------ picking
    def grip_at(self, x_px: float, y_px: float) -> str | None:
        """The grip under a display point: a point grip within :data:`PICK_PX`, else the
        body; None."""
        if self.plane_map is None:
            return None
        best, best_d = None, PICK_PX
        for name, pt in self.grips.items():
            uv, _off = self.plane_map.to_uv(np.asarray(pt, dtype=np.float64).reshape(1, 3))
            if not np.all(np.isfinite(uv)):
                continue
            px = self.display_of(uv[0])
            d = float(np.hypot(px[0] - x_px, px[1] - y_px))
            if d <= best_d:
                best, best_d = name, d
        if best is None and self.grip_plan is not None:
            lps = self._lps(self.uv_of_display(x_px, y_px))
            if lps is not None and body_hit(self.grip_plan, lps, reach_mm=BODY_REACH_MM):
                best = "body"
        return best

    def canal_point_at(self, x_px: float, y_px: float) -> tuple[int, int] | None:
        """(landmark, point) of the traced canal point under a display point, if any."""
        if self.plane_map is None:
            return None
        best, best_d = None, PICK_PX
        for landmark, points in self.canals:
            uv, off = self.plane_map.to_uv(points)
            px = self.display_of(np.nan_to_num(uv, nan=1e12)).reshape(-1, 2)
            d = np.hypot(px[:, 0] - x_px, px[:, 1] - y_px)
            d[~(np.abs(off) <= self.on_plane_mm) | ~np.all(np.isfinite(uv), axis=1)] = np.inf
            k = int(np.argmin(d)) if len(d) else -1
            if k >= 0 and float(d[k]) <= best_d:
                best, best_d = (landmark, k), float(d[k])
        return best

    # ------------------------------------------------------------------ mouse
    def _press(self, event: MouseEvent) -> None:
        uv = self._event_uv(event)
        if uv is None or self.plane_map is None:
            return
        if event.button == 3:
            self.right_press(event, uv)
            return
        if event.button != 1:
            return
        x, y = float(event.x), float(event.y)
        lps = self._lps(uv)
        if self.mode == "canal":
            hit = self.canal_point_at(x, y)
            if hit is not None:
                self._drag = ("canal", *hit)
            elif lps is not None:
                self.canal_edited.emit("add", -1, -1, lps)
        elif self.mode in ("distance", "angle", "arch"):
            self.tools.press(uv, x, y)
        else:
            grip = self.grip_at(x, y)
            if grip is not None:
                shift, ctrl = modifiers(event)
                start = self.grips.get(grip, lps)
                if start is not None:
                    mode = drag_mode(grip, shift=shift, ctrl=ctrl)
                    self._drag = ("grip", grip, mode, start, uv)
                    if self.live_drag:  # the drag starts: the plan as it is, previewed
                        self.grip_dragged.emit(grip, mode, start, start, False)
            elif lps is not None:
                self._click = (x, y, lps)

    def _motion(self, event: MouseEvent) -> None:
        uv = self._event_uv(event)
        if self.motion_hook(event, uv):
            return
        if uv is not None:
            self._hover_px = (float(event.x), float(event.y))
            lps = self._lps(uv)
            if lps is not None:
                self.cursor_moved.emit(lps)
        if self.tools.motion(uv):
            return
        if (
            self._click is not None
            and np.hypot(float(event.x) - self._click[0], float(event.y) - self._click[1])
            > CLICK_PX
        ):
            self._click = None
        if self._drag is None or uv is None:
            return
        if self._drag[0] == "grip":
            _, grip, mode, start, uv0 = self._drag
            now = self._dragged_to(start, uv0, uv)
            if now is None:
                return
            if self.live_drag:
                self.grip_dragged.emit(grip, mode, start, now, False)
            else:
                self.show_ghost([], {grip: uv})
        else:
            self.show_ghost([], {"canal": uv})

    def _dragged_to(self, start: np.ndarray, uv0: np.ndarray, uv: np.ndarray) -> np.ndarray | None:
        """Where a grip taken at ``start`` (LPS) under ``uv0`` is, with the mouse at ``uv``:
        moved by the image's own displacement (a grip off the plane keeps its offset)."""
        a, b = self._lps(uv0), self._lps(uv)
        if a is None or b is None:
            return None
        return np.asarray(start, dtype=np.float64) + (b - a)

    def _release(self, event: MouseEvent) -> None:
        uv = self._event_uv(event)
        if event.button == 3:
            self.right_release(event, uv)
            return
        if self.tools.release(uv):
            return
        drag, self._drag = self._drag, None
        click, self._click = self._click, None
        if drag is not None:
            if drag[0] == "grip":
                _, grip, mode, start, uv0 = drag
                now = None if uv is None else self._dragged_to(start, uv0, uv)
                self.end_ghost()
                self.grip_dragged.emit(grip, mode, start, start if now is None else now, True)
            else:
                self.end_ghost()
                lps = None if uv is None else self._lps(uv)
                if lps is not None:
                    self.canal_edited.emit("move", drag[1], drag[2], lps)
            return
        if click is not None:
            self.linked.emit(click[2])

    # hooks for the subclasses (the slice views' window/level drag and right-click placing)
    def right_press(self, event: MouseEvent, uv: np.ndarray) -> None:
        """A right press on the image (the slice views start a window/level drag)."""

    def right_release(self, event: MouseEvent, uv: np.ndarray | None) -> None:
        """A right release acts or says why not (:attr:`told`): in navigation it places the
        target (Shift: the entry, :attr:`placed`); in a tool it removes the canal point, the
        measurement or the arch vertex under it."""
        if uv is None:
            self.told.emit("right-click on the image: nothing to act on outside it")
            return
        x, y = float(event.x), float(event.y)
        if self.mode == "canal":
            hit = self.canal_point_at(x, y)
            if hit is not None:
                self.canal_edited.emit("delete", hit[0], hit[1], None)
            else:
                self.told.emit("right-click removes a traced canal point: none under the cursor")
        elif self.mode in ("distance", "angle", "arch"):
            if not self.tools.right_click(x, y):
                self.told.emit(
                    "right-click removes the measurement or the arch point under the cursor: "
                    "none there"
                )
        elif self.mode == "navigate":
            lps = self._lps(uv)
            if lps is None:
                self.told.emit("right-click: no CT position under the cursor")
                return
            shift, _ctrl = modifiers(event)
            self.placed.emit("entry" if shift else "target", lps)
        else:
            self.told.emit(f"right-click does nothing in the {self.mode!r} tool")

    def motion_hook(self, event: MouseEvent, uv: np.ndarray | None) -> bool:
        """A move the subclass takes first (True: nothing else sees it)."""
        return False

    def delete_under_cursor(self) -> None:
        """Delete / Backspace / Escape: the canal point under the cursor, else the tools'."""
        if self.mode == "canal" and self._hover_px is not None:
            hit = self.canal_point_at(*self._hover_px)
            if hit is not None:
                self.canal_edited.emit("delete", hit[0], hit[1], None)
                return
        self.tools.delete()

    # ------------------------------------------------------------------ ghost (blitting)
    def ghost_lines(self, plan: Plan) -> list[np.ndarray]:
        """The outline of ``plan``'s drill and implant on this image, (M, 2) uv mm each."""
        return []

    def show_ghost_of(self, plan: Plan) -> None:
        """Draw ``plan`` (a dragged trajectory) as a ghost with its grips."""
        if self.plane_map is None:
            return
        points = {}
        for name, pt in grips_lps(plan).items():
            uv, _off = self.plane_map.to_uv(np.asarray(pt).reshape(1, 3))
            if np.all(np.isfinite(uv)):
                points[name] = uv[0]
        self.show_ghost(self.ghost_lines(plan), points)

    def show_ghost(self, lines_uv: list[np.ndarray], points_uv: dict[str, np.ndarray]) -> None:
        """Redraw the ghost only: ``lines_uv`` outlines and ``points_uv`` markers, over the
        image as it was at the drag's first move."""
        if self._ghost_bg is None:
            self._ghost_bg = self.copy_from_bbox(self.ax.bbox)
        self._clear_ghost()
        for line in lines_uv:
            art = Line2D(line[:, 0], line[:, 1], color=GHOST_COLOUR, lw=1.4, ls="-", animated=True)
            self._ghost.append(self.ax.add_line(art))
        for uv in points_uv.values():
            art = Line2D([uv[0]], [uv[1]], marker="o", mfc="none", mec=GHOST_COLOUR, mew=2, ms=9)
            art.set_animated(True)
            self._ghost.append(self.ax.add_line(art))
        self._blit_ghost()

    def _blit_ghost(self) -> None:
        """The ghost over the kept bitmap, shown at the next paint (one screen update per
        event-loop pass however many moves arrived)."""
        self.restore_region(self._ghost_bg)
        for art in self._ghost:
            self.ax.draw_artist(art)
        ratio = self.devicePixelRatioF()
        x0, y0, x1, y1 = self.ax.bbox.extents / ratio
        top = self.height() - y1
        self.update(int(x0) - 1, int(top) - 1, int(x1 - x0) + 3, int(y1 - y0) + 3)

    def _clear_ghost(self) -> None:
        for art in self._ghost:
            with contextlib.suppress(ValueError, NotImplementedError):
                art.remove()
        self._ghost = []

    def end_ghost(self) -> None:
        """Remove the ghost (the next redraw shows the plan as it is)."""
        self._clear_ghost()
        if self._ghost_bg is not None:
            self._ghost_bg = None
            self.draw_idle()

    def _drawn(self, _event: object) -> None:
        if self._ghost_bg is not None:  # redrawn under a drag: keep the ghost on top
            self._ghost_bg = self.copy_from_bbox(self.ax.bbox)
            for art in self._ghost:
                self.ax.draw_artist(art)

    # ------------------------------------------------------------------ crosshair
    def draw_crosshair(self) -> None:
        """Draw the link point (a cross) where it lies on this image."""
        if self.crosshair_lps is None or self.plane_map is None:
            return
        uv, off = self.plane_map.to_uv(self.crosshair_lps.reshape(1, 3))
        if not (np.all(np.isfinite(uv)) and abs(float(off[0])) <= self.on_plane_mm):
            return
        u, v = float(uv[0, 0]), float(uv[0, 1])
        style = {"color": CROSSHAIR_COLOUR, "lw": 1.0, "zorder": 12}
        self.ax.plot([u - CROSSHAIR_MM, u + CROSSHAIR_MM], [v, v], **style)
        self.ax.plot([u, u], [v - CROSSHAIR_MM, v + CROSSHAIR_MM], **style)
