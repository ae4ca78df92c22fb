"""What keeps the window's edits off the UI thread's back: slice overlays drawn one canvas a
step and coalesced, canal tube fields kept, the implant list left alone on other edits.

The times themselves (a canal click, the longest stall of a session) are measured in
``bench/bench_window.py``; these tests check the mechanisms, which do not depend on load.
"""

from __future__ import annotations

import numpy as np
import pytest
from pytestqt.qtbot import QtBot

from ctdrill.app.gui.main_window import MainWindow
from ctdrill.app.gui.sections import Plane, tube_field
from ctdrill.app.gui.slice_overlays import cached_tube_field

#: The views whose plane a canal click leaves where it is.
ORTHO_VIEWS = ("axial", "coronal", "sagittal")


def test_tube_fields_are_kept_by_value() -> None:
    plane = Plane(
        origin_lps=np.zeros(3), u_lps=np.array([1.0, 0.0, 0.0]), v_lps=np.array([0.0, 1.0, 0.0])
    )
    canal = np.array([[-10.0, 0.0, 0.5], [0.0, 1.0, 0.2], [10.0, 0.0, 0.4]])
    first = cached_tube_field(plane, canal, 3.0, 0.3)
    again = cached_tube_field(plane, canal.copy(), 3.0, 0.3)  # equal values: the same field
    assert first is not None and again is first
    fresh = tube_field(plane, canal, 3.0, 0.3)
    assert fresh is not None
    np.testing.assert_array_equal(first.distance_mm, fresh.distance_mm)
    moved = canal.copy()
    moved[1, 1] += 1.0  # a point moved: computed again
    other = cached_tube_field(plane, moved, 3.0, 0.3)
    assert other is not first and other is not None
    assert not np.array_equal(other.distance_mm, first.distance_mm)


def test_overlay_requests_coalesce_into_one_step_per_canvas(window: MainWindow) -> None:
    grid = window.slice_grid
    before = window.ui_steps.pending
    grid.draw_overlays()
    grid.draw_overlays()  # the plan, then its path: drawn once
    grid.draw_overlays(only="axial")
    assert window.ui_steps.pending - before == len(grid.canvases)
    scene = grid.canvases["axial"].scene  # hit-testing has the new scene at once
    while window.ui_steps.pending:
        window.ui_steps._step()
    assert grid.canvases["axial"].scene is scene


def test_a_draw_queued_before_new_overlays_draws_them_once(window: MainWindow) -> None:
    grid = window.slice_grid
    while window.ui_steps.pending:
        window.ui_steps._step()
    canvas = grid.canvases["coronal"]
    drawn: list[int] = []
    overlays: list[int] = []
    draw, set_overlays = canvas.draw, canvas.set_overlays
    canvas.draw = lambda: (drawn.append(1), draw())[1]  # type: ignore[method-assign]
    canvas.set_overlays = lambda scene: (  # type: ignore[method-assign]
        overlays.append(1),
        set_overlays(scene),
    )[1]
    canvas.draw_idle()  # a draw queued (a new slice shown) ...
    grid.draw_overlays()  # ... then new overlays (the path arrived) before it ran
    while window.ui_steps.pending:
        window.ui_steps._step()
    assert drawn == [1] and overlays == [1]  # the queued draw showed them: one draw
    canvas.draw_idle()
    while window.ui_steps.pending:
        window.ui_steps._step()
    assert drawn == [1, 1] and overlays == [1]  # nothing due: drawn as it was


def test_the_implant_list_is_rebuilt_only_when_it_changes(window: MainWindow) -> None:
    picker = window.plan_panel.implant
    specs = list(picker._specs)
    items = picker.count()
    picker.show_plan(None)  # an edit elsewhere in the plan: the same list
    assert picker._specs == specs and picker.count() == items
    assert picker._specs is not None


def test_the_audio_library_is_loaded_aside_once() -> None:
    import threading

    from ctdrill.app.gui.sound import VibrationSound

    fake = VibrationSound(opener=lambda _cb: None)
    before = threading.active_count()
    fake.prepare()  # a test's own output: nothing to load
    assert threading.active_count() == before
    sound = VibrationSound()
    sound.prepare()
    sound.prepare()  # once
    loaders = [t for t in threading.enumerate() if t.name == "ctdrill-audio"]
    assert len(loaders) <= 1
    for t in loaders:
        t.join(timeout=60)
    assert not any(t.name == "ctdrill-audio" and t.is_alive() for t in threading.enumerate())


