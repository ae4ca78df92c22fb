"""What the hand feels, drawn live: the three named forces, the depth against the stop and the
margin, and the cutting vibration as a moving trace (painted with QPainter: a frame costs well
under a millisecond, so the 30 Hz poll never waits on them)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from PySide6.QtCore import QPointF, QRectF, Qt
from PySide6.QtGui import QColor, QPainter, QPaintEvent, QPen, QPolygonF
from PySide6.QtWidgets import QSizePolicy, QWidget

from ctdrill.app.readout import GAUGE_FORCES
from ctdrill.haptics.renderer import CONTINUOUS_FORCE_N
from ctdrill.imaging.plan.clinical import CLINICAL_MARGIN_MM

#: Colours of the gauge's forces (:data:`ctdrill.app.readout.GAUGE_FORCES`).
FORCE_COLOURS = {"hand": "#1e88e5", "cutting": "#2e7d32", "wall": "#c62828"}
#: The force gauge's smallest full scale, N.
GAUGE_SCALE_N = 25.0
#: The vibration trace shows this much of the past, s.
TRACE_WINDOW_S = 0.25
#: The trace removes the force's mean over this much time (a period of the 30 Hz harmonic),
#: so a step of the push shows as a short blip, not as a shifted line, s.
RIPPLE_MEAN_S = 1.0 / 30.0


class ForceGauge(QWidget):
    """Three bars: the hand's push, the cut's resistance, the stop's wall (N)."""

    def __init__(self) -> None:
        super().__init__()
        self.setObjectName("gauge:forces")
        self.setMinimumHeight(84)
        self.setSizePolicy(QSizePolicy.Policy.Expanding, QSizePolicy.Policy.Fixed)
        self.forces = dict.fromkeys(GAUGE_FORCES, 0.0)
        self.setToolTip(
            "hand: what the device reads of your push (reaction-force observer); cutting: "
            "the force the bone resists with (the device's force while it cuts or holds); "
            f"wall: the stop's force. The tick is the device's {CONTINUOUS_FORCE_N:g} N "
            "continuous rating."
        )

    def set_forces(self, forces: Mapping[str, float]) -> None:
        """The forces by name, N."""
        self.forces = {k: float(forces.get(k, 0.0)) for k in GAUGE_FORCES}
        self.update()

    def paintEvent(self, _event: QPaintEvent) -> None:
        p = QPainter(self)
        label_w, value_w = 58.0, 62.0
        left, right = label_w, self.width() - value_w
        scale = max(GAUGE_SCALE_N, *self.forces.values())
        row_h = (self.height() - 4) / len(GAUGE_FORCES)
        for i, name in enumerate(GAUGE_FORCES):
            top = 2 + i * row_h
            value = self.forces[name]
            p.setPen(QColor("#263238"))
            p.drawText(QRectF(0, top, label_w - 6, row_h), Qt.AlignmentFlag.AlignVCenter, name)
            p.setPen(Qt.PenStyle.NoPen)
            p.setBrush(QColor("#eceff1"))
            p.drawRect(QRectF(left, top + 4, right - left, row_h - 8))
            p.setBrush(QColor(FORCE_COLOURS[name]))
            p.drawRect(QRectF(left, top + 4, (right - left) * max(value, 0.0) / scale, row_h - 8))
            p.setPen(QColor("#263238"))
            p.drawText(
                QRectF(right + 4, top, value_w - 4, row_h),
                Qt.AlignmentFlag.AlignVCenter,
                f"{value:5.1f} N",
            )
        x = left + (right - left) * CONTINUOUS_FORCE_N / scale
        p.setPen(QPen(QColor("#78909c"), 1, Qt.PenStyle.DotLine))
        p.drawLine(QPointF(x, 2), QPointF(x, self.height() - 2))
        p.end()


