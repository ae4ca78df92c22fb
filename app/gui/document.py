"""The window's document: the one observable object every view draws from.

The CT volume (with its bone surface), the plan, the path computed for the plan and the
rehearsal state live here and nowhere else. A view subscribes to the signals it needs and
changes the document only through its methods (napari's model/view split); the computing
happens in headless functions (:mod:`ctdrill.app.gui.compute`,
:mod:`ctdrill.app.gui.results`) run by :class:`ctdrill.app.gui.controller.Controller`.

A suggestion (``ctdrill suggest`` run on the document's plan, :mod:`ctdrill.app.search`) is
kept with the plan it was computed for: adopting one of its candidates replaces the plan's
axis and keeps the suggestion (marked adopted); any other plan edit or a new series drops it.

The plan is locked while a rehearsal runs: the device holds the force table of the plan it was
armed with, so an edit then would make the views show a stop the device does not enforce.
:meth:`Document.set_plan` refuses it and emits ``edit_refused`` with the reason.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from PySide6.QtCore import QObject, Signal

from ctdrill.app.gui.results import PathView
from ctdrill.app.gui.workers import StepQueue
from ctdrill.app.search.candidates import SearchSpace
from ctdrill.app.search.suggest import Suggestion
from ctdrill.imaging import CTVolume
from ctdrill.imaging.plan.types import Plan
from ctdrill.model.band import HuUncertainty

#: What ``edit_refused`` says while a rehearsal runs.
LOCKED_MESSAGE = "the plan is locked while a rehearsal runs: stop the rehearsal to edit it"


class Document(QObject):
    """Volume, plan, path result and rehearsal state, with a signal per change.

    Signals
    -------
    volume_changed(volume) : a new series is open (``surface`` is set before).
    surface_changed(surface) : a new bone surface (new series or iso-surface preset).
    plan_changed(plan) : the plan (or None) changed; the path result is reset to None.
    path_changed(view) : a path result for the current plan (a ``PathView``), or None with
        ``path_error`` saying why (empty: not computed yet).
    rehearsal_changed(running) : a rehearsal started or ended.
    live_depth_changed(depth_mm) : the drill depth reported by the device.
    edit_refused(message) : a plan change refused (locked, or an invalid edit).
    suggestion_requested(space) : a search around the plan is asked for (the controller runs
        it; ``space`` a ``SearchSpace``).
    suggestion_changed(suggestion) : a search started (None, ``suggest_status`` "running"),
        finished (a ``Suggestion``), failed (None, the message in ``suggest_status``), was
        dropped (None) or one of its candidates was adopted.
    """

    volume_changed = Signal(object)
    surface_changed = Signal(object)
    plan_changed = Signal(object)
    path_changed = Signal(object)
    rehearsal_changed = Signal(bool)
    live_depth_changed = Signal(float)
    edit_refused = Signal(str)
    suggestion_requested = Signal(object)
    suggestion_changed = Signal(object)

    def __init__(self, parent: QObject | None = None) -> None:
        super().__init__(parent)
        self.volume: CTVolume | None = None
        self.volume_path = ""
        self.surface: Any = None  # pyvista.PolyData of the bone surface
        self.plan: Plan | None = None
        #: Trajectory points placed before a plan exists (``entry`` / ``target``), LPS mm.
        self.draft: dict[str, np.ndarray] = {}
        self.path: PathView | None = None
        self.path_error = ""
        self.rehearsing = False
        #: The series' HU uncertainty (``ctdrill gui --hu-sigma``), entered into the force band.
        self.hu_uncertainty: HuUncertainty | None = None
        self.live_depth_mm: float | None = None
        self.suggestion: Suggestion | None = None
        #: Candidate of :attr:`suggestion` adopted as the plan's axis (None: none).
        self.adopted: int | None = None
        #: "" (idle), "running", or why the last search failed.
        self.suggest_status = ""

    # ------------------------------------------------------------------ changes
    def set_volume(self, volume: CTVolume, path: str, surface: Any) -> bool:
        """Open a new series (refused while a rehearsal runs)."""
        if self.rehearsing:
            self.edit_refused.emit("a rehearsal runs: stop it before opening another series")
            return False
        self.volume, self.volume_path = volume, path
        self._drop_suggestion()
        self.set_surface(surface)
        self.volume_changed.emit(volume)
        return True

    def set_surface(self, surface: Any) -> None:
        """A new bone surface for the open series."""
        self.surface = surface
        self.surface_changed.emit(surface)

    def set_plan(self, plan: Plan | None, *, adopted: int | None = None) -> bool:
        """Make ``plan`` the plan (refused while a rehearsal runs); the path result is reset.

        The suggestion is dropped, unless ``adopted`` names the candidate of it that ``plan``
        takes its axis from (:meth:`adopt_candidate`)."""
        if self.rehearsing:
            self.edit_refused.emit(LOCKED_MESSAGE)
            return False
        if adopted is None:
            self._drop_suggestion()
        self.plan = plan
        self.draft = {}
        self.path, self.path_error = None, ""
        self.plan_changed.emit(plan)
        return True

    # ------------------------------------------------------------------ suggestions
    def request_suggestion(self, space: SearchSpace) -> bool:
        """Ask for a search around the plan (refused without a series and a plan, or while a
        rehearsal runs)."""
        if self.rehearsing:
            self.edit_refused.emit(LOCKED_MESSAGE)
            return False
        if self.volume is None or self.plan is None:
            self.edit_refused.emit("open a series and a plan before asking for suggestions")
            return False
        self.suggestion, self.adopted, self.suggest_status = None, None, "running"
        self.suggestion_changed.emit(None)
        self.suggestion_requested.emit(space)
        return True

    def set_suggestion(self, plan: Plan, suggestion: Suggestion) -> None:
        """The search around ``plan`` finished (dropped if the plan changed meanwhile)."""
        if plan is not self.plan or self.suggest_status != "running":
            return
        self.suggestion, self.adopted, self.suggest_status = suggestion, None, ""
        self.suggestion_changed.emit(suggestion)

    def set_suggestion_failed(self, plan: Plan, message: str) -> None:
        """The search around ``plan`` failed: ``message`` says why."""
        if plan is not self.plan or self.suggest_status != "running":
            return
        self.suggestion, self.adopted, self.suggest_status = None, None, message
        self.suggestion_changed.emit(None)

    def adopt_candidate(self, index: int) -> bool:
        """Make candidate ``index`` of the suggestion the plan's axis (everything else kept)."""
        suggestion = self.suggestion
        if suggestion is None or not 0 <= index < suggestion.candidates.size:
            return False
        if not self.set_plan(suggestion.plan_of(index), adopted=index):
            return False
        self.adopted = index
        self.suggestion_changed.emit(suggestion)
        return True

    def _drop_suggestion(self) -> None:
        if self.suggestion is not None or self.suggest_status:
            self.suggestion, self.adopted, self.suggest_status = None, None, ""
            self.suggestion_changed.emit(None)

    def set_draft_point(self, name: str, point_lps: np.ndarray) -> None:
        """Keep ``entry`` or ``target`` placed while no plan exists (views redraw it)."""
        if self.rehearsing:
            self.edit_refused.emit(LOCKED_MESSAGE)
            return
        self.draft = {**self.draft, name: np.asarray(point_lps, dtype=np.float64).reshape(3)}
        self.plan_changed.emit(None)

    def set_path(self, view: PathView) -> None:
        """The path result for the current plan (dropped if computed for another plan)."""
        if view.plan is not self.plan:
            return
        self.path, self.path_error = view, ""
        self.path_changed.emit(view)

    def set_path_failed(self, plan: Plan, message: str) -> None:
        """No path for ``plan``: the result is unknown (never shown as safe)."""
        if plan is not self.plan:
            return
        self.path, self.path_error = None, message
        self.path_changed.emit(None)

    def set_rehearsing(self, running: bool) -> None:
        """A rehearsal started (the plan locks) or ended (it unlocks)."""
        if running != self.rehearsing:
            self.rehearsing = running
            if not running:
                self.live_depth_mm = None
            self.rehearsal_changed.emit(running)

    def set_live_depth(self, depth_mm: float) -> None:
        """The drill's depth reported by the device during a rehearsal, mm."""
        self.live_depth_mm = depth_mm
        self.live_depth_changed.emit(depth_mm)


class ViewContext:
    """What every view is built with: the document, the UI-thread step queue (one drawing
    step per event-loop pass, so no view holds the UI thread for long) and the status line."""

    def __init__(self, doc: Document, steps: StepQueue, status: Callable[[str], None]) -> None:
        self.doc = doc
        self.steps = steps
        self.status = status
