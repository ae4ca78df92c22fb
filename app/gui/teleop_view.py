"""The teleoperation page: the slave cuts the current plan under bilateral control.

The settings of ``ctdrill teleop`` (push, hand damping, delay, force-law error,
misregistration, seed, duration) and a Run button; the run is headless
(:func:`ctdrill.app.teleop.teleop_case`, :func:`ctdrill.app.teleop.run_teleop`) off the UI
thread, the figure :func:`ctdrill.app.teleop_plot.draw_teleop`: both robots' depths, the force
felt and the force cut, the estimated CT number over the CT's along the path.
"""

from __future__ import annotations

from typing import Any

from matplotlib.backends.backend_qtagg import FigureCanvasQTAgg
from matplotlib.figure import Figure
from PySide6.QtWidgets import (
    QDoubleSpinBox,
    QFormLayout,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QPushButton,
    QSpinBox,
    QVBoxLayout,
    QWidget,
)

from ctdrill.app.gui.document import ViewContext
from ctdrill.app.gui.plots import WINDOW_DPI
from ctdrill.app.gui.workers import Runner
from ctdrill.app.teleop import run_teleop, teleop_case
from ctdrill.app.teleop_plot import draw_teleop
from ctdrill.haptics.bilateral.params import FIRM_GRIP_N_S_PER_M
from ctdrill.haptics.session import parse_operator


def _spin(lo: float, hi: float, value: float, step: float, suffix: str) -> QDoubleSpinBox:
    box = QDoubleSpinBox()
    box.setRange(lo, hi)
    box.setSingleStep(step)
    box.setValue(value)
    box.setSuffix(suffix)
    return box


class TeleopView(QWidget):
    """The teleoperation page (module docstring)."""

    def __init__(self, ctx: ViewContext) -> None:
        super().__init__()
        self.ctx = ctx
        self.result: tuple[Any, dict[str, Any]] | None = None
        outer = QHBoxLayout(self)
        box = QGroupBox("Slave robot under bilateral control")
        form = QFormLayout(box)
        self.push = _spin(1.0, 60.0, 15.0, 1.0, " N")
        form.addRow("hand push", self.push)
        self.damping = _spin(0.0, 200.0, FIRM_GRIP_N_S_PER_M, 1.0, " N s/m")
        form.addRow("hand damping", self.damping)
        self.delay = _spin(0.0, 100.0, 0.0, 1.0, " ms")
        form.addRow("one-way delay", self.delay)
        self.model_error = _spin(-50.0, 100.0, 0.0, 5.0, " %")
        form.addRow("true force law off by", self.model_error)
        self.misregister = _spin(-10.0, 10.0, 0.0, 0.5, " mm")
        form.addRow("CT shifted (misregistration)", self.misregister)
        self.seed = QSpinBox()
        self.seed.setRange(0, 1_000_000)
        form.addRow("seed", self.seed)
        self.duration = _spin(0.5, 60.0, 4.0, 0.5, " s")
        form.addRow("duration", self.duration)
        self.run_button = QPushButton("Run the slave")
        self.run_button.clicked.connect(self.run)
        form.addRow(self.run_button)
        self.message = QLabel("Load a CT and place a trajectory, then run.")
        self.message.setWordWrap(True)
        form.addRow(self.message)
        left = QVBoxLayout()
        left.addWidget(box)
        left.addStretch(1)
        outer.addLayout(left, 1)
        self.figure = Figure(figsize=(7, 6), dpi=WINDOW_DPI)
        self.canvas = FigureCanvasQTAgg(self.figure)
        self.canvas.setObjectName("plot:teleop")
        outer.addWidget(self.canvas, 3)
        self.runner = Runner(self._done, self._failed, parent=self)

    def run(self) -> bool:
        """Start a run on the document's CT and current trajectory (False: nothing to run)."""
        doc = self.ctx.doc
        if doc.volume is None or doc.plan is None:
            self.message.setText("Load a CT and place a trajectory first.")
            return False
        volume, plan = doc.volume, doc.plan
        push = self.push.value()
        duration, seed = self.duration.value(), self.seed.value()
        damping, delay = self.damping.value(), self.delay.value()
        error, shift = self.model_error.value() / 100.0, self.misregister.value()

        def job() -> tuple[Any, dict[str, Any]]:
            case = teleop_case(volume, plan, misregister_mm=shift)
            return run_teleop(
                case,
                parse_operator(f"push:{push:g}"),
                duration_s=duration,
                seed=seed,
                hand_damping_n_s_per_m=damping,
                delay_ms=delay,
                model_error=error,
            )

        self.run_button.setEnabled(False)
        self.message.setText("Running the 10 kHz loop...")
        self.runner.submit(job)
        return True

    def _done(self, result: object) -> None:
        self.run_button.setEnabled(True)
        if not isinstance(result, tuple):
            return
        run, figures = result
        self.result = (run, figures)
        draw_teleop(self.figure, run, figures)
        self.canvas.draw_idle()
        stop = figures.get("stop_depth_mm")
        where = (
            "no stop" if stop is None else f"stopped at {stop:.2f} mm ({figures['stop_reason']})"
        )
        self.message.setText(
            f"{where}; tracking {figures.get('tracking_rms_um') or 0.0:.1f} um RMS in cutting; "
            f"passive {'yes' if figures['passive'] else 'no'}; layers "
            f"{figures['layers_detected']} found, {figures['layers_missed']} missed"
        )

    def _failed(self, exc: BaseException, tb: str) -> None:
        self.run_button.setEnabled(True)
        self.message.setText(f"The run failed: {exc}")
