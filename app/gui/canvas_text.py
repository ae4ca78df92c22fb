"""Labels over a matplotlib canvas painted by Qt (:class:`PaintedText`, :func:`paint_texts`).

A slice view's title, orientation letters, plane readout and note were matplotlib figure
texts: Agg lays out and rasterises every glyph again on every draw (about half of a slice
view's draw, ~6 ms of its ~13 ms). Painted by ``QPainter`` after the canvas' bitmap they
cost a fraction of a millisecond, and a changed label needs a repaint, not a draw.
"""

from __future__ import annotations

from collections.abc import Iterable

from PySide6.QtCore import QPointF, QRectF, Qt
from PySide6.QtGui import QColor, QFont, QFontMetricsF, QPainter
from PySide6.QtWidgets import QWidget

#: A matplotlib point, in inches.
POINT_IN = 1.0 / 72.0


class PaintedText:
    """One label at ``(x, y)`` in figure fractions (y up, as matplotlib's ``fig.text``),
    aligned by ``ha`` (left, center, right) and ``va`` (top, center, bottom, baseline);
    ``size_pt`` at the figure's dpi; ``wrap``: broken into lines across the widget."""

    def __init__(
        self,
        x: float,
        y: float,
        text: str = "",
        *,
        ha: str = "left",
        va: str = "baseline",
        colour: str = "#e8e8e8",
        size_pt: float = 9.0,
        bold: bool = False,
        wrap: bool = False,
    ) -> None:
        self.x, self.y, self.ha, self.va = float(x), float(y), ha, va
        self.colour, self.size_pt, self.bold, self.wrap = colour, float(size_pt), bold, wrap
        self._text = str(text)

    def get_text(self) -> str:
        """The label's text."""
        return self._text

    def set_text(self, text: str) -> None:
        """Show ``text`` from the next paint."""
        self._text = str(text)


def paint_texts(widget: QWidget, texts: Iterable[PaintedText], px_per_pt: float) -> None:
    """Paint ``texts`` on ``widget`` (call from its ``paintEvent``, after the canvas);
    ``px_per_pt``: widget pixels per point (the figure's dpi / 72 / device pixel ratio)."""
    painter = QPainter(widget)
    try:
        painter.setRenderHint(QPainter.RenderHint.TextAntialiasing, True)
        w, h = float(widget.width()), float(widget.height())
        for t in texts:
            if not t.get_text():
                continue
            font = QFont(painter.font())
            font.setPixelSize(max(1, round(t.size_pt * px_per_pt)))
            font.setBold(t.bold)
            painter.setFont(font)
            painter.setPen(QColor(t.colour))
            x, y = t.x * w, (1.0 - t.y) * h
            metrics = QFontMetricsF(font)
            if t.wrap:  # centred lines across the widget, the first one's top at y
                flags = Qt.AlignmentFlag.AlignHCenter | Qt.AlignmentFlag.AlignTop
                top = y - metrics.ascent()
                painter.drawText(
                    QRectF(0.0, top, w, h - top),
                    int(flags | Qt.TextFlag.TextWordWrap),
                    t.get_text(),
                )
                continue
            width = metrics.horizontalAdvance(t.get_text())
            left = {"left": x, "center": x - width / 2.0, "right": x - width}[t.ha]
            base = {
                "baseline": y,
                "top": y + metrics.ascent(),
                "bottom": y - metrics.descent(),
                "center": y + (metrics.ascent() - metrics.descent()) / 2.0,
            }[t.va]
            painter.drawText(QPointF(left, base), t.get_text())
    finally:
        painter.end()
