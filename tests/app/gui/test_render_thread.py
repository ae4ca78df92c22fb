"""The 3D view's render thread: frames drawn off the UI thread show the scene, the UI thread
never renders, a burst of changes draws the last one, and closing stops the thread."""

from __future__ import annotations

import threading
import time
from typing import Any

import numpy as np
import pytest
from pytestqt.qtbot import QtBot

from ctdrill.app.gui.camera import CameraPose
from ctdrill.app.gui.render_thread import Frame, RenderThread
from ctdrill.app.gui.screenshot import qimage_to_rgb

pytestmark = pytest.mark.gui

#: Looking at the origin from 100 mm in front (-y), superior up: a sphere of 20 mm radius
#: there fills the centre of the frame (30 degrees of view: 53.6 mm tall at that distance).
FRONT = CameraPose(np.array([0.0, -100.0, 0.0]), np.zeros(3), np.array([0.0, 0.0, 1.0]))


def _ball(
    colour: tuple[float, float, float], centre: tuple[float, float, float] = (0, 0, 0)
) -> Any:
    def add(stage: Any) -> None:
        import pyvista as pv

        stage.add_mesh(pv.Sphere(radius=20.0, center=centre), name="ball", color=colour)
        stage.unlit()  # flat: the pixels are the colour itself

    return add


def _frames(qtbot: QtBot, rt: RenderThread) -> list[Frame]:
    got: list[Frame] = []
    rt.frame_ready.connect(got.append)
    return got


def _wait_idle(qtbot: QtBot, rt: RenderThread, got: list[Frame]) -> None:
    qtbot.waitUntil(lambda: bool(got) and got[-1].seq == rt.seq, timeout=20_000)


def test_a_frame_drawn_on_the_render_thread_shows_the_scene_where_the_camera_puts_it(
    qtbot: QtBot,
) -> None:
    rt = RenderThread((160, 120))
    try:
        got = _frames(qtbot, rt)
        renders: list[int] = []
        rt.submit(
            lambda st: st.window.AddObserver(
                "StartEvent", lambda *_: renders.append(threading.get_ident())
            ),
            frame=False,
        )
        rt.set_size((160, 120))
        rt.submit(_ball((1.0, 0.0, 0.0), centre=(30.0, 0.0, 0.0)))  # right of the centre
        rt.set_camera(FRONT)
        _wait_idle(qtbot, rt, got)
        image = next(f.image for f in reversed(got) if f.image is not None)
        assert (image.width(), image.height()) == (160, 120)
        rgb = qimage_to_rgb(image).astype(int)
        # 30 mm to the patient's left (+x) is on the right of the screen seen from the front
        # (LPS: the viewer faces posterior, so left is at screen right)
        px_per_mm = 120 / (2 * 100.0 * np.tan(np.radians(15.0)))
        x = round(80 + 30.0 * px_per_mm)
        assert tuple(rgb[60, x]) == (255, 0, 0)
        assert tuple(rgb[60, 80 - 40]) != (255, 0, 0)  # the other side: background
        # every render ran on the render thread, none on this (the UI) thread
        assert renders and set(renders) == {rt.render_thread.ident}  # type: ignore[union-attr]
        assert threading.get_ident() not in renders
        assert rt.call(lambda st: st.thread) is rt.render_thread
    finally:
        rt.stop()
    assert rt.render_thread is not None and not rt.render_thread.is_alive()


def test_a_burst_of_scene_changes_draws_the_last_one_once(qtbot: QtBot) -> None:
    rt = RenderThread((64, 48))
    try:
        got = _frames(qtbot, rt)
        rt.set_camera(FRONT)
        builds: list[int] = []
        release = threading.Event()
        rt.submit(lambda _st: release.wait(10.0), frame=False)  # the thread busy meanwhile
        colours = [(i / 20.0, 1.0 - i / 20.0, 0.0) for i in range(21)]
        for i, colour in enumerate(colours):
            add = _ball(colour)

            def build(st: Any, i: int = i, add: Any = add) -> None:
                builds.append(i)
                add(st)

            rt.submit(build, key="scene")
        release.set()
        _wait_idle(qtbot, rt, got)
        assert builds == [20]  # the stale scenes never built
        drawn = [f for f in got if f.image is not None]
        assert len(drawn) == 1  # one frame for the whole burst
        rgb = qimage_to_rgb(drawn[0].image).astype(int)  # type: ignore[arg-type]
        np.testing.assert_allclose(rgb[24, 32], np.array(colours[-1]) * 255, atol=2)
    finally:
        rt.stop()


