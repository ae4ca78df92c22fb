"""The 3D view's render thread: one per view, owning a :class:`~ctdrill.app.gui.stage.Stage` (an
off-screen EGL render window) and everything VTK in the view's scene.

The UI thread never touches VTK's OpenGL: it sends work items (:meth:`RenderThread.submit`: a
function run on the render thread with the stage, e.g. a piece of the bone surface added or the
plan's actors rebuilt), the camera (:meth:`RenderThread.set_camera`) and the frame size; the
thread runs what is queued, renders one frame and hands it back as a ``QImage`` (a copy) through
the :attr:`RenderThread.frame_ready` signal. Items sent under the same ``key`` replace the one
still queued (the latest scene, camera or size wins) and a frame is drawn once for everything
queued while the previous one rendered: frames never queue up behind a burst of changes.

VTK's Python wrappers release the interpreter lock while a frame renders, so the UI thread runs
on meanwhile. The thread (and the software rasteriser's threads it starts) runs at the window's
own priority: lowered (nice 10), a frame got about 5 % of a core beside two busy processes on
2 cores, and a canal click settled in 460 ms instead of 132 ms; idle, the window's drawing is no
slower for it (a canal click 86 ms either way, the longest stall and the drag unchanged). Where
EGL cannot be had (no ``libEGL``), the same items run on the UI thread, one batch per event-loop
pass, with VTK's default off-screen window.
"""

from __future__ import annotations

import atexit
import contextlib
import threading
import time
import traceback
import weakref
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from PySide6.QtCore import QObject, QTimer, Signal
from PySide6.QtGui import QImage

#: Render threads alive, stopped at interpreter exit if their view was never closed.
_LIVE: weakref.WeakSet[RenderThread] = weakref.WeakSet()


@dataclass
class _Item:
    fn: Callable[[Any], Any] | None
    key: str | None
    frame: bool
    seq: int
    then: Callable[[Any], None] | None = None


@dataclass
class Frame:
    """A finished frame: ``image`` (RGBA, ``size_px`` device pixels) covering every item up to
    ``seq``; ``render_s`` the render's duration on the render thread (nan: no frame drawn, the
    items needed none); ``done``: the callbacks of those items with their results."""

    image: QImage | None
    seq: int
    render_s: float
    done: list[tuple[Callable[[Any], None], Any]] = field(default_factory=list)


