"""The window's document: the Qt face of the window's state.

The state itself (the series, the plans, the draft, the path results, the rehearsal's state,
the debrief) and every rule of editing it live in :class:`ctdrill.app.gui.state.window.WindowState`,
a plain evented object that imports no Qt (napari's model/view split). :class:`Document` is a
thin adapter: it owns one, re-emits each of its events as the Qt signal of the same name (so
widgets connect as to any QObject, their connections dropped with them), reads and writes its
attributes and calls its methods, and adds the drag preview (:attr:`Document.live`, a
:class:`~ctdrill.app.gui.live_edit.LiveEdit`) in front of :meth:`Document.set_path`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from PySide6.QtCore import QObject, Signal

from ctdrill.app.gui.live_edit import LiveEdit
from ctdrill.app.gui.results import PathView
from ctdrill.app.gui.state.events import events_of
from ctdrill.app.gui.state.window import LOCKED_MESSAGE, PATH_CACHE_SIZE, WindowState
from ctdrill.app.gui.workers import StepQueue

__all__ = ["LOCKED_MESSAGE", "PATH_CACHE_SIZE", "Document", "ViewContext", "WindowState"]

#: The state's events, each re-emitted as the document's Qt signal of the same name.
EVENTS = events_of(WindowState)


class Document(QObject):
    """The window's :class:`~ctdrill.app.gui.state.window.WindowState` with a Qt signal per event
    (the same names and values; see there), and the drag preview :attr:`live`."""

    volume_changed = Signal(object)
    surface_changed = Signal(object)
    plans_changed = Signal(object)
    plan_changed = Signal(object)
    history_changed = Signal()
    path_changed = Signal(object)
    rehearsal_changed = Signal(bool)
    live_depth_changed = Signal(float)
    edit_refused = Signal(str)
    suggestion_requested = Signal(object)
    suggestion_changed = Signal(object)
    debrief_changed = Signal(object)
    #: The state this document shows (set once, in ``__init__``).
    state: WindowState

    def __init__(self, parent: QObject | None = None, state: WindowState | None = None) -> None:
        super().__init__(parent)
        self.__dict__["state"] = WindowState() if state is None else state
        for name in EVENTS:
            getattr(self.state, name).connect(getattr(self, name).emit)
        #: The drag preview and the views' link point (their own signals).
        self.live = LiveEdit(self)

    def __getattr__(self, name: str) -> Any:
        # only for what the document itself does not have: the state's attributes and methods
        if name == "state":
            raise AttributeError(name)
        return getattr(self.state, name)

    def __setattr__(self, name: str, value: Any) -> None:
        state = self.__dict__.get("state")
        if state is not None and name in vars(state) and name not in EVENTS:
            setattr(state, name, value)
        else:
            super().__setattr__(name, value)

    def set_path(self, view: PathView) -> None:
        """The path result for the plan being dragged (:attr:`live`), else the state's
        (:meth:`~ctdrill.app.gui.state.window.WindowState.set_path`)."""
        if self.live.offer(view):
            return
        self.state.set_path(view)


class ViewContext:
    """What every view is built with: the document, the UI-thread step queue (one drawing
    step per event-loop pass, so no view holds the UI thread for long) and the status line."""

    def __init__(self, doc: Document, steps: StepQueue, status: Callable[[str], None]) -> None:
        self.doc = doc
        self.steps = steps
        self.status = status
