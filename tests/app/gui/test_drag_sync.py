"""A readout that follows the mouse is shown, during a drag, with the next dragged position
drawn (its curves) or at the drag's end: the latest value once; at once outside a drag."""

from __future__ import annotations

from pytestqt.qtbot import QtBot

from ctdrill.app.gui.document import Document
from ctdrill.app.gui.drag_sync import WithDrawnPosition
from tests.app.gui.test_document import plan


def test_a_readout_waits_for_the_drawn_position_during_a_drag(qtbot: QtBot) -> None:
    doc = Document()
    doc.set_plan(plan())
    shown: list[object] = []
    follow = WithDrawnPosition(doc.live, shown.append)
    follow("a")
    assert shown == ["a"]  # no drag: at once
    assert doc.live.drag_to(plan(-1.0))
    follow("b")
    follow("c")
    assert shown == ["a"]  # waiting for the position drawn
    doc.live.curves_changed.emit(object())
    assert shown == ["a", "c"]  # the latest, once
    doc.live.curves_changed.emit(object())
    assert shown == ["a", "c"]
    follow("d")
    doc.live.end_drag(None)  # the drag's end shows what waits
    assert shown == ["a", "c", "d"]
    follow("e")
    assert shown == ["a", "c", "d", "e"]
