"""Updates that wait for a drag's next drawn position: during a drag the window draws a
position (the outline, the force plot, the banner) when its curves come, and every update of
this window is one composition of the whole window on the screen (the 3D view is an OpenGL
widget), so a readout that follows the mouse is shown with that position's update instead of
one more update for every mouse move."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from ctdrill.app.gui.live_edit import LiveEdit


class WithDrawnPosition:
    """Calls ``show(value)`` at once, or during a drag with the next position drawn
    (``curves_changed``) or the drag's end, the latest value only."""

    def __init__(self, live: LiveEdit, show: Callable[[Any], None]) -> None:
        self.live = live
        self.show = show
        self._due: tuple[Any] | None = None  # the latest value waiting (in a 1-tuple)
        live.curves_changed.connect(lambda _view: self.flush())
        live.plan_dragged.connect(lambda plan: None if plan is not None else self.flush())

    def __call__(self, value: Any) -> None:
        if self.live.dragging:
            self._due = (value,)
            return
        self._due = None
        self.show(value)

    def flush(self) -> None:
        """Show the value waiting, if any."""
        due, self._due = self._due, None
        if due is not None:
            self.show(due[0])
