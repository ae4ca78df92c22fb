"""What the image views' mouse reports do to the document: one place for the slice views, the
panoramic and the cross-section (:class:`~ctdrill.app.gui.map_canvas.MapCanvas` signals).

- a grip drag (:mod:`ctdrill.app.gui.implant_drag`): every move previews the dragged plan
  (``Document.live.drag_to``: its path is computed and the plots follow); the canvas' ghost
  is drawn for the position whose curves came, with them (``curves_changed``: the outline
  and the force plot of one position in one screen update, not a window update per mouse
  move; without curves, the position that has none); the release makes one undo step
  (``Document.live.end_drag``);
- a canal edit (:mod:`ctdrill.app.gui.canal_edit`): a traced point goes to the canal chosen in
  the trace settings (``Document.live.trace_canal``; empty: the canal of the side clicked), with
  the radius set there for a new canal; moving and deleting points; each one undo step;
- a link click: the crosshair (``Document.live.set_crosshair``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ctdrill.app.gui import canal_edit, planning
from ctdrill.app.gui.document import ViewContext
from ctdrill.app.gui.implant_drag import EDIT_NAMES, dragged_plan
from ctdrill.app.gui.map_canvas import MapCanvas
from ctdrill.imaging.plan.types import Plan

if TYPE_CHECKING:
    from ctdrill.app.gui.results import PathView


class PlanEditor:
    """Turns one view's canvas reports into document edits."""

    def __init__(self, ctx: ViewContext) -> None:
        self.ctx = ctx
        self._base: Plan | None = None  # the plan at the drag's press
        self._last: tuple[np.ndarray, Plan] | None = None  # the drag's last point and plan
        self._drag: object = None  # the drag's grip point (one object for a whole drag)
        self._ghost_on: MapCanvas | None = None  # the canvas of the drag under way
        live = ctx.doc.live
        live.curves_changed.connect(self._ghost_of_curves)
        live.path_changed.connect(self._ghost_without_path)

    def connect(self, canvas: MapCanvas) -> None:
        """Route ``canvas``' grip drags, canal edits and link clicks here."""
        canvas.grip_dragged.connect(
            lambda grip, mode, a, b, final: self.grip(canvas, grip, mode, a, b, final)
        )
        canvas.canal_edited.connect(self.canal)
        canvas.linked.connect(self.ctx.doc.live.set_crosshair)
        canvas.placed.connect(self.place)
        canvas.told.connect(self.ctx.doc.edit_refused.emit)

    def _ghost_of_curves(self, view: PathView) -> None:
        """A dragged position's curves came: its ghost, painted with them."""
        if self._ghost_on is not None and self.ctx.doc.live.dragging:
            self._ghost_on.show_ghost_of(view.plan)

    def _ghost_without_path(self, view: PathView | None) -> None:
        """A dragged position has no path (the plots say why): its ghost all the same."""
        live = self.ctx.doc.live
        if view is None and live.error and self._ghost_on is not None and live.plan is not None:
            self._ghost_on.show_ghost_of(live.plan)

    def place(self, name: str, point_lps: np.ndarray) -> None:
        """A right-click placed ``name`` (``entry`` | ``target``) at ``point_lps``: the first
        trajectory's points (both needed), else the current trajectory's handle moved."""
        doc = self.ctx.doc
        if doc.plan is None:
            self._place_draft(name, point_lps)
            if doc.plan is None:
                other = "entry (Shift+right-click)" if name == "target" else "target (right-click)"
                doc.edit_refused.emit(f"{name} placed; now place the {other}")
            return
        try:
            plan = planning.move_handle(doc.plan, name, point_lps)
        except ValueError as exc:
            doc.edit_refused.emit(f"error: {exc}")
            return
        doc.set_plan(plan)

    # ------------------------------------------------------------------ grips
    def grip(
        self,
        canvas: MapCanvas,
        grip: str,
        mode: str,
        start_lps: np.ndarray,
        now_lps: np.ndarray,
        final: bool,
    ) -> None:
        """A grip of the current trajectory dragged from ``start_lps`` to ``now_lps``."""
        doc = self.ctx.doc
        if doc.plan is None:  # the entry or target placed before a plan exists
            if final and grip in ("entry", "target"):
                self._place_draft(grip, now_lps)
            return
        if self._drag is not start_lps:  # a new drag: from the plan as it is now
            self._drag, self._base, self._last = start_lps, doc.plan, None
        base = self._base if self._base is not None else doc.plan
        last = self._last
        if final:
            self._drag, self._base, self._last = None, None, None
            self._ghost_on = None
        try:
            if last is not None and np.array_equal(last[0], now_lps):
                plan = last[1]
            else:
                plan = dragged_plan(base, mode, start_lps, now_lps)
        except ValueError as exc:
            doc.edit_refused.emit(f"error: {exc}")
            if final:
                doc.live.end_drag(None)
                canvas.draw_idle()
            return
        if not final:
            self._last = (np.array(now_lps, dtype=np.float64), plan)
            if doc.live.drag_to(plan):
                self._ghost_on = canvas  # its ghost comes with its curves
            return
        if np.array_equal(np.asarray(start_lps), np.asarray(now_lps)):
            doc.live.end_drag(None)  # pressed and released in place: nothing moved
            return
        name = EDIT_NAMES[mode]
        if base.implant is None:
            name = name.replace("implant", "trajectory")
        if not doc.live.end_drag(plan, edit=name):
            canvas.draw_idle()  # refused: the plan stays as drawn

    def _place_draft(self, name: str, point_lps: np.ndarray) -> None:
        doc = self.ctx.doc
        try:
            placed = planning.place_handle(doc.plan, doc.draft, name, point_lps)
        except ValueError as exc:
            doc.edit_refused.emit(f"error: {exc}")
            return
        if isinstance(placed, dict):
            doc.set_draft_point(name, placed[name])
        else:
            doc.set_plan(placed)

    # ------------------------------------------------------------------ canals
    def midline_x_mm(self) -> float:
        """LPS x of the midline that picks a traced point's side."""
        return canal_edit.midline_x_mm(self.ctx.doc.arch_lps)

    def canal(self, op: str, landmark: int, point: int, point_lps: np.ndarray | None) -> None:
        """A canal edit: ``add`` a traced point, ``move`` or ``delete`` point ``point`` of
        landmark ``landmark``."""
        doc = self.ctx.doc
        plan = doc.plan
        if plan is None:
            doc.edit_refused.emit("place the trajectory before tracing a canal")
            return
        live = doc.live
        try:
            if op == "add" and point_lps is not None:
                name = (
                    live.trace_canal
                    or canal_edit.SIDE_NAMES[canal_edit.side_of(point_lps, self.midline_x_mm())]
                )
                new, landmark, _ = canal_edit.trace(
                    plan, point_lps, name=name, radius_mm=live.trace_radius_mm
                )
            elif op == "move" and point_lps is not None:
                name = plan.landmarks[landmark].name
                new = canal_edit.move_point(plan, landmark, point, point_lps)
            elif op == "delete":
                name = plan.landmarks[landmark].name
                new = canal_edit.delete_point(plan, landmark, point)
            else:
                return
        except (ValueError, IndexError) as exc:
            doc.edit_refused.emit(f"error: {exc}")
            return
        if doc.set_plan(new, edit=canal_edit.edit_name(op, name)):
            self.ctx.status(f"{canal_edit.edit_name(op, name)} (Edit > Undo takes it back)")
