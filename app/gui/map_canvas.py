"""A matplotlib canvas whose image maps to the patient: the interactions the slice views, the
panoramic and the cross-section share.

The image is drawn in millimetres (``uv``: along its columns and down its rows); a
:class:`~ctdrill.app.gui.map_ghost.PlaneMap` maps ``uv`` to LPS and back (a slice plane, the
panoramic's curved curtain, a cross-section plane). On top of that mapping the canvas offers,
in widget pixels, :meth:`MapCanvas.pixel_to_lps` and :meth:`MapCanvas.lps_to_pixel`, and these
mouse tools (:attr:`MapCanvas.mode`):

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
Mouse moves are coalesced: a grip drag reports only the latest position, once per event-loop
pass (``grip_dragged``; however many moves Qt delivered meanwhile, none is queued), and the
ghost of a dragged plan is computed when the canvas paints
(:mod:`ctdrill.app.gui.map_ghost`: at most once per repaint, for the latest plan).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from matplotlib.backend_bases import MouseEvent
from PySide6.QtCore import Qt, QTimer, Signal

from ctdrill.app.gui.implant_drag import body_hit, drag_mode
from ctdrill.app.gui.map_ghost import GhostCanvas
from ctdrill.app.gui.slice_tools import PICK_PX, ToolState
from ctdrill.imaging.plan.types import Plan

#: A press this close to the implant (or drill) body, beyond its radius, grabs it, mm.
BODY_REACH_MM = 0.5
#: A press that moves less than this before its release is a click, display pixels.
CLICK_PX = 4.0
CROSSHAIR_COLOUR = "#b0ff40"
#: Half length of the crosshair's arms, mm.
CROSSHAIR_MM = 6.0


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


class MapCanvas(GhostCanvas):
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
        # No pick events: matplotlib's default pick on every press and scroll walks every
        # artist (building the axes' ticks), 0.05-0.2 s a click; the views hit-test themselves.
        self.mpl_disconnect(self.button_pick_id)
        self.mpl_disconnect(self.scroll_pick_id)
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
        #: A grip drag's latest move not reported yet (coalescing, :meth:`_report_move`).
        self._move: tuple[Any, ...] | None = None
        self._hover_px: tuple[float, float] | None = None
        self.mpl_connect("button_press_event", self._press)
        self.mpl_connect("motion_notify_event", self._motion)
        self.mpl_connect("button_release_event", self._release)

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
                self._report_latest((grip, mode, start, now))
            else:
                self.show_ghost([], {grip: uv})
        else:
            self.show_ghost([], {"canal": uv})

    def _report_latest(self, move: tuple[Any, ...]) -> None:
        """Keep ``move`` (grip, mode, from, to) as the drag's latest and report it at the next
        event-loop pass: moves that arrive meanwhile replace it (none is queued)."""
        queued = self._move is not None
        self._move = move
        if not queued:
            QTimer.singleShot(0, self._report_move)

    def _report_move(self) -> None:
        move, self._move = self._move, None
        if move is not None and self._drag is not None:
            self.grip_dragged.emit(*move, False)

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
        self._move = None  # the release reports the final position itself
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
