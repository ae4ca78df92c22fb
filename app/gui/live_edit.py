"""The document's live part: a trajectory being dragged, and the point the views are linked at.

A drag is a **preview**, not an edit: while the mouse moves, :meth:`LiveEdit.drag_to` hands the
plan under the mouse to whoever computes (the controller plans its path at once, latest wins)
and whoever draws fast (the dragged view's outline, the depth plots, the banner, the
cross-section's readouts); the heavy views (3D, the other slices, contours) wait for the
release. :meth:`LiveEdit.end_drag` then makes the one undo step, with the path already
computed for it when there is one.

The **crosshair** links the views: a click on one view's image puts the others through that
point (:meth:`LiveEdit.set_crosshair`). The **trace settings** say which canal a traced point
goes to (empty: the canal of the side clicked) and a new canal's radius; the trace toolbars
share them.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Protocol

import numpy as np
from PySide6.QtCore import QObject, Signal

from ctdrill.imaging.plan.landmarks import DEFAULT_CANAL_RADIUS_MM
from ctdrill.imaging.plan.types import Plan

#: Plans of a drag remembered (a result older than these is dropped).
TRAIL = 64

if TYPE_CHECKING:
    from ctdrill.app.gui.results import PathView


class EditedDocument(Protocol):
    """What the live edit uses of its owner (:class:`~ctdrill.app.gui.document.Document`, a
    QObject that is its parent)."""

    @property
    def plan(self) -> Plan | None: ...

    @property
    def rehearsing(self) -> bool: ...

    @property
    def edit_refused(self) -> Any: ...

    def set_plan(self, plan: Plan | None, *, edit: str | None = None) -> bool: ...

    def set_path(self, view: PathView) -> None: ...


class LiveEdit(QObject):
    """Drag preview and crosshair of a :class:`~ctdrill.app.gui.document.Document`.

    Signals
    -------
    plan_dragged(plan) : the current trajectory is being dragged to ``plan``; None when the
        drag ended (after the edit, if any, is in the document).
    path_changed(view) : the path result of the dragged plan (``path``).
    curves_changed(view) : the curves to plot of a dragged plan (``curves``): a path result
        whose checks may still be computing (they follow with ``path_changed``).
    crosshair_changed(point) : the views are linked at a (3,) LPS point, or None.
    trace_changed() : the trace settings changed.
    readout_changed(readout) : the current (or dragged) implant's readout
        (:class:`~ctdrill.app.gui.readouts.ImplantReadout`).
    """

    plan_dragged = Signal(object)
    path_changed = Signal(object)
    curves_changed = Signal(object)
    crosshair_changed = Signal(object)
    trace_changed = Signal()
    readout_changed = Signal(object)

    def __init__(self, doc: EditedDocument) -> None:
        super().__init__(doc if isinstance(doc, QObject) else None)
        self.doc = doc
        #: The plan the current trajectory is being dragged to (None: no drag).
        self.plan: Plan | None = None
        #: The latest path computed during the drag (the plan under the mouse's, or one a
        #: little behind it while the mouse outpaces the computation); or why there is none.
        self.path: PathView | None = None
        #: The newest curves computed during the drag (``path``'s, or a newer plan's whose
        #: checks are still computing).
        self.curves: PathView | None = None
        self.error = ""
        #: This drag's plans, oldest first (a result for one of them is shown if newer than
        #: the one shown).
        self._trail: list[Plan] = []
        #: Where the views are linked, LPS mm (None: nowhere).
        self.crosshair_lps: np.ndarray | None = None
        #: The canal traced points go to ("": the canal of the side clicked), and the
        #: radius a new canal gets, mm.
        self.trace_canal = ""
        self.trace_radius_mm = DEFAULT_CANAL_RADIUS_MM
        #: The latest readout shown and the plan it is for.
        self.readout: object = None
        self._readout_for: Plan | None = None

    @property
    def dragging(self) -> bool:
        """A drag is under way."""
        return self.plan is not None

    def drag_to(self, plan: Plan) -> bool:
        """The current trajectory is being dragged to ``plan``. Refused (False) while a
        rehearsal runs or without a current trajectory."""
        doc = self.doc
        if doc.plan is None:
            return False
        if doc.rehearsing:
            doc.edit_refused.emit("the plan is locked while a rehearsal runs")
            return False
        self.plan = plan
        self._trail = [*self._trail[-(TRAIL - 1) :], plan]
        self.plan_dragged.emit(plan)
        return True

    def _rank(self, plan: Plan | None) -> int:
        return next((i for i, p in enumerate(self._trail) if p is plan), -1)

    def offer(self, view: PathView) -> bool:
        """A path result arrived: True when it is for a plan of this drag (kept and announced
        when newer than the one shown; an older one is dropped)."""
        rank = self._rank(view.plan)
        if self.plan is None or rank < 0:
            return False
        shown = -1 if self.path is None else self._rank(self.path.plan)
        if rank > shown:
            self.path, self.error = view, ""
            self.offer_curves(view)
            self.path_changed.emit(view)
        return True

    def offer_curves(self, view: PathView) -> None:
        """Curves computed for a plan of this drag: kept and announced (``curves_changed``)
        when for a newer plan than those shown."""
        rank = self._rank(view.plan)
        if self.plan is None or rank < 0:
            return
        if rank > (-1 if self.curves is None else self._rank(self.curves.plan)):
            self.curves = view
            self.curves_changed.emit(view)

    def fail(self, plan: Plan, message: str) -> None:
        """No path for the dragged ``plan``: ``path_changed(None)`` with ``error`` saying why."""
        if plan is self.plan:
            self.path, self.curves, self.error = None, None, message
            self.path_changed.emit(None)

    def end_drag(self, plan: Plan | None, *, edit: str = "") -> bool:
        """End the drag: ``plan`` becomes the current trajectory as one undo step named
        ``edit``, its path shown at once when computed during the drag; None cancels (the
        trajectory stays). Returns True when the edit was made."""
        live = self.path
        self.plan, self.path, self.curves, self.error = None, None, None, ""
        self._trail = []
        done = plan is not None and self.doc.set_plan(plan, edit=edit or None)
        if done and live is not None and live.plan is plan:
            self.doc.set_path(live)  # computed while dragging: not computed again
        self.plan_dragged.emit(None)
        return done

    def set_readout(self, plan: Plan, readout: object) -> None:
        """The readout of ``plan`` arrived: shown when ``plan`` is the current trajectory
        (no drag) or a plan of the drag newer than the one shown."""
        if self.plan is None:
            ok = plan is self.doc.plan
        else:
            ok = self._rank(plan) > self._rank(self._readout_for)
        if ok:
            self.readout, self._readout_for = readout, plan
            self.readout_changed.emit(readout)

    def set_crosshair(self, point_lps: np.ndarray | None) -> None:
        """Link the views at ``point_lps`` (3,) LPS mm (None: no crosshair)."""
        self.crosshair_lps = (
            None if point_lps is None else np.asarray(point_lps, dtype=np.float64).reshape(3)
        )
        self.crosshair_changed.emit(self.crosshair_lps)

    def set_trace(self, canal: str | None = None, radius_mm: float | None = None) -> None:
        """Change the trace settings (None: keep)."""
        if canal is not None:
            self.trace_canal = canal
        if radius_mm is not None:
            self.trace_radius_mm = float(radius_mm)
        self.trace_changed.emit()
