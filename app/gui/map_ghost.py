"""The outline of a dragged trajectory (the **ghost**) over a kept bitmap of a canvas' image
(matplotlib blitting): :class:`GhostCanvas`, the base of
:class:`~ctdrill.app.gui.map_canvas.MapCanvas`.

:meth:`GhostCanvas.show_ghost_of` only records the dragged plan and asks for a paint of the
axes; the paint computes its outline and draws it (:meth:`GhostCanvas.draw_ghost_of`), so the
outline is computed at most once per repaint, for the newest plan, however many moves came.
"""

from __future__ import annotations

import contextlib
from typing import Any, Protocol

import numpy as np
from matplotlib.backends.backend_qtagg import FigureCanvasQTAgg
from matplotlib.lines import Line2D
from PySide6.QtGui import QPaintEvent

from ctdrill.app.gui.implant_drag import grips_lps
from ctdrill.imaging.plan.types import Plan

GHOST_COLOUR = "#ffffff"


class PlaneMap(Protocol):
    """Image millimetres (uv) <-> LPS of one view's image."""

    def to_lps(self, uv_mm: np.ndarray) -> np.ndarray:
        """(..., 2) uv mm -> (..., 3) LPS mm on the image's surface (NaN off it)."""
        ...

    def to_uv(self, points_lps: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(..., 3) LPS -> (..., 2) uv mm and (...) offset from the surface, mm."""
        ...


class GhostCanvas(FigureCanvasQTAgg):
    """A canvas with axes :attr:`ax` mapped to LPS by :attr:`plane_map` that draws a dragged
    plan's outline (:meth:`ghost_lines`, given by subclasses) over its image."""

    ax: Any

    def __init__(self, figure: Any) -> None:
        super().__init__(figure)
        self.plane_map: PlaneMap | None = None
        self._ghost: list[Any] = []
        self._ghost_bg: Any = None
        #: The plan whose ghost the next paint draws (:meth:`show_ghost_of`).
        self._ghost_plan: Plan | None = None
        self.mpl_connect("draw_event", self._drawn)

    def ghost_lines(self, plan: Plan) -> list[np.ndarray]:
        """The outline of ``plan``'s drill and implant on this image, (M, 2) uv mm each."""
        return []

    def show_ghost_of(self, plan: Plan) -> None:
        """Show ``plan`` (a dragged trajectory) as a ghost with its grips: computed and drawn
        by the next paint (a newer plan before it replaces this one)."""
        if self.plane_map is None:
            return
        self._ghost_plan = plan
        if self._ghost_bg is None:
            self._ghost_bg = self.copy_from_bbox(self.ax.bbox)
        self._update_axes()

    def draw_ghost_of(self, plan: Plan) -> None:
        """Compute ``plan``'s ghost and draw it into the canvas' bitmap (the paint shows it)."""
        if self.plane_map is None:
            return
        points = {}
        for name, pt in grips_lps(plan).items():
            uv, _off = self.plane_map.to_uv(np.asarray(pt).reshape(1, 3))
            if np.all(np.isfinite(uv)):
                points[name] = uv[0]
        self._ghost_artists(self.ghost_lines(plan), points)
        self.restore_region(self._ghost_bg)
        for art in self._ghost:
            self.ax.draw_artist(art)

    def paintEvent(self, event: QPaintEvent) -> None:
        """Draw the pending ghost (the latest dragged plan's), then paint."""
        plan, self._ghost_plan = self._ghost_plan, None
        if plan is not None and self._ghost_bg is not None:
            self.draw_ghost_of(plan)
        super().paintEvent(event)

    def show_ghost(self, lines_uv: list[np.ndarray], points_uv: dict[str, np.ndarray]) -> None:
        """Redraw the ghost only: ``lines_uv`` outlines and ``points_uv`` markers, over the
        image as it was at the drag's first move."""
        self._ghost_artists(lines_uv, points_uv)
        self._blit_ghost()

    def _ghost_artists(self, lines_uv: list[np.ndarray], points_uv: dict[str, np.ndarray]) -> None:
        """The ghost's two artists with new data: every outline as one line (NaN between
        them) and every grip as one set of markers; made once per drag, then only their data
        change (one artist update each per repaint)."""
        if self._ghost_bg is None:
            self._ghost_bg = self.copy_from_bbox(self.ax.bbox)
        gap = np.full((1, 2), np.nan)
        pieces = [part for line in lines_uv for part in (np.asarray(line, float), gap)]
        outline = np.concatenate(pieces) if pieces else np.empty((0, 2))
        grips = np.array(list(points_uv.values()), float).reshape(-1, 2)
        if len(self._ghost) != 2:
            self._clear_ghost()
            line = Line2D([], [], color=GHOST_COLOUR, lw=1.4, ls="-", animated=True)
            marks = Line2D([], [], ls="none", marker="o", mfc="none", mec=GHOST_COLOUR, mew=2, ms=9)
            marks.set_animated(True)
            self._ghost = [self.ax.add_line(line), self.ax.add_line(marks)]
        self._ghost[0].set_data(outline[:, 0], outline[:, 1])
        self._ghost[1].set_data(grips[:, 0], grips[:, 1])

    def _blit_ghost(self) -> None:
        """The ghost over the kept bitmap, shown at the next paint (one screen update per
        event-loop pass however many moves arrived)."""
        self.restore_region(self._ghost_bg)
        for art in self._ghost:
            self.ax.draw_artist(art)
        self._update_axes()

    def _update_axes(self) -> None:
        """Ask for a paint of the axes' region."""
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
        self._ghost_plan = None
        self._clear_ghost()
        if self._ghost_bg is not None:
            self._ghost_bg = None
            self.draw_idle()

    def _drawn(self, _event: object) -> None:
        if self._ghost_bg is not None:  # redrawn under a drag: keep the ghost on top
            self._ghost_bg = self.copy_from_bbox(self.ax.bbox)
            for art in self._ghost:
                self.ax.draw_artist(art)