class DepthGauge(QWidget):
    """The drill's depth going down, against the planned depth, the safety zone around the
    nerve (the margin), the nerve itself and the device's stop; the hand's position marked."""

    def __init__(self) -> None:
        super().__init__()
        self.setObjectName("gauge:depth")
        self.setMinimumSize(150, 230)
        self.depth_mm = np.zeros(0)
        self.clearance_mm = np.zeros(0)
        self.margin_mm = CLINICAL_MARGIN_MM  # until set_path gives the plan's
        self.planned_mm = 0.0
        self.stop_mm = 0.0
        self.drill_mm = 0.0
        self.hand_mm = 0.0
        self.setToolTip(
            "Depth from the entry point, going down. Amber: the safety zone (closer to the "
            "nerve than the margin); red: the nerve canal; the thick line is where the device "
            "stops the drill; the triangle is your hand (the master)."
        )

    def set_path(
        self,
        depth_mm: np.ndarray,
        clearance_mm: np.ndarray,
        *,
        margin_mm: float,
        planned_mm: float,
        stop_mm: float,
    ) -> None:
        """The path: clearance per depth (empty without landmarks), its margin, the planned
        depth and the device's stop, mm."""
        self.depth_mm = np.asarray(depth_mm, dtype=float)
        self.clearance_mm = np.asarray(clearance_mm, dtype=float)
        self.margin_mm, self.planned_mm, self.stop_mm = margin_mm, planned_mm, stop_mm
        self.update()

    def set_depth(self, drill_mm: float, hand_mm: float) -> None:
        """The drill's depth and the hand's (master's), mm."""
        self.drill_mm, self.hand_mm = drill_mm, hand_mm
        self.update()

    def _span(self) -> float:
        deepest = max(self.stop_mm, self.planned_mm, self.drill_mm, self.hand_mm)
        if self.depth_mm.size:
            deepest = min(max(deepest, self.planned_mm + 2.0), float(self.depth_mm[-1]))
        return max(deepest + 1.0, 1.0)

    def paintEvent(self, _event: QPaintEvent) -> None:
        p = QPainter(self)
        p.setRenderHint(QPainter.RenderHint.Antialiasing)
        top, bottom = 8.0, self.height() - 8.0
        x0, w = 40.0, 36.0
        span = self._span()

        def y(depth: float) -> float:
            return top + (bottom - top) * min(max(depth, 0.0), span) / span

        p.setPen(Qt.PenStyle.NoPen)
        p.setBrush(QColor("#f5f5f5"))
        p.drawRect(QRectF(x0, top, w, bottom - top))
        if self.clearance_mm.size:
            d, c = self.depth_mm, self.clearance_mm
            for lo, colour in ((self.margin_mm, "#ffcc80"), (0.0, "#ef9a9a")):
                inside = c < lo
                if np.any(inside):
                    first = float(d[np.argmax(inside)])
                    p.setBrush(QColor(colour))
                    p.drawRect(QRectF(x0, y(first), w, bottom - y(first)))
        p.setBrush(QColor("#8d6e63"))
        p.drawRect(QRectF(x0 + w * 0.3, top, w * 0.4, y(self.drill_mm) - top))
        hy = y(self.hand_mm)
        p.setBrush(QColor("#1e88e5"))
        p.drawPolygon(
            QPolygonF([QPointF(x0 - 2, hy), QPointF(x0 - 12, hy - 6), QPointF(x0 - 12, hy + 6)])
        )
        p.setPen(QPen(QColor("#263238"), 1, Qt.PenStyle.DashLine))
        p.drawLine(QPointF(x0 - 4, y(self.planned_mm)), QPointF(x0 + w + 4, y(self.planned_mm)))
        p.setPen(QPen(QColor("#000000"), 3))
        p.drawLine(QPointF(x0 - 4, y(self.stop_mm)), QPointF(x0 + w + 4, y(self.stop_mm)))
        p.setPen(QColor("#263238"))
        text_x = x0 + w + 8
        labels = [
            (self.planned_mm, f"planned {self.planned_mm:.1f}"),
            (self.stop_mm, f"stop {self.stop_mm:.1f}"),
        ]
        if self.planned_mm <= 0.0 and self.stop_mm <= 0.0:
            labels = []  # no path yet
        for depth, text in labels:
            p.drawText(
                QRectF(text_x, y(depth) - 8, self.width() - text_x, 16),
                Qt.AlignmentFlag.AlignVCenter,
                text,
            )
        p.drawText(QRectF(0, top, x0 - 14, 16), Qt.AlignmentFlag.AlignRight, f"{self.drill_mm:.1f}")
        p.drawText(QRectF(0, top + 14, x0 - 14, 16), Qt.AlignmentFlag.AlignRight, "mm")
        p.end()


