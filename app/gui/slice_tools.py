"""The measuring tools and the arch editor, on one image canvas (a slice view, the panoramic
or the cross-section: :class:`ToolCanvas`).

Distance (mode ``distance``): two left clicks place the ends of a segment on the image; the line
and its length in mm (in LPS: the straight line between the two points in the patient,
:mod:`ctdrill.app.gui.measure`) are drawn while that image is shown; a third click starts a
new one; a right click, Delete or Escape removes it. Angle (mode ``angle``): three clicks, an
arm's end, the vertex, the other arm's end; the angle in degrees is drawn at the vertex.

Arch (mode ``arch``, axial view): a left click adds a point on the current slice (inserted into
the segment it falls on, else appended), dragging a vertex moves it onto the current slice, a
right click on a vertex or Delete over it removes it. The canvas reports each edit as
``arch_edited(op, index, lps)``; the grid turns it into ``Document.set_arch``.
"""

from __future__ import annotations

import contextlib
from typing import Any, Protocol

import numpy as np

from ctdrill.app.gui.measure import CLICKS, measure_label, next_points
from ctdrill.app.gui.slice_nav import ON_PLANE_MM

#: Pick radius for a handle, an arch vertex or segment, display pixels.
PICK_PX = 10.0
MEASURE_COLOUR = "#80ff80"


def remove_artists(artists: list[Any]) -> None:
    """Remove artists that may already be gone (the canvas clears its overlays wholesale)."""
    for artist in artists:
        with contextlib.suppress(NotImplementedError, ValueError):  # already removed
            artist.remove()
    artists.clear()


def label_at(uv: np.ndarray) -> np.ndarray:
    """Where an angle's value is written: outside the angle, a fifth of its shorter arm from
    the vertex ``uv[1]`` (image mm), so it hides neither arm."""
    a, v, b = uv[0], uv[1], uv[2]
    arms = [a - v, b - v]
    lengths = [float(np.linalg.norm(arm)) for arm in arms]
    if min(lengths) == 0.0:
        return np.asarray(v)
    bisector = arms[0] / lengths[0] + arms[1] / lengths[1]
    norm = float(np.linalg.norm(bisector))
    away = -bisector / norm if norm > 1e-9 else np.array([arms[0][1], -arms[0][0]]) / lengths[0]
    return np.asarray(v + 0.2 * min(lengths) * away)


def _segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    d = b - a
    dd = float(d @ d)
    t = 0.0 if dd == 0.0 else float(np.clip((p - a) @ d / dd, 0.0, 1.0))
    return float(np.linalg.norm(p - (a + t * d)))


def insert_index(points_px: np.ndarray, click_px: np.ndarray, pick_px: float) -> int:
    """Where a new arch point goes: after the first vertex of the segment within ``pick_px``
    of the click (the nearest), else at the end."""
    best, best_d = len(points_px), pick_px
    for k in range(len(points_px) - 1):
        d = _segment_distance(click_px, points_px[k], points_px[k + 1])
        if d <= best_d:
            best, best_d = k + 1, d
    return best


class PlaneMapLike(Protocol):
    def to_lps(self, uv_mm: np.ndarray) -> np.ndarray: ...

    def to_uv(self, points_lps: np.ndarray) -> tuple[np.ndarray, np.ndarray]: ...


class ToolCanvas(Protocol):
    """What the tools need of a canvas (:class:`~ctdrill.app.gui.map_canvas.MapCanvas`)."""

    ax: Any
    mode: str
    plane_map: PlaneMapLike | None

    def display_of(self, uv_mm: np.ndarray) -> np.ndarray: ...

    def draw_idle(self) -> None: ...

    def arch_points(self) -> np.ndarray | None: ...

    def emit_arch_edit(self, op: str, index: int, point_lps: np.ndarray | None) -> None: ...


