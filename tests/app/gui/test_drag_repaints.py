"""What a drag move repaints (issue 37): only the widgets whose content changed.

A ``QLabel``'s ``setText`` asks the layouts for room and a ``QTabWidget`` on the way repaints
itself whole, every view in it: a readout that follows the mouse repainted the window per move.
Counted here with a paint counter on every widget (an application event filter): during a drag
on ``view:drill`` the drill view, ``plot:force`` (once per result), the readout lines and the
banner repaint; the 3D view, the other slices and the tab widget holding them do not.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterator
from pathlib import Path

import pytest
from PySide6.QtCore import QEvent, QObject, QPoint, QSettings, Qt
from PySide6.QtWidgets import QApplication, QLabel, QTabWidget, QVBoxLayout, QWidget
from pytestqt.qtbot import QtBot

from ctdrill.api import open_window
from ctdrill.app.gui.main_window import MainWindow
from ctdrill.app.gui.text_line import SteadyLabel, TextLine
from tests.app.gui.helpers import LOAD_TIMEOUT_MS

pytestmark = pytest.mark.gui  # a real window: run under a display (make test: Xvfb)

ROOT = Path(__file__).resolve().parents[3]
DEMO_CT = ROOT / "assets" / "demo" / "ct"
DEMO_PLAN = ROOT / "assets" / "demo" / "plan.json"


class PaintCounter(QObject):
    """Counts paint events per widget (every widget of the application)."""

    def __init__(self) -> None:
        super().__init__()
        self.paints: Counter[int] = Counter()
        self.widgets: dict[int, QWidget] = {}

    def eventFilter(self, obj: QObject, event: QEvent) -> bool:
        if event.type() == QEvent.Type.Paint and isinstance(obj, QWidget):
            self.paints[id(obj)] += 1
            self.widgets[id(obj)] = obj
        return False

    def count(self, widget: QWidget) -> int:
        return self.paints[id(widget)]

    def painted(self) -> list[QWidget]:
        return [self.widgets[key] for key, n in self.paints.items() if n]


@pytest.fixture
def counter() -> Iterator[PaintCounter]:
    app = QApplication.instance()
    assert app is not None
    found = PaintCounter()
    app.installEventFilter(found)
    yield found
    app.removeEventFilter(found)


def _tabbed(qtbot: QtBot, readout: QWidget) -> tuple[QTabWidget, QLabel]:
    """``readout`` under a neighbour in a tab widget, shown."""
    tabs = QTabWidget()
    page = QWidget()
    box = QVBoxLayout(page)
    neighbour = QLabel("a view beside the readout")
    box.addWidget(neighbour)
    box.addWidget(readout)
    tabs.addTab(page, "views")
    qtbot.addWidget(tabs)
    tabs.resize(300, 160)
    tabs.show()
    qtbot.waitExposed(tabs, timeout=LOAD_TIMEOUT_MS)
    return tabs, neighbour


def test_a_new_readout_text_repaints_the_line_alone(qtbot: QtBot, counter: PaintCounter) -> None:
    line = TextLine("HU 100")
    tabs, neighbour = _tabbed(qtbot, line)
    qtbot.waitUntil(lambda: counter.count(neighbour) > 0, timeout=LOAD_TIMEOUT_MS)
    height = line.height()
    counter.paints.clear()
    for k in range(5):
        line.setText(f"HU {k * 1000}  a longer readout at ({k}, {k}, {k}) mm" * (k + 1))
        qtbot.waitUntil(lambda: counter.count(line) > 0, timeout=LOAD_TIMEOUT_MS)
        QApplication.processEvents()
        assert counter.count(tabs) == 0 and counter.count(neighbour) == 0
        counter.paints.clear()
    assert line.text().startswith("HU 4000") and line.height() == height
    line.setText(line.text())  # the same text: nothing to repaint
    QApplication.processEvents()
    assert counter.count(line) == 0


def test_a_wrapped_readout_asks_for_room_only_for_a_new_line_count(
    qtbot: QtBot, counter: PaintCounter
) -> None:
    readout = SteadyLabel("tilt 1.0 deg, depth 2.0 mm")
    tabs, neighbour = _tabbed(qtbot, readout)
    qtbot.waitUntil(lambda: counter.count(neighbour) > 0, timeout=LOAD_TIMEOUT_MS)
    one_line = readout.height()
    counter.paints.clear()
    for k in range(3):  # the same line count: the label alone repaints
        readout.setText(f"tilt {k}.5 deg, depth {k}.25 mm")
        qtbot.waitUntil(lambda: counter.count(readout.label) > 0, timeout=LOAD_TIMEOUT_MS)
        QApplication.processEvents()
        assert counter.count(tabs) == 0 and counter.count(neighbour) == 0
        assert readout.height() == one_line
        counter.paints.clear()
    long = " ".join(f"figure {k}: {k}.0 mm" for k in range(30))  # more lines: more room
    readout.setText(long)
    qtbot.waitUntil(lambda: readout.height() > 2 * one_line, timeout=LOAD_TIMEOUT_MS)
    assert readout.text() == long
    assert readout.label.height() == readout.height()


@pytest.fixture
def demo(qtbot: QtBot, tmp_path: Path) -> Iterator[MainWindow]:
    settings = QSettings(str(tmp_path / "settings.ini"), QSettings.Format.IniFormat)
    win = open_window(DEMO_CT, [DEMO_PLAN], settings=settings)
    qtbot.addWidget(win)
    yield win
    win.close()
    assert win.internal_error == "", win.internal_error


def test_a_drag_move_repaints_only_the_views_it_changes(
    qtbot: QtBot, demo: MainWindow, counter: PaintCounter
) -> None:
    drill = demo.findChild(QWidget, "view:drill")
    plot = demo.findChild(QWidget, "plot:force")
    assert drill is not None and plot is not None and demo.doc.plan is not None
    qtbot.waitUntil(lambda: demo.ui_steps.pending == 0, timeout=LOAD_TIMEOUT_MS)
    grip = drill.lps_to_pixel(demo.doc.plan.target_lps)  # type: ignore[attr-defined]
    x, y = round(grip[0]), round(grip[1])
    qtbot.mousePress(drill, Qt.MouseButton.LeftButton, pos=QPoint(x, y))
    qtbot.waitUntil(lambda: demo.doc.live.path is not None, timeout=LOAD_TIMEOUT_MS)
    with qtbot.waitSignal(plot.stopDepthMmChanged, timeout=LOAD_TIMEOUT_MS):
        qtbot.mouseMove(drill, QPoint(x, y + 2))  # the first move draws the ghost's artists
    qtbot.wait(50)
    counter.paints.clear()
    drawn = []
    plot.stopDepthMmChanged.connect(drawn.append)  # type: ignore[attr-defined]
    moves = 6
    for k in range(2, 2 + moves):
        with qtbot.waitSignal(plot.stopDepthMmChanged, timeout=LOAD_TIMEOUT_MS):
            qtbot.mouseMove(drill, QPoint(x, y + 2 * k))
    qtbot.waitUntil(lambda: counter.count(drill) >= 1, timeout=LOAD_TIMEOUT_MS)
    qtbot.wait(50)  # room for any extra paint the upper bounds below must count
    plot.stopDepthMmChanged.disconnect(drawn.append)  # type: ignore[attr-defined]
    assert len(drawn) == moves
    assert 1 <= counter.count(drill) <= moves + 1
    assert counter.count(plot) <= len(drawn) + 1  # one paint per drawn result (its label apart)
    still = [
        demo.view3d,
        *(demo.findChild(QWidget, f"view:{v}") for v in ("axial", "coronal", "sagittal")),
        *demo.findChildren(QTabWidget),
    ]
    repainted = [w for w in still if w is not None and counter.count(w)]
    names = sorted(f"{type(w).__name__}:{w.objectName()}" for w in repainted)
    assert names == [], f"repainted during a drag: {names}"
    qtbot.mouseRelease(drill, Qt.MouseButton.LeftButton, pos=QPoint(x, y + 2 * (moves + 1)))
