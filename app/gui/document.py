"""The window's document: the one observable object every view draws from.

The CT volume (with its bone surface), the plan, the path computed for the plan and the
rehearsal state live here and nowhere else. A view subscribes to the signals it needs and
changes the document only through its methods (napari's model/view split); the computing
happens in headless functions (:mod:`ctdrill.app.gui.compute`,
:mod:`ctdrill.app.gui.results`) run by :class:`ctdrill.app.gui.controller.Controller`.

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
from ctdrill.imaging import CTVolume
from ctdrill.imaging.plan.types import Plan

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
    """

    volume_changed = Signal(object)
    surface_changed = Signal(object)
    plan_changed = Signal(object)
    path_changed = Signal(object)
    rehearsal_changed = Signal(bool)
    live_depth_changed = Signal(float)
    edit_refused = Signal(str)

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
        self.live_depth_mm: float | None = None

    # ------------------------------------------------------------------ changes
    def set_volume(self, volume: CTVolume, path: str, surface: Any) -> bool:
        """Open a new series (refused while a rehearsal runs)."""
        if self.rehearsing:
            self.edit_refused.emit("a rehearsal runs: stop it before opening another series")
            return False
        self.volume, self.volume_path = volume, path
        self.set_surface(surface)
        self.volume_changed.emit(volume)
        return True

    def set_surface(self, surface: Any) -> None:
        """A new bone surface for the open series."""
        self.surface = surface
        self.surface_changed.emit(surface)

    def set_plan(self, plan: Plan | None) -> bool:
        """Make ``plan`` the plan (refused while a rehearsal runs); the path result is reset."""
        if self.rehearsing:
            self.edit_refused.emit(LOCKED_MESSAGE)
            return False
        self.plan = plan
        self.draft = {}
        self.path, self.path_error = None, ""
        self.plan_changed.emit(plan)
        return True

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
