"""The slice views' tools, on one canvas: the distance tool and the arch editor.

Distance (mode ``distance``): two left clicks place the ends of a segment on the plane; the line
and its length in mm (exact in LPS: both ends lie on the plane) are drawn while that plane is
shown; a third click starts a new one; a right click, Delete or Escape removes it.

Arch (mode ``arch``, axial view): a left click adds a point on the current slice (inserted into
the segment it falls on, else appended), dragging a vertex moves it onto the current slice, a
right click on a vertex or Delete over it removes it. The canvas reports each edit as
``arch_edited(op, index, lps)``; the grid turns it into ``Document.set_arch``.
"""

from __future__ import annotations

import contextlib
from typing import Any, Protocol

import numpy as np

from ctdrill.app.gui.sections import in_plane_distance_mm
from ctdrill.app.gui.slice_nav import ON_PLANE_MM
from ctdrill.app.gui.slice_scene import OverlayScene
from ctdrill.app.gui.slices import SliceImage

#: Pick radius for a handle, an arch vertex or segment, display pixels.
PICK_PX = 10.0
MEASURE_COLOUR = "#80ff80"


def remove_artists(artists: list[Any]) -> None:
    """Remove artists that may already be gone (the canvas clears its overlays wholesale)."""
    for artist in artists:
        with contextlib.suppress(NotImplementedError, ValueError):  # already removed
            artist.remove()
    artists.clear()


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


class ToolCanvas(Protocol):
    """What the tools use of their canvas (:class:`ctdrill.app.gui.slice_view.SliceCanvas`,
    which holds a :class:`ToolState`)."""

    @property
    def image(self) -> SliceImage | None: ...

    @property
    def ax(self) -> Any: ...

    @property
    def scene(self) -> OverlayScene: ...

    @property
    def mode(self) -> str: ...

    @property
    def view(self) -> str: ...

    @property
    def arch_edited(self) -> Any: ...

    def display_of(self, uv_mm: np.ndarray) -> np.ndarray: ...

    def draw_idle(self) -> None: ...


class ToolState:
    """The distance measurement and the arch editing of one canvas."""

    def __init__(self, canvas: ToolCanvas) -> None:
        self.canvas = canvas
        #: Ends of the measurement placed so far (0, 1 or 2), LPS mm.
        self.measure_lps: list[np.ndarray] = []
        self._rubber: np.ndarray | None = None  # in-plane mm of the cursor while measuring
        self._vertex_drag: int | None = None
        self._hover_px: tuple[float, float] | None = None
        self._artists: list[Any] = []

    # ------------------------------------------------------------------ distance
    @property
    def length_mm(self) -> float | None:
        """Length of the finished measurement, mm (None: none)."""
        if len(self.measure_lps) != 2:
            return None
        return in_plane_distance_mm(self.measure_lps[0], self.measure_lps[1])

    def clear_measure(self) -> None:
        """Remove the measurement."""
        self.measure_lps = []
        self._rubber = None
        self.draw()
        self.canvas.draw_idle()

    def draw(self) -> None:
        """(Re)draw the measurement when its ends lie on the shown plane."""
        remove_artists(self._artists)
        img, ax = self.canvas.image, self.canvas.ax
        if img is None or not self.measure_lps:
            return
        uv, off = img.to_plane_mm(np.array(self.measure_lps))
        if np.any(np.abs(off) > ON_PLANE_MM):
            return  # measured on another plane
        if len(uv) == 1 and self._rubber is not None:
            uv = np.vstack([uv, self._rubber])
        self._artists += ax.plot(uv[:, 0], uv[:, 1], "-o", color=MEASURE_COLOUR, lw=1.5, ms=4)
        length = self.length_mm
        if length is not None:
            mid = uv.mean(axis=0)
            self._artists.append(
                ax.text(
                    mid[0],
                    mid[1],
                    f" {length:.2f} mm",
                    color=MEASURE_COLOUR,
                    fontsize=10,
                    fontweight="bold",
                    zorder=10,
                )
            )

    # ------------------------------------------------------------------ arch
    def _arch_px(self) -> np.ndarray:
        img, arch = self.canvas.image, self.canvas.scene.arch_lps
        if img is None or arch is None or len(arch) == 0:
            return np.empty((0, 2))
        uv, _ = img.to_plane_mm(np.atleast_2d(arch))
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
        return self.canvas.mode == "arch" and self.canvas.view == "axial"

    # ------------------------------------------------------------------ events
    def press(self, uv: np.ndarray, x_px: float, y_px: float) -> None:
        """Left press in the ``distance`` or ``arch`` mode."""
        img = self.canvas.image
        if img is None:
            return
        lps = img.to_lps(uv)
        if self.canvas.mode == "distance":
            self.measure_lps = [lps] if len(self.measure_lps) != 1 else [*self.measure_lps, lps]
            self._rubber = None
            self.draw()
            self.canvas.draw_idle()
        elif self._arch_here():
            k = self.vertex_at(x_px, y_px)
            if k is not None:
                self._vertex_drag = k
                return
            index = insert_index(self._arch_px(), np.array([x_px, y_px]), PICK_PX)
            self.canvas.arch_edited.emit("add", index, lps)

    def motion(self, uv: np.ndarray | None) -> bool:
        """Mouse moved; True when a tool took the event."""
        canvas = self.canvas
        if canvas.mode == "distance" and len(self.measure_lps) == 1 and uv is not None:
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
        img = self.canvas.image
        if uv is not None and img is not None:
            self.canvas.arch_edited.emit("move", k, img.to_lps(uv))
        return True

    def right_click(self, x_px: float, y_px: float) -> None:
        """Right click in the ``distance`` (remove it) or ``arch`` mode (remove a vertex)."""
        if self.canvas.mode == "distance":
            self.clear_measure()
        elif self._arch_here():
            k = self.vertex_at(x_px, y_px)
            if k is not None:
                self.canvas.arch_edited.emit("delete", k, None)

    def delete(self) -> None:
        """Delete/Backspace/Escape: remove the measurement, or the arch vertex under the
        cursor."""
        if self.canvas.mode == "distance" or self.measure_lps:
            self.clear_measure()
        elif self._arch_here() and self._hover_px is not None:
            k = self.vertex_at(*self._hover_px)
            if k is not None:
                self.canvas.arch_edited.emit("delete", k, None)


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