def ripple(rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(time_s, force less its centred running mean)`` of ``(N, 2)`` rows over the last
    :data:`TRACE_WINDOW_S` (the mean over :data:`RIPPLE_MEAN_S`, shorter at the ends)."""
    if rows.shape[0] < 2:
        return rows[:, 0], np.zeros(rows.shape[0])
    keep = rows[:, 0] >= rows[-1, 0] - TRACE_WINDOW_S
    t, f = rows[:, 0], rows[:, 1]
    step = float(np.median(np.diff(t))) or 1e-3
    half = max(round(RIPPLE_MEAN_S / step / 2.0), 1)
    csum = np.concatenate([[0.0], np.cumsum(f)])
    idx = np.arange(f.size)
    lo, hi = np.maximum(idx - half, 0), np.minimum(idx + half + 1, f.size)
    mean = (csum[hi] - csum[lo]) / (hi - lo)
    return t[keep], (f - mean)[keep]


class VibrationTrace(QWidget):
    """The device force's ripple over the last :data:`TRACE_WINDOW_S` (its mean removed):
    the 30 and 60 Hz vibration of the cut, moving as the session runs."""

    def __init__(self) -> None:
        super().__init__()
        self.setObjectName("gauge:vibration")
        self.setMinimumHeight(70)
        self.setSizePolicy(QSizePolicy.Policy.Expanding, QSizePolicy.Policy.Fixed)
        self.time_s = np.zeros(0)
        self.ripple_n = np.zeros(0)

    def set_trace(self, rows: Sequence[tuple[float, float]]) -> None:
        """``(time_s, force_n)`` rows, oldest first; the last :data:`TRACE_WINDOW_S` shown,
        less the force's running mean over :data:`RIPPLE_MEAN_S`."""
        self.time_s, self.ripple_n = ripple(np.asarray(rows, dtype=float).reshape(-1, 2))
        self.update()

    def paintEvent(self, _event: QPaintEvent) -> None:
        p = QPainter(self)
        p.setRenderHint(QPainter.RenderHint.Antialiasing)
        rect = QRectF(0, 0, self.width(), self.height()).adjusted(1, 14, -1, -1)
        p.fillRect(rect, QColor("#102027"))
        p.setPen(QColor("#263238"))
        amp = max(1.0, float(np.max(np.abs(self.ripple_n))) if self.ripple_n.size else 1.0)
        p.drawText(
            QRectF(0, 0, self.width(), 14),
            Qt.AlignmentFlag.AlignLeft,
            f"vibration you feel (+-{amp:.1f} N)",
        )
        mid = rect.center().y()
        p.setPen(QPen(QColor("#37474f"), 1))
        p.drawLine(QPointF(rect.left(), mid), QPointF(rect.right(), mid))
        if self.time_s.size >= 2:
            t_end = float(self.time_s[-1])
            xs = rect.right() - (t_end - self.time_s) / TRACE_WINDOW_S * rect.width()
            ys = mid - self.ripple_n / amp * (rect.height() / 2.0 - 2.0)
            p.setPen(QPen(QColor("#76ff03"), 1.5))
            p.drawPolyline(QPolygonF([QPointF(x, v) for x, v in zip(xs, ys, strict=True)]))
        p.end()