class ToolState:
    """The measurements and the arch editing of one :class:`ToolCanvas`."""

    def __init__(self, canvas: ToolCanvas) -> None:
        self.canvas = canvas
        #: Points of the measurement placed so far, LPS mm.
        self.measure_lps: list[np.ndarray] = []
        #: ``distance`` or ``angle``: what :attr:`measure_lps` measures.
        self.measure_kind = "distance"
        self._rubber: np.ndarray | None = None  # in-plane mm of the cursor while measuring
        self._vertex_drag: int | None = None
        self._hover_px: tuple[float, float] | None = None
        self._artists: list[Any] = []

    # ------------------------------------------------------------------ distance
    @property
    def length_mm(self) -> float | None:
        """Length of the finished distance measurement, mm (None: none)."""
        if self.measure_kind != "distance" or len(self.measure_lps) != 2:
            return None
        return float(np.linalg.norm(self.measure_lps[1] - self.measure_lps[0]))

    @property
    def label(self) -> str | None:
        """The finished measurement's text (``12.34 mm``, ``87.5°``), None before."""
        return measure_label(self.measure_kind, self.measure_lps)

    def clear_measure(self) -> None:
        """Remove the measurement."""
        self.measure_lps = []
        self._rubber = None
        self.draw()
        self.canvas.draw_idle()

    def draw(self) -> None:
        """(Re)draw the measurement when its points lie on the shown image."""
        remove_artists(self._artists)
        pmap, ax = self.canvas.plane_map, self.canvas.ax
        if pmap is None or not self.measure_lps:
            return
        uv, off = pmap.to_uv(np.array(self.measure_lps))
        if np.any(~(np.abs(off) <= ON_PLANE_MM)) or not np.all(np.isfinite(uv)):
            return  # measured on another image
        if len(uv) < CLICKS[self.measure_kind] and self._rubber is not None:
            uv = np.vstack([uv, self._rubber])
        self._artists += ax.plot(uv[:, 0], uv[:, 1], "-o", color=MEASURE_COLOUR, lw=1.5, ms=4)
        label = self.label
        if label is not None:
            at = uv.mean(axis=0) if self.measure_kind == "distance" else label_at(uv)
            self._artists.append(
                ax.text(
                    at[0],
                    at[1],
                    f" {label}",
                    color=MEASURE_COLOUR,
                    fontsize=10,
                    fontweight="bold",
                    zorder=10,
                    ha="center",
                    va="center",
                    bbox={"facecolor": "black", "alpha": 0.5, "lw": 0, "pad": 1},
                )
            )

    # ------------------------------------------------------------------ arch
    def _arch_px(self) -> np.ndarray:
        pmap, arch = self.canvas.plane_map, self.canvas.arch_points()
        if pmap is None or arch is None or len(arch) == 0:
            return np.empty((0, 2))
        uv, _ = pmap.to_uv(np.atleast_2d(arch))
        return self.canvas.display_of(uv).reshape(-1, 2)

    def vertex_at(self, x_px: float, y_px: float) -> int | None:
        """The arch vertex within ``PICK_PX`` of a display point (the nearest), if any."""
        px = self._arch_px()
        if len(px) == 0:
            return None
        d = np.hypot(px[:, 0] - x_px, px[:, 1] - y_px)
        k = int(np.argmin(d))
        return k if d[k] <= PICK_PX else None

    def _arch_here(self) -> bool:
        return self.canvas.mode == "arch" and self.canvas.arch_points() is not None

    # ------------------------------------------------------------------ events
    def press(self, uv: np.ndarray, x_px: float, y_px: float) -> None:
        """Left press in the ``distance``, ``angle`` or ``arch`` mode."""
        pmap = self.canvas.plane_map
        if pmap is None:
            return
        lps = np.asarray(pmap.to_lps(uv), dtype=np.float64)
        if not np.all(np.isfinite(lps)):
            return
        mode = self.canvas.mode
        if mode in CLICKS:
            if mode != self.measure_kind:
                self.measure_kind, self.measure_lps = mode, []
            self.measure_lps = next_points(mode, self.measure_lps, lps)
            self._rubber = None
            self.draw()
            self.canvas.draw_idle()
        elif self._arch_here():
            k = self.vertex_at(x_px, y_px)
            if k is not None:
                self._vertex_drag = k
                return
            index = insert_index(self._arch_px(), np.array([x_px, y_px]), PICK_PX)
            self.canvas.emit_arch_edit("add", index, lps)

    def motion(self, uv: np.ndarray | None) -> bool:
        """Mouse moved; True when a tool took the event."""
        canvas = self.canvas
        placing = 0 < len(self.measure_lps) < CLICKS.get(canvas.mode, 0)
        if canvas.mode == self.measure_kind and placing and uv is not None:
            self._rubber = uv
            self.draw()
            canvas.draw_idle()
            return True
        if self._arch_here() and uv is not None:
            x, y = canvas.display_of(uv)
            self._hover_px = (float(x), float(y))
            if self._vertex_drag is not None:
                remove_artists(self._artists)
                self._artists = canvas.ax.plot([uv[0]], [uv[1]], "s", color="#ff9040", ms=8)
                canvas.draw_idle()
                return True
        return False

    def release(self, uv: np.ndarray | None) -> bool:
        """Left release; True when a tool took the event."""
        k, self._vertex_drag = self._vertex_drag, None
        if k is None:
            return False
        pmap = self.canvas.plane_map
        if uv is not None and pmap is not None:
            self.canvas.emit_arch_edit("move", k, np.asarray(pmap.to_lps(uv)))
        return True

    def right_click(self, x_px: float, y_px: float) -> bool:
        """Right click in a measuring mode (remove it) or the ``arch`` mode (remove a
        vertex); whether it removed something."""
        if self.canvas.mode in CLICKS:
            had = bool(self.measure_lps)
            self.clear_measure()
            return had
        if self._arch_here():
            k = self.vertex_at(x_px, y_px)
            if k is not None:
                self.canvas.emit_arch_edit("delete", k, None)
                return True
        return False

    def delete(self) -> None:
        """Delete/Backspace/Escape: remove the measurement, or the arch vertex under the
        cursor."""
        if self.canvas.mode in CLICKS or self.measure_lps:
            self.clear_measure()
        elif self._arch_here() and self._hover_px is not None:
            k = self.vertex_at(*self._hover_px)
            if k is not None:
                self.canvas.emit_arch_edit("delete", k, None)


