"""The student's hand on the simulated master: a vertical bar whose fill is the push.

Drilling goes down the screen: press on the bar and drag down to push harder (the push follows
the pointer), roll the wheel down for more (:data:`WHEEL_STEP_N` a notch); keys: Down / Up
more / less by :data:`KEY_STEP_N`, Page Down / Page Up by :data:`PAGE_STEP_N`, Space lets go
(0 N), R retracts the drill out of the hole. A line marks the push that cuts at the drill's
depth (:meth:`HandControl.set_need`).
"""

from __future__ import annotations

from PySide6.QtCore import QPointF, QRectF, Qt, Signal
from PySide6.QtGui import (
    QColor,
    QFocusEvent,
    QKeyEvent,
    QMouseEvent,
    QPainter,
    QPaintEvent,
    QPen,
    QWheelEvent,
)
from PySide6.QtWidgets import QSizePolicy, QWidget

from ctdrill.haptics.physics import HAND_MAX_N

#: The bar's full scale, N (the device takes up to 78 N; a drilling hand stays far below).
SCALE_N = 40.0
WHEEL_STEP_N = 0.5
KEY_STEP_N = 0.5
PAGE_STEP_N = 5.0
#: Room above and below the bar for its labels, px.
_TOP, _BOTTOM = 18, 34


class HandControl(QWidget):
    """The hand (module docstring). ``push_changed`` carries the new push (N) at every change
    the student makes; ``retract_requested`` the R key."""

    push_changed = Signal(float)
    retract_requested = Signal()

    def __init__(self) -> None:
        super().__init__()
        self.setObjectName("hand")
        self.setFocusPolicy(Qt.FocusPolicy.StrongFocus)
        self.setMinimumSize(96, 230)
        self.setSizePolicy(QSizePolicy.Policy.Fixed, QSizePolicy.Policy.Expanding)
        self.push_n = 0.0
        self.need_n: float | None = None
        self.retracting = False
        self.setToolTip(
            "Your hand on the drill. Drag down on the bar or roll the wheel to push harder; "
            "Down/Up arrows +-0.5 N, Page Down/Up +-5 N, Space lets go, R pulls the drill out."
        )

    # ------------------------------------------------------------------ state
    def set_push(self, push_n: float, *, emit: bool = True) -> None:
        """Set the push (clamped to 0..78 N); ``emit``: tell the session."""
        push = min(max(float(push_n), 0.0), HAND_MAX_N)
        changed = push != self.push_n or self.retracting
        self.push_n = push
        self.retracting = False
        self.update()
        if emit and changed:
            self.push_changed.emit(push)

    def set_need(self, need_n: float | None) -> None:
        """The push that cuts at the drill's depth, N (None: nothing to cut there)."""
        if need_n != self.need_n:
            self.need_n = need_n
            self.update()

    def retract(self) -> None:
        """Let go and draw the drill back out (the R key)."""
        self.push_n = 0.0
        self.retracting = True
        self.update()
        self.retract_requested.emit()

    # ------------------------------------------------------------------ geometry
    def _bar(self) -> QRectF:
        w = min(44.0, self.width() - 40.0)
        return QRectF((self.width() - w) / 2.0, _TOP, w, max(self.height() - _TOP - _BOTTOM, 10))

    def push_at(self, y: float) -> float:
        """The push at the widget's height ``y`` (px from its top), N."""
        bar = self._bar()
        return SCALE_N * (y - bar.top()) / bar.height()

    def y_of(self, push_n: float) -> float:
        """Where the bar's fill ends for a push of ``push_n`` (px from the widget's top)."""
        bar = self._bar()
        return bar.top() + bar.height() * min(push_n, SCALE_N) / SCALE_N

    # ------------------------------------------------------------------ input
    def mousePressEvent(self, event: QMouseEvent) -> None:
        self.setFocus(Qt.FocusReason.MouseFocusReason)
        if event.button() == Qt.MouseButton.LeftButton:
            self.set_push(self.push_at(event.position().y()))

    def mouseMoveEvent(self, event: QMouseEvent) -> None:
        if event.buttons() & Qt.MouseButton.LeftButton:
            self.set_push(self.push_at(event.position().y()))

    def wheelEvent(self, event: QWheelEvent) -> None:
        notches = -event.angleDelta().y() / 120.0  # rolled down (towards the user): more
        if notches:
            self.set_push(self.push_n + WHEEL_STEP_N * notches)
        event.accept()

    def keyPressEvent(self, event: QKeyEvent) -> None:
        key = event.key()
        steps = {
            Qt.Key.Key_Down: KEY_STEP_N,
            Qt.Key.Key_Up: -KEY_STEP_N,
            Qt.Key.Key_PageDown: PAGE_STEP_N,
            Qt.Key.Key_PageUp: -PAGE_STEP_N,
        }
        if key in steps:
            self.set_push(self.push_n + steps[key])  # type: ignore[index]
        elif key == Qt.Key.Key_Space:
            self.set_push(0.0)
        elif key == Qt.Key.Key_R:
            self.retract()
        else:
            super().keyPressEvent(event)

    def focusInEvent(self, event: QFocusEvent) -> None:
        self.update()
        super().focusInEvent(event)

    def focusOutEvent(self, event: QFocusEvent) -> None:
        self.update()
        super().focusOutEvent(event)

    # ------------------------------------------------------------------ drawing
    def paintEvent(self, _event: QPaintEvent) -> None:
        p = QPainter(self)
        p.setRenderHint(QPainter.RenderHint.Antialiasing)
        bar = self._bar()
        p.setPen(QPen(QColor("#1565c0") if self.hasFocus() else QColor("#90a4ae"), 2))
        p.setBrush(QColor("#eceff1"))
        p.drawRoundedRect(bar, 4, 4)
        fill = QRectF(bar.left(), bar.top(), bar.width(), self.y_of(self.push_n) - bar.top())
        p.setPen(Qt.PenStyle.NoPen)
        p.setBrush(QColor("#1e88e5"))
        p.drawRoundedRect(fill, 4, 4)
        p.setPen(QPen(QColor("#607d8b"), 1))
        for n in range(10, int(SCALE_N), 10):
            y = self.y_of(n)
            p.drawLine(QPointF(bar.left() - 4, y), QPointF(bar.left(), y))
            p.drawText(QRectF(0, y - 7, bar.left() - 5, 14), Qt.AlignmentFlag.AlignRight, f"{n}")
        if self.need_n is not None:
            y = self.y_of(self.need_n)
            p.setPen(QPen(QColor("#c62828"), 2, Qt.PenStyle.DashLine))
            p.drawLine(QPointF(bar.left() - 6, y), QPointF(bar.right() + 6, y))
            p.drawText(
                QRectF(bar.right() + 2, y - 16, self.width() - bar.right(), 14),
                Qt.AlignmentFlag.AlignLeft,
                "cuts",
            )
        p.setPen(QColor("#263238"))
        p.drawText(QRectF(0, 0, self.width(), _TOP), Qt.AlignmentFlag.AlignCenter, "your push")
        text = "retracting" if self.retracting else f"{self.push_n:.1f} N"
        font = p.font()
        font.setBold(True)
        p.setFont(font)
        p.drawText(
            QRectF(0, bar.bottom() + 4, self.width(), _BOTTOM - 6),
            Qt.AlignmentFlag.AlignCenter,
            text,
        )
        p.end()
