"""A series replaced by another is released at once (by reference counting): no finished job
keeps its closure, and with it the whole CT, until a full garbage collection finds it."""

from __future__ import annotations

import gc
import weakref

import pytest
from pytestqt.qtbot import QtBot

from ctdrill.app.gui.main_window import MainWindow
from ctdrill.app.gui.workers import Job
from ctdrill.imaging.phantom.io import PhantomCase
from tests.app.gui.helpers import LOAD_TIMEOUT_MS, open_case

pytestmark = pytest.mark.gui


def test_a_job_lets_go_of_its_function_once_it_ran() -> None:
    class Held:
        pass

    held = Held()
    alive = weakref.ref(held)
    job = Job(lambda h=held: type(h).__name__, 1)  # type: ignore[misc]
    del held
    job.run()
    assert alive() is None  # the job object kept, what its function held released


def test_the_previous_series_is_released_when_another_opens(
    qtbot: QtBot, window: MainWindow, phantom_case: PhantomCase
) -> None:
    open_case(qtbot, window, phantom_case)
    old = weakref.ref(window.doc.volume)
    assert old() is not None
    gc.collect()
    gc.disable()
    try:
        window.open_folder(phantom_case.ct_dir)
        qtbot.waitUntil(
            lambda: window.doc.volume is not None and window.doc.volume is not old(),
            timeout=LOAD_TIMEOUT_MS,
        )
        qtbot.waitUntil(window.view3d.surface_is_shown, timeout=LOAD_TIMEOUT_MS)
        qtbot.waitUntil(lambda: old() is None, timeout=5000)  # without a collection
    finally:
        gc.enable()


def test_the_kernels_freeze_comes_once_and_only_after_the_imports_froze(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from ctdrill.app.gui import preload

    frozen: list[int] = []
    monkeypatch.setattr(preload.gc, "freeze", lambda: frozen.append(1))
    monkeypatch.setattr(preload, "_FROZE", [False])
    monkeypatch.setattr(preload, "_KERNELS_FROZEN", [False])
    assert not preload.freeze_kernels() and frozen == []  # a process that did not freeze them
    preload._FROZE[0] = True
    assert preload.freeze_kernels() and frozen == [1]
    assert not preload.freeze_kernels() and frozen == [1]  # once a process