def edit_arch(
    points_lps: np.ndarray | None, op: str, index: int, point_lps: np.ndarray | None
) -> np.ndarray:
    """The arch's points after one edit: ``add`` ``point_lps`` before ``index`` (``index`` =
    the count: append), ``move`` vertex ``index`` to ``point_lps``, or ``delete`` it.

    Raises
    ------
    ValueError
        An unknown edit, a vertex that does not exist, or a point on its neighbour (an arch's
        consecutive points are distinct).
    """
    pts = np.empty((0, 3)) if points_lps is None else np.array(points_lps, dtype=np.float64)
    pts = pts.reshape(-1, 3)
    n = len(pts)
    if op == "add" and point_lps is not None and 0 <= index <= n:
        out = np.insert(pts, index, np.asarray(point_lps, dtype=np.float64).reshape(3), axis=0)
    elif op == "move" and point_lps is not None and 0 <= index < n:
        out = pts.copy()
        out[index] = np.asarray(point_lps, dtype=np.float64).reshape(3)
    elif op == "delete" and 0 <= index < n:
        out = np.delete(pts, index, axis=0)
    else:
        raise ValueError(f"arch edit {op!r} at vertex {index} of {n} is not possible")
    if len(out) > 1 and np.any(np.linalg.norm(np.diff(out, axis=0), axis=1) < 1e-6):
        raise ValueError("two consecutive arch points at the same place: place it elsewhere")
    return out
