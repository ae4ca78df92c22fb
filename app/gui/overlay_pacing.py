"""Which slice views draw a plan edit at once, and which wait for its path.

A plan edit (a canal point clicked, a handle placed, a field typed) is followed by its path
result, which changes every view's overlays again (the drill down to its stop). Drawing every
view for the edit and again for its path cost each view two overlay passes and two Agg draws
whenever the path came after their turn on the step queue (under load, most of them). So
while a path is on its way every view draws once, with the path, or without it if it is late
(a slow series, a busy machine): the view the person acts on (the last one pressed) after
:data:`ACTING_WAIT_MS` at most, for the feedback under the mouse (a canal point's path, planned
in a few milliseconds, comes well before: its view then drew the point, and then it again with
the path, 15-20 ms of the UI thread beside the path's worker), the others after
:data:`WAIT_FOR_PATH_MS`. Every view hit-tests the new plan at once either way.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

from PySide6.QtCore import QEvent, QObject, QTimer
from PySide6.QtWidgets import QWidget

from ctdrill.app.gui.document import ViewContext

#: How long the views other than the one acted on wait for an edit's path, ms.
WAIT_FOR_PATH_MS = 600
#: How long the view acted on waits for an edit's path before it draws the edit alone, ms
#: (feedback under the mouse within a frame or two of a screen's).
ACTING_WAIT_MS = 35


class OverlayPacing(QObject):
    """Tracks the view acted on (``canvases``' mouse presses) and calls ``redraw(view)`` for
    each view left waiting when a path is later than :data:`WAIT_FOR_PATH_MS`."""

    def __init__(
        self,
        ctx: ViewContext,
        canvases: Mapping[str, QWidget],
        redraw: Callable[[str], None],
        parent: QObject | None = None,
    ) -> None:
        super().__init__(parent)  # the timer goes with its parent (the views' grid)
        self._ctx, self._redraw = ctx, redraw
        self._names = {id(canvas): name for name, canvas in canvases.items()}
        #: The view last pressed (None: none yet).
        self.acting: str | None = None
        #: The views waiting for the path (drawn by it, or by the timer if it is late).
        self.waiting: set[str] = set()
        self._late = QTimer(self)
        self._late.setSingleShot(True)
        self._late.setInterval(WAIT_FOR_PATH_MS)
        self._late.timeout.connect(self._path_late)
        #: The view acted on, waiting for the path (drawn by it, or by this timer).
        self.acting_waits: str | None = None
        self._acting_late = QTimer(self)
        self._acting_late.setSingleShot(True)
        self._acting_late.setInterval(ACTING_WAIT_MS)
        self._acting_late.timeout.connect(self._acting_path_late)
        for canvas in canvases.values():
            canvas.installEventFilter(self)
        # released in the same signal as the views' own redraw on a path (no pass between)
        ctx.doc.path_changed.connect(self._path_came)

    def eventFilter(self, watched: QObject, event: QEvent) -> bool:
        if event.type() == QEvent.Type.MouseButtonPress:
            self.acting = self._names.get(id(watched), self.acting)
        return False

    def path_pending(self) -> bool:
        """The current plan's path result is on its way (not known, not failed)."""
        doc = self._ctx.doc
        return doc.plan is not None and doc.path is None and not doc.path_error

    def draws_now(self, view: str) -> bool:
        """Whether ``view`` draws a plan edit now (else with its path, or once it is late)."""
        if not self.path_pending():
            self.waiting.discard(view)
            if self.acting_waits == view:
                self.acting_waits = None
            self._ctx.steps.release(("overlays", view))
            return True
        if view == self.acting:
            self.acting_waits = view
            self._ctx.steps.hold(("overlays", view))
            if not self._acting_late.isActive():
                self._acting_late.start()
            return False
        self.waiting.add(view)
        self._ctx.steps.hold(("overlays", view))  # the window is not drawn until it is
        if not self._late.isActive():
            self._late.start()
        return False

    def _path_came(self, _view: object) -> None:
        """A path result (or its failure): every view was asked to draw it."""
        self._acting_late.stop()
        acting, self.acting_waits = self.acting_waits, None
        if acting is not None:
            self._ctx.steps.release(("overlays", acting))
        self._release(redraw=False)

    def _acting_path_late(self) -> None:
        acting, self.acting_waits = self.acting_waits, None
        if acting is not None:
            self._redraw(acting)
            self._ctx.steps.release(("overlays", acting))

    def _path_late(self) -> None:
        self._release(redraw=True)

    def _release(self, *, redraw: bool) -> None:
        waiting, self.waiting = sorted(self.waiting), set()
        for view in waiting:
            if redraw:
                self._redraw(view)
            self._ctx.steps.release(("overlays", view))
