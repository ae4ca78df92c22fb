"""A one-line text readout that changes often without moving anything: :class:`TextLine`.

A ``QLabel`` asks its layout to re-lay out on every ``setText`` (its size hint may have
changed), and the request climbs to the window: a ``QTabWidget`` on the way repaints itself
whole (every view in it) for each one. A readout that follows the mouse during a drag would
repaint the window per move; this line keeps its size and repaints only itself.
"""

from __future__ import annotations

from PySide6.QtCore import QEvent, Qt
from PySide6.QtGui import QPainter, QPaintEvent
from PySide6.QtWidgets import QSizePolicy, QWidget


class TextLine(QWidget):
    """One line of text, elided at the right, a fixed height of one line of its font; its
    width follows the layout (size policy Ignored: a long text never widens its row)."""

    def __init__(self, text: str = "", parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self._text = text
        self.setSizePolicy(QSizePolicy.Policy.Ignored, QSizePolicy.Policy.Fixed)
        self.fit_height()
        # it fills its rectangle: the widgets under it are not painted with it
        self.setAutoFillBackground(True)
        self.setAttribute(Qt.WidgetAttribute.WA_OpaquePaintEvent)
        #: Paints so far (for tests of what a change repaints).
        self.paints = 0

    def text(self) -> str:
        """The text shown (all of it, however much is elided on the screen)."""
        return self._text

    def setText(self, text: str) -> None:
        """Show ``text``: a repaint of this line only (no layout request)."""
        if text != self._text:
            self._text = text
            self.update()

    def fit_height(self) -> None:
        """A fixed height: one line of the font within the contents margins."""
        margins = self.contentsMargins()
        self.setFixedHeight(self.fontMetrics().height() + margins.top() + margins.bottom())

    def changeEvent(self, event: QEvent) -> None:
        """A new font (a style sheet): the height of one of its lines."""
        super().changeEvent(event)
        if event.type() == QEvent.Type.FontChange:
            self.fit_height()

    def paintEvent(self, _event: QPaintEvent) -> None:
        self.paints += 1
        painter = QPainter(self)
        painter.fillRect(self.rect(), self.palette().window())
        rect = self.contentsRect()
        metrics = self.fontMetrics()
        shown = metrics.elidedText(self._text, Qt.TextElideMode.ElideRight, rect.width())
        painter.drawText(
            rect, int(Qt.AlignmentFlag.AlignLeft | Qt.AlignmentFlag.AlignVCenter), shown
        )
        painter.end()
