"""The slice views' edits: the mouse mode of every view, a handle placed (a grip dragged or
a right click), an arch point added, moved or deleted, turned into document edits
(:class:`~ctdrill.app.gui.slice_grid.SliceGrid`'s part that edits)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from ctdrill.app.gui import planning
from ctdrill.app.gui.document import ViewContext
from ctdrill.app.gui.slice_tools import edit_arch


class SliceEdits:
    """Mixed into the grid: its ``ctx``, ``canvases``, ``toolbar``, ``arch_draft`` and
    ``draw_overlays``."""

    ctx: ViewContext
    canvases: dict[str, Any]
    toolbar: Any
    arch_draft: np.ndarray | None
    draw_overlays: Callable[..., None]

    def set_mode(self, mode: str) -> None:
        """``navigate``, ``canal``, ``distance``, ``angle`` or ``arch`` on every canvas."""
        for canvas in self.canvases.values():
            canvas.mode = mode
        self.toolbar.show_mode(mode)

    def set_canal_mode(self, on: bool) -> None:
        """Left clicks append canal points (True) or drag handles."""
        self.set_mode("canal" if on else "navigate")

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

    def _arch_edit(self, op: str, index: int, point_lps: np.ndarray | None) -> None:
        doc = self.ctx.doc
        current = self.arch_draft if self.arch_draft is not None else doc.arch_lps
        try:
            points = edit_arch(current, op, index, point_lps)
        except ValueError as exc:
            doc.edit_refused.emit(f"error: {exc}")
            return
        if len(points) >= 2:
            self.arch_draft = None
            doc.set_arch(points)
        else:  # one point (or none): held here until a second one makes an arch
            self.arch_draft = points if len(points) else None
            if doc.arch_lps is not None:
                doc.set_arch(None)
            self.draw_overlays()
