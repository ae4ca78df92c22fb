"""The Qt binding must not leak or drop references on signal/slot calls: the window's poll
timers call Python slots tens of times a second for as long as a rehearsal runs."""

from __future__ import annotations

import sys

import pytest
from PySide6.QtCore import QObject, QTimer, Signal
from PySide6.QtWidgets import QApplication

pytestmark = pytest.mark.gui  # a real window: run under a display (make test: Xvfb)

CALLS = 3000


class _Emitter(QObject):
    plain = Signal()
    value = Signal(object)


def test_timer_slots_keep_the_refcount_of_none(qapp: QApplication) -> None:
    ticks: list[int] = []
    timer = QTimer()
    timer.setInterval(0)
    timer.timeout.connect(lambda: ticks.append(1))
    before = sys.getrefcount(None)
    timer.start()
    while len(ticks) < CALLS:
        qapp.processEvents()
    timer.stop()
    drift = sys.getrefcount(None) - before
    assert abs(drift) < CALLS // 10, f"None refcount drifted by {drift} over {len(ticks)} calls"


def test_signal_emission_keeps_the_refcounts_of_none_and_bools(qapp: QApplication) -> None:
    emitter = _Emitter()
    got: list[object] = []
    emitter.plain.connect(lambda: got.append(1))
    emitter.value.connect(lambda v: got.append(1))
    before = (sys.getrefcount(None), sys.getrefcount(True), sys.getrefcount(False))
    for _ in range(CALLS):
        emitter.plain.emit()
        emitter.value.emit(7)
    after = (sys.getrefcount(None), sys.getrefcount(True), sys.getrefcount(False))
    assert len(got) == 2 * CALLS
    drift = [a - b for a, b in zip(after, before, strict=True)]
    assert all(abs(d) < CALLS // 10 for d in drift), f"refcount drift (None, True, False): {drift}"