def test_stopping_joins_the_thread_and_drops_what_is_queued(qtbot: QtBot) -> None:
    rt = RenderThread((64, 48))
    ran: list[int] = []
    release = threading.Event()
    rt.submit(lambda _st: release.wait(10.0), frame=False)
    rt.submit(lambda _st: ran.append(1))
    threading.Timer(0.2, release.set).start()
    t0 = time.perf_counter()
    rt.stop()
    assert time.perf_counter() - t0 < 5.0
    assert rt.render_thread is not None and not rt.render_thread.is_alive() and rt.stage is None
    assert ran == []


def test_without_a_thread_the_ui_thread_renders_the_same(qtbot: QtBot) -> None:
    rt = RenderThread((64, 48), threaded=False)
    try:
        got = _frames(qtbot, rt)
        rt.set_camera(FRONT)
        rt.submit(_ball((0.0, 0.0, 1.0)))
        _wait_idle(qtbot, rt, got)
        assert rt.render_thread is None
        image = next(f.image for f in reversed(got) if f.image is not None)
        assert tuple(qimage_to_rgb(image)[24, 32]) == (0, 0, 255)
    finally:
        rt.stop()


def test_the_window_draws_its_3d_frames_off_the_ui_thread_and_stops_the_thread_on_close(
    qtbot: QtBot, window: Any, phantom_case: Any
) -> None:
    from PySide6.QtCore import QPoint, Qt
    from PySide6.QtWidgets import QWidget

    from tests.app.gui.helpers import LOAD_TIMEOUT_MS, open_case

    view = window.view3d
    renders: list[int] = []
    view.rt.call(
        lambda st: st.window.AddObserver(
            "StartEvent", lambda *_: renders.append(threading.get_ident())
        )
    )
    open_case(qtbot, window, phantom_case)
    qtbot.waitUntil(lambda: not view.busy and window.ui_steps.pending == 0, timeout=LOAD_TIMEOUT_MS)
    thread = view.rt.render_thread
    assert thread is not None and thread is not threading.main_thread()
    assert renders and set(renders) == {thread.ident}
    # no OpenGL widget in the window: Qt composes it without OpenGL
    assert not any("OpenGL" in type(w).__name__ for w in window.findChildren(QWidget))
    # a drag with the left button turns the camera about the target; a frame follows
    before, frames = view.camera, view.frames_drawn
    assert before is not None
    centre = view.rect().center()
    qtbot.mousePress(view, Qt.MouseButton.LeftButton, pos=centre)
    qtbot.mouseMove(view, centre + QPoint(40, 0))
    qtbot.mouseRelease(view, Qt.MouseButton.LeftButton, pos=centre + QPoint(40, 0))
    qtbot.waitUntil(lambda: not view.busy and view.frames_drawn > frames, timeout=LOAD_TIMEOUT_MS)
    after = view.camera
    np.testing.assert_allclose(after.focal_lps, before.focal_lps)
    assert after.distance_mm == pytest.approx(before.distance_mm)
    assert not np.allclose(after.position_lps, before.position_lps)
    assert set(renders) == {thread.ident}
    # the frames follow the view's size, in device pixels
    window.resize(window.width() - 120, window.height() - 60)
    dpr = view.devicePixelRatioF()

    def sized() -> bool:
        image = view._image
        size = (round(view.width() * dpr), round(view.height() * dpr))
        return not view.busy and image is not None and (image.width(), image.height()) == size

    qtbot.waitUntil(sized, timeout=LOAD_TIMEOUT_MS)
    window.close()
    assert not thread.is_alive()


def test_without_egl_the_view_falls_back_to_the_ui_thread(
    qtbot: QtBot, monkeypatch: pytest.MonkeyPatch
) -> None:
    from ctdrill.app.gui import stage as stage_module

    monkeypatch.setattr(stage_module, "egl_render_window", lambda: None)
    rt = RenderThread((64, 48))
    try:
        got = _frames(qtbot, rt)
        rt.set_camera(FRONT)
        rt.submit(_ball((0.0, 1.0, 0.0)))
        _wait_idle(qtbot, rt, got)
        assert not rt.threaded and rt.render_thread is None  # no EGL: the UI thread draws
        assert rt.stage is not None and rt.stage.thread is threading.current_thread()
        image = next(f.image for f in reversed(got) if f.image is not None)
        assert tuple(qimage_to_rgb(image)[24, 32]) == (0, 255, 0)
    finally:
        rt.stop()