def test_only_the_view_acted_on_draws_an_edit_before_its_path(
    qtbot: QtBot, monkeypatch: pytest.MonkeyPatch
) -> None:
    from types import SimpleNamespace

    from PySide6.QtCore import QObject, QPoint, Qt, Signal
    from PySide6.QtTest import QTest
    from PySide6.QtWidgets import QWidget

    from ctdrill.app.gui import overlay_pacing
    from ctdrill.app.gui.overlay_pacing import OverlayPacing
    from ctdrill.app.gui.workers import StepQueue

    monkeypatch.setattr(overlay_pacing, "WAIT_FOR_PATH_MS", 60)  # a late path, sooner
    monkeypatch.setattr(overlay_pacing, "ACTING_WAIT_MS", 20)

    class Doc(QObject):
        path_changed = Signal(object)

    doc = Doc()
    doc.plan, doc.path, doc.path_error = object(), object(), ""  # type: ignore[attr-defined]
    steps = StepQueue()
    canvases = {name: QWidget() for name in ("axial", "coronal")}
    for canvas in canvases.values():
        qtbot.addWidget(canvas)
        canvas.resize(50, 50)
        canvas.show()
    redraws: list[str] = []
    ctx = SimpleNamespace(doc=doc, steps=steps)
    pacing = OverlayPacing(ctx, canvases, redraws.append)  # type: ignore[arg-type]
    assert pacing.draws_now("coronal")  # the path known: every view draws
    QTest.mouseClick(canvases["axial"], Qt.MouseButton.LeftButton, pos=QPoint(10, 10))
    assert pacing.acting == "axial"
    doc.path = None  # type: ignore[attr-defined]  # an edit: its path on its way
    # every view waits for it; the one acted on the shorter while (feedback under the mouse)
    assert not pacing.draws_now("axial") and not pacing.draws_now("coronal")
    assert steps.pending == 2  # the views waiting: the window is not drawn yet
    qtbot.waitUntil(lambda: len(redraws) == 2, timeout=2000)
    assert redraws == ["axial", "coronal"] and steps.pending == 0  # late: drawn without it
    # the path in time: the view acted on draws once, with it
    redraws.clear()
    assert not pacing.draws_now("axial") and not pacing.draws_now("coronal")
    doc.path = object()  # type: ignore[attr-defined]
    doc.path_changed.emit(doc.path)  # the path came (every view drew it) before the wait ended
    assert steps.pending == 0
    qtbot.wait(200)
    assert redraws == []
    doc.path, doc.path_error = None, "no path"  # type: ignore[attr-defined]  # failed
    assert pacing.draws_now("coronal") and steps.pending == 0


def test_a_canal_click_draws_every_view_once_with_its_path_and_each_tube_once(
    qtbot: QtBot, window: MainWindow, phantom_case: object, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Every view draws the click once, with its path (the click's view too, the path coming
    within its wait), each tube computed once (a plane the trajectory view shares with another
    shares its tube), every draw over the kept image."""
    from PySide6.QtCore import QPoint, Qt

    from ctdrill.app.gui import slice_overlays
    from ctdrill.app.gui.slice_overlays import _tube_request
    from tests.app.gui.helpers import open_case
    from tests.app.gui.test_slice_navigation import settle

    window.resize(1440, 900)
    open_case(qtbot, window, phantom_case)  # type: ignore[arg-type]
    settle(qtbot, window)
    grid = window.slice_grid
    grid.pacing._late.setInterval(60_000)  # a path late under load: still drawn once
    grid.pacing._acting_late.setInterval(60_000)
    qtbot.waitUntil(lambda: all(c.kept.full_draws for c in grid.canvases.values()), timeout=5000)

    computed: list[bytes] = []  # the tubes computed (their keys), in any thread
    compute = slice_overlays.tube_field

    def watched(plane: Plane, pts: np.ndarray, reach: float, step: float) -> object:
        computed.append(slice_overlays.TubeRequest(plane, pts, reach, step).key)
        return compute(plane, pts, reach, step)

    monkeypatch.setattr(slice_overlays, "tube_field", watched)
    passes: dict[str, int] = dict.fromkeys(grid.canvases, 0)
    for name, canvas in grid.canvases.items():
        original = canvas.set_overlays

        def counted(scene: object, name: str = name, original: object = original) -> None:
            passes[name] += 1
            original(scene)  # type: ignore[operator]

        monkeypatch.setattr(canvas, "set_overlays", counted)
    before = {v: (c.kept.full_draws, c.kept.blits) for v, c in grid.canvases.items()}
    plan = window.plan
    assert plan is not None
    grid.set_canal_mode(True)
    axial = grid.canvases["axial"]
    px = axial.lps_to_pixel(plan.target_lps + np.array([2.0, 1.5, 0.0]))
    assert px is not None
    with qtbot.waitSignal(window.path_updated, timeout=30_000):
        qtbot.mouseClick(axial, Qt.MouseButton.LeftButton, pos=QPoint(round(px[0]), round(px[1])))
    settle(qtbot, window)
    assert passes == {"axial": 1, "coronal": 1, "sagittal": 1, "trajectory": 1}
    wanted = {
        v: {
            r.key
            for lm in c.scene.landmarks  # type: ignore[union-attr]
            if (r := _tube_request(c.image, lm)) is not None  # type: ignore[arg-type]
        }
        for v, c in grid.canvases.items()
    }
    assert all(wanted.values())
    assert sorted(computed) == sorted(set().union(*wanted.values()))  # each computed once
    after = {v: (c.kept.full_draws, c.kept.blits) for v, c in grid.canvases.items()}
    assert all(after[v][0] == before[v][0] for v in ORTHO_VIEWS)  # the planes stayed
    assert all(after[v][1] > before[v][1] for v in ORTHO_VIEWS)


def test_an_edit_starts_its_path_before_the_drawing_steps_queued_with_it(qtbot: QtBot) -> None:
    """A 0 ms debounce runs once the events posted before it are served: before the step
    queue's zero-interval timer (the path's worker starts, then the views draw), once for
    several pokes, not at all once cancelled."""
    from ctdrill.app.gui.workers import Debouncer, StepQueue

    order: list[str] = []
    steps = StepQueue()
    debounce = Debouncer(lambda: order.append("path"), 0)
    steps.push(lambda: order.append("step"))  # an edit queues its drawing, then pokes
    debounce.poke()
    debounce.poke()
    assert debounce.pending
    qtbot.waitUntil(lambda: len(order) == 2, timeout=2000)
    qtbot.wait(20)
    assert order == ["path", "step"] and not debounce.pending
    debounce.poke()
    debounce.cancel()
    assert not debounce.pending
    qtbot.wait(20)
    assert order == ["path", "step"]
    debounce.set_interval(5)  # a real delay: the timer, as before
    debounce.poke()
    qtbot.waitUntil(lambda: len(order) == 3, timeout=2000)
    assert order[-1] == "path"