class RenderThread(QObject):
    """The render thread of one 3D view (see the module's docstring).

    Signals
    -------
    frame_ready(Frame) : emitted from the render thread, received on the UI thread.
    """

    frame_ready = Signal(object)
    _fell_back = Signal()

    def __init__(self, size_px: tuple[int, int] = (400, 300), *, threaded: bool = True) -> None:
        super().__init__()
        self._cond = threading.Condition()
        self._items: list[_Item] = []
        self._seq = 0
        self._stop = False
        self._size = size_px
        self._camera: Any = None  # the latest CameraPose sent
        self._camera_applied: Any = None
        #: The stage, created on (and only used from) the render thread.
        self.stage: Any = None
        self.rendering = False
        self.errors: list[str] = []
        self.threaded = threaded
        self._pass_queued = False
        self._thread: threading.Thread | None = None
        self._fell_back.connect(self._fall_back)
        if threaded:
            self._thread = threading.Thread(target=self._run, name="ctdrill-3d-render", daemon=True)
            _LIVE.add(self)
            self._thread.start()
        else:
            self._make_stage()

    # ------------------------------------------------------------------ UI thread
    @property
    def seq(self) -> int:
        """Number of the last item sent."""
        return self._seq

    @property
    def render_thread(self) -> threading.Thread | None:
        """The thread that owns the stage (None: the UI thread renders)."""
        return self._thread if self.threaded else None

    def submit(
        self,
        fn: Callable[[Any], Any] | None,
        *,
        key: str | None = None,
        frame: bool = True,
        then: Callable[[Any], None] | None = None,
    ) -> int:
        """Run ``fn(stage)`` on the render thread (None: nothing, only the frame), then draw a
        frame when ``frame``; ``then(result)`` runs on the UI thread once that frame (or the
        item, without one) arrived. An item of the same ``key`` still queued is replaced.
        Returns the item's number (:attr:`Frame.seq` covers it once done)."""
        with self._cond:
            self._seq += 1
            item = _Item(fn, key, frame, self._seq, then)
            if key is not None:
                self._items = [i for i in self._items if i.key != key]
            self._items.append(item)
            self._cond.notify()
            seq = self._seq
        if not self.threaded and not self._pass_queued:
            self._pass_queued = True
            QTimer.singleShot(0, self._inline_pass)
        return seq

    def set_camera(self, pose: Any) -> int:
        """Draw the next frame from ``pose`` (a ``CameraPose``; the latest one wins)."""
        with self._cond:
            self._camera = pose
        return self.submit(None, key="camera")

    def set_size(self, size_px: tuple[int, int]) -> int:
        """Draw frames of ``size_px`` (width, height) device pixels from now on."""
        with self._cond:
            self._size = (max(int(size_px[0]), 1), max(int(size_px[1]), 1))
        return self.submit(None, key="size")

    def call(self, fn: Callable[[Any], Any], timeout_s: float = 60.0) -> Any:
        """``fn(stage)`` run on the render thread after what is queued, its result (the
        caller waits: for benchmarks, tests and screenshots, never for the window's own
        work). Raises ``TimeoutError`` after ``timeout_s``, and what ``fn`` raised."""
        if not self.threaded:
            self._inline_pass()
            return fn(self.stage)
        done = threading.Event()
        box: dict[str, Any] = {}

        def run(stage: Any) -> None:
            try:
                box["result"] = fn(stage)
            except BaseException as exc:
                box["error"] = exc
            finally:
                done.set()

        self.submit(run, frame=False)
        if not done.wait(timeout_s):
            raise TimeoutError(f"the 3D view's render thread did not answer in {timeout_s} s")
        if "error" in box:
            raise box["error"]
        return box.get("result")

    def stop(self, timeout_s: float = 10.0) -> None:
        """Drop what is queued, release the stage on its thread and end the thread."""
        if self.threaded:
            self._stop_thread(timeout_s)
        elif self.stage is not None:
            self.stage.close()
            self.stage = None

    def _stop_thread(self, timeout_s: float = 10.0) -> None:
        with self._cond:
            self._stop = True
            self._items = []
            self._cond.notify()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout_s)
        _LIVE.discard(self)

    def _fall_back(self) -> None:
        """No EGL on the render thread (it ended without touching the queue): render on the
        UI thread from now on."""
        if not self.threaded or self._stop:
            return
        self.threaded = False
        _LIVE.discard(self)
        self._make_stage()
        self._inline_pass()

    def _inline_pass(self) -> None:
        self._pass_queued = False
        if self.stage is None:
            return
        with self._cond:
            batch, self._items = self._items, []
        if batch:
            self._deliver(self._work(batch))

    def _deliver(self, frame: Frame) -> None:
        with contextlib.suppress(RuntimeError):  # the view is gone (closed while rendering)
            self.frame_ready.emit(frame)

    # ------------------------------------------------------------------ render thread
    def _make_stage(self) -> None:
        from ctdrill.app.gui.stage import Stage, egl_render_window

        window = egl_render_window() if self.threaded else None
        if self.threaded and window is None:
            return
        self.stage = Stage(self._size, window=window)

    def _run(self) -> None:
        try:
            self._make_stage()
        except Exception:
            self.errors.append(traceback.format_exc())
        if self.stage is None or not self.stage.egl:
            self.stage = None
            with contextlib.suppress(RuntimeError):
                self._fell_back.emit()
            return
        try:
            while True:
                with self._cond:
                    while not self._items and not self._stop:
                        self._cond.wait()
                    if self._stop:
                        break
                    batch, self._items = self._items, []
                frame = self._work(batch)
                if self._stop:
                    break
                self._deliver(frame)
        finally:
            self.stage.close()
            self.stage = None

    def _work(self, batch: list[_Item]) -> Frame:
        """Run ``batch`` on the stage, then draw a frame if any item wants one."""
        stage = self.stage
        done: list[tuple[Callable[[Any], None], Any]] = []
        wanted = False
        for item in batch:
            if self._stop:  # closing: the rest is dropped
                return Frame(None, 0, float("nan"))
            result = None
            if item.fn is not None:
                try:
                    result = item.fn(stage)
                except Exception:
                    self.errors.append(traceback.format_exc())
            wanted = wanted or item.frame
            if item.then is not None:
                done.append((item.then, result))
        seq = max(i.seq for i in batch)
        if not wanted or self._stop:
            return Frame(None, seq, float("nan"), done)
        self.rendering = True
        try:
            render_s = self.render_once(stage)
            rgba = stage.rgba()
        finally:
            self.rendering = False
        h, w = rgba.shape[:2]
        image = QImage(rgba.data, w, h, 4 * w, QImage.Format.Format_RGBA8888).copy()
        return Frame(image, seq, render_s, done)

    def render_once(self, stage: Any) -> float:
        """Draw one frame on the render thread (inside a work item), its duration, s."""
        with self._cond:
            size, camera = self._size, self._camera
        stage.set_size(size)
        if camera is not None and camera is not self._camera_applied:
            from ctdrill.app.gui.camera import apply_camera

            apply_camera(stage, camera)
            self._camera_applied = camera
        t0 = time.perf_counter()
        stage.render()
        return time.perf_counter() - t0


def stop_all() -> None:
    """Stop every render thread still alive (at interpreter exit)."""
    for rt in list(_LIVE):
        rt.stop(timeout_s=2.0)


atexit.register(stop_all)
