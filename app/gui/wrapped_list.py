"""A list whose items are shown whole: every item's text wrapped to the list's width (at word
boundaries, and anywhere inside a word too long for a line, such as a file path), each item as
tall as its text, the list scrolling vertically by pixels; no text is ever elided."""

from __future__ import annotations

from PySide6.QtCore import QModelIndex, QPersistentModelIndex, QSize, Qt
from PySide6.QtGui import QAbstractTextDocumentLayout, QColor, QPainter, QTextDocument, QTextOption
from PySide6.QtWidgets import (
    QAbstractItemView,
    QListView,
    QListWidget,
    QStyle,
    QStyledItemDelegate,
    QStyleOptionViewItem,
)

#: Padding around an item's text, px.
PAD_PX = 4


class WrappedDelegate(QStyledItemDelegate):
    """Lays an item's text out in a ``QTextDocument`` as wide as the list's viewport."""

    def __init__(self, view: QListWidget) -> None:
        super().__init__(view)
        self.view = view

    def document(self, text: str, width_px: int) -> QTextDocument:
        """The item's text laid out to ``width_px`` (padding included)."""
        doc = QTextDocument()
        doc.setDefaultFont(self.view.font())
        option = QTextOption()
        option.setWrapMode(QTextOption.WrapMode.WrapAtWordBoundaryOrAnywhere)
        doc.setDefaultTextOption(option)
        doc.setDocumentMargin(0)
        doc.setPlainText(text)
        doc.setTextWidth(max(1, width_px - 2 * PAD_PX))
        return doc

    def sizeHint(
        self, option: QStyleOptionViewItem, index: QModelIndex | QPersistentModelIndex
    ) -> QSize:
        width = self.view.viewport().width()
        doc = self.document(str(index.data()), width)
        return QSize(width, int(doc.size().height()) + 2 * PAD_PX + 1)

    def paint(
        self,
        painter: QPainter,
        option: QStyleOptionViewItem,
        index: QModelIndex | QPersistentModelIndex,
    ) -> None:
        rect = option.rect
        painter.save()
        if option.state & QStyle.StateFlag.State_Selected:
            painter.fillRect(rect, option.palette.highlight())
        doc = self.document(str(index.data()), rect.width())
        painter.translate(rect.left() + PAD_PX, rect.top() + PAD_PX)
        ctx = QAbstractTextDocumentLayout.PaintContext()
        doc.documentLayout().draw(painter, ctx)
        painter.restore()
        painter.save()
        painter.setPen(QColor("#c8c8c8"))
        painter.drawLine(rect.left(), rect.bottom(), rect.right(), rect.bottom())
        painter.restore()


class WrappedList(QListWidget):
    """A ``QListWidget`` showing every item whole (see the module)."""

    def __init__(self) -> None:
        super().__init__()
        self.delegate = WrappedDelegate(self)
        self.setItemDelegate(self.delegate)
        self.setWordWrap(True)
        self.setTextElideMode(Qt.TextElideMode.ElideNone)
        self.setUniformItemSizes(False)
        self.setResizeMode(QListView.ResizeMode.Adjust)
        self.setHorizontalScrollBarPolicy(Qt.ScrollBarPolicy.ScrollBarAlwaysOff)
        self.setVerticalScrollMode(QAbstractItemView.ScrollMode.ScrollPerPixel)

    def text_height(self, row: int) -> int:
        """Height the text of item ``row`` needs at the current width, px (padding included)."""
        doc = self.delegate.document(self.item(row).text(), self.viewport().width())
        return int(doc.size().height()) + 2 * PAD_PX
