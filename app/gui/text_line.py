"""Readouts that change often without moving anything: :class:`TextLine` (one line) and
:class:`SteadyLabel` (wrapped lines).

A ``QLabel`` asks its layout to re-lay out on every ``setText`` (its size hint may have
changed), and the request climbs to the window: a ``QTabWidget`` on the way repaints itself
whole (every view in it) for each one. A readout that follows the mouse during a drag would
repaint the window per move; this line keeps its size and repaints only itself.
"""

from __future__ import annotations

from PySide6.QtCore import QEvent, Qt
from PySide6.QtGui import QPainter, QPaintEvent, QResizeEvent
from PySide6.QtWidgets import QLabel, QSizePolicy, QWidget


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


class SteadyLabel(QWidget):
    """A word-wrapped label that asks its layout for room only when it needs more or fewer
    lines: a new text of the same height repaints the label alone (a bare ``QLabel`` would
    re-lay out, and repaint, the window)."""

    def __init__(self, text: str = "", parent: QWidget | None = None) -> None:
        super().__init__(parent)
        # the label has no layout above it: its requests for room stop here
        self.label = QLabel(text, self)
        self.label.setWordWrap(True)
        self.label.setAlignment(Qt.AlignmentFlag.AlignTop | Qt.AlignmentFlag.AlignLeft)
        self.label.setAutoFillBackground(True)  # opaque: the widgets under it are not painted
        self.setSizePolicy(QSizePolicy.Policy.Ignored, QSizePolicy.Policy.Fixed)
        self._fit()

    def text(self) -> str:
        """The label's text."""
        return self.label.text()

    def setText(self, text: str) -> None:
        """Show ``text``; a new height (more or fewer lines) re-lays out, nothing else does."""
        if text != self.label.text():
            self.label.setText(text)
            self._fit()

    def _fit(self) -> None:
        width = max(1, self.width())
        height = self.label.heightForWidth(width) if self.label.text() else 0
        height = max(height, self.label.fontMetrics().height())
        self.label.setGeometry(0, 0, width, height)
        if self.minimumHeight() != height or self.maximumHeight() != height:
            self.setFixedHeight(height)

    def resizeEvent(self, event: QResizeEvent) -> None:
        """A new width: the lines wrap anew."""
        super().resizeEvent(event)
        self._fit()
