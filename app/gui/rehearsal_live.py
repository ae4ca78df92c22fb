"""The rehearsal panel's live part: the hand, the depth gauge, the forces, the vibration trace
and the plain-word status, updated from each telemetry sample (:meth:`LiveReadouts.show_telemetry`).
"""

from __future__ import annotations

from PySide6.QtWidgets import QGroupBox, QHBoxLayout, QLabel, QVBoxLayout

from ctdrill.app.gui.blind_words import blind_live_words
from ctdrill.app.gui.gauges import DepthGauge, ForceGauge, VibrationTrace
from ctdrill.app.gui.hand_control import HandControl
from ctdrill.app.gui.rehearsal import RehearsalRun, Telemetry
from ctdrill.app.gui.rehearsal_words import live_words, need_here_n
from ctdrill.app.gui.sound import VibrationSound
from ctdrill.app.readout import gauge_forces, harmonics_at, live_readout

#: The drill's feed readout is measured over this much session time, s.
FEED_WINDOW_S = 0.25
#: The hand's push when the panel opens, N.
START_PUSH_N = 12.0
STATE_STYLE = {
    "idle": "background:#505860; color:white",
    "cutting": "background:#2e7d32; color:white",
    "stopped": "background:#c62828; color:white",
    "safe": "background:#6a1b9a; color:white",
}
WARN_STYLE = "color:#c62828; font-weight:bold"
#: The device's states in the trainee's words (the state's own name is in the tooltip).
STATE_WORDS = {
    "idle": "not drilling",
    "cutting": "drilling",
    "stopped": "at the stop",
    "safe": "stopped for safety",
}


class LiveReadouts(QGroupBox):
    """Your hand and what it feels (module docstring)."""

    def __init__(self) -> None:
        super().__init__("Your hand and what it feels")
        #: A blind trial: no word of the force the bone resists with or the push it needs.
        self.blind = False
        box = QVBoxLayout(self)
        self.state_label = QLabel(STATE_WORDS["idle"])
        self.state_label.setStyleSheet(STATE_STYLE["idle"])
        self.state_label.setToolTip("device state: idle")
        box.addWidget(self.state_label)
        pair = QHBoxLayout()
        self.hand = HandControl()
        self.hand.set_push(START_PUSH_N, emit=False)
        self.depth_gauge = DepthGauge()
        pair.addWidget(self.hand)
        pair.addWidget(self.depth_gauge, 1)
        box.addLayout(pair)
        self.forces = ForceGauge()
        box.addWidget(self.forces)
        self.trace = VibrationTrace()
        box.addWidget(self.trace)
        self.status_label = QLabel("-")
        self.status_label.setWordWrap(True)
        # room for two lines whatever it says, so a longer text never overlaps the next row
        self.status_label.setMinimumHeight(2 * self.status_label.fontMetrics().lineSpacing() + 6)
        box.addWidget(self.status_label)
        self.depth_label = QLabel("-")
        self.clearance_label = QLabel("-")
        self.clearance_label.setToolTip(
            "Distance from the drill to the nearest landmark (the nerve)"
        )
        where = QHBoxLayout()
        where.addWidget(self.depth_label)
        where.addWidget(self.clearance_label)
        box.addLayout(where)
        self.auto_stop_label = QLabel("auto-stop: -")
        self.auto_stop_label.setWordWrap(True)
        self.safe_label = QLabel("safe state: -")
        box.addWidget(self.auto_stop_label)
        box.addWidget(self.safe_label)
        self._drill_history: list[tuple[float, float]] = []  # (session s, drill mm)

    def reset(self) -> None:
        """A new run."""
        self._drill_history.clear()

    def show_telemetry(
        self, run: RehearsalRun, tel: Telemetry, stop_why: str, sound: VibrationSound
    ) -> None:
        """Update every readout from one telemetry sample of ``run``."""
        self.state_label.setText(STATE_WORDS.get(tel.state, tel.state))
        self.state_label.setToolTip(f"device state: {tel.state}")
        self.state_label.setStyleSheet(STATE_STYLE.get(tel.state, ""))
        self.depth_label.setText(f"drill {tel.drill_mm:.2f} mm deep")
        self.depth_gauge.set_depth(tel.drill_mm, tel.master_mm)
        self._show_forces(run, tel, sound)
        c = tel.clearance_mm
        self.clearance_label.setText(
            "-" if c is None else (f"{c:.2f} mm from the nerve" if c >= 0.0 else "in the nerve!")
        )
        reached = tel.state == "stopped"
        self.auto_stop_label.setText(f"auto-stop: {'REACHED' if reached else 'armed'}: {stop_why}")
        self.auto_stop_label.setStyleSheet(WARN_STYLE if reached else "")
        self.safe_label.setText("safe state: YES" if tel.state == "safe" else "safe state: no")
        self.trace.set_trace(list(run.trace))

    def _feed(self, tel: Telemetry) -> float | None:
        """The drill's feed over the last :data:`FEED_WINDOW_S`, mm/s (None: too short)."""
        hist = self._drill_history
        if hist and tel.time_s < hist[-1][0]:
            hist.clear()  # a new run
        hist.append((tel.time_s, tel.drill_mm))
        while len(hist) > 2 and hist[1][0] <= tel.time_s - FEED_WINDOW_S:
            hist.pop(0)
        span = hist[-1][0] - hist[0][0]
        return (hist[-1][1] - hist[0][1]) / span if span >= 0.5 * FEED_WINDOW_S else None

    def _show_forces(self, run: RehearsalRun, tel: Telemetry, sound: VibrationSound) -> None:
        """The gauge's three forces and what the push does here, in plain words (once the
        device is idle or safe again: its last armed reading, said so); the sound's vibration."""
        now_state = tel.state
        if now_state not in ("cutting", "stopped") and run.last_armed is not None:
            tel = run.last_armed
        push = run.push_n if run.device.simulated else None
        r = live_readout(
            run.table,
            state=tel.state,
            master_mm=tel.master_mm,
            drill_mm=tel.drill_mm,
            force_n=tel.force_n,
            hand_n=tel.hand_n,
            push_n=push,
            plan_feed_mm_s=run.result.plan.feed_mm_s,
            drill_feed_mm_s=self._feed(tel),
        )
        self.forces.set_forces(gauge_forces(r, push))
        need = None if self.blind else need_here_n(r, push)
        self.hand.set_need(None if need is None else float(need))
        text, tip = blind_live_words(r, push) if self.blind else live_words(r, push)
        if tel.state != now_state:
            text = f"{text} (last reading; the device is now {now_state})"
        self.status_label.setText(text)
        self.status_label.setToolTip(tip)
        self.status_label.setStyleSheet(WARN_STYLE if r.kind == "holding" else "")
        cutting = r.kind == "cutting" and now_state == "cutting"
        s1, s2 = harmonics_at(run.table, tel.drill_mm) if cutting else (0.0, 0.0)
        f1, f2 = (float(f) for f in run.table.freqs_hz)
        sound.set_vibration(s1, s2, (f1, f2))
