"""The window's first series drawn, and the work that waits for it: numba and the kernels.

numba's import and its first cache load cost 0.5-0.8 s of CPU, most of it Python holding the
interpreter lock the window's first draws need. The window defers them (:func:`ctdrill.jit.defer`):
its first path, checks and readout run on the kernels' NumPy twins (the same bits: each
kernel not loaded yet gives them as in a one-plan job, :mod:`ctdrill.jit`), and once every
view shows the first series (slices, 3D surface, the path or its refusal, no drawing step
left) the kernels load in a background thread (:func:`ctdrill.jit.release`); each is used
compiled from then on (a drag, a search). Then what lives is frozen for the garbage collector
(:func:`ctdrill.app.gui.preload.freeze_kernels`).
"""

from __future__ import annotations

from typing import Any

from PySide6.QtCore import QObject, QTimer, Signal

from ctdrill import jit
from ctdrill.app.gui.preload import freeze_kernels

#: At the latest this long after the first series arrived, the kernels load even if a view
#: never said it was drawn (a view that failed quietly), ms.
RELEASE_AFTER_MS = 5000
#: How often the window looks whether the kernels have loaded, ms.
LOADED_POLL_MS = 100


class FirstDraw(QObject):
    """Watches ``window`` until every view has drawn its first series, then emits
    :attr:`drawn` and loads the kernels (:func:`ctdrill.jit.release`).

    ``window`` is a :class:`~ctdrill.app.gui.main_window.MainWindow` (its signals
    ``slices_updated``, ``path_updated``, ``path_failed``, its 3D view's ``surface_shown``,
    its controller's ``failed``, its document's ``volume_changed``, its ``ui_steps``).
    """

    drawn = Signal()

    def __init__(self, window: Any) -> None:
        super().__init__(window)
        jit.defer()
        self.window = window
        self.done = False
        self._seen: set[str] = set()
        self._fallback = QTimer(self)
        self._fallback.setSingleShot(True)
        self._fallback.setInterval(RELEASE_AFTER_MS)
        self._fallback.timeout.connect(self._release)
        #: The kernels load on the event loop's next pass after :attr:`drawn` (whatever else
        #: waits for the views drawn runs first); a window closed before never loads them.
        self._load = QTimer(self)
        self._load.setSingleShot(True)
        self._load.setInterval(0)
        self._load.timeout.connect(self._load_kernels)
        #: Polls for the kernels loaded, then freezes what lives (preload.freeze_kernels).
        self._loaded = QTimer(self)
        self._loaded.setInterval(LOADED_POLL_MS)
        self._loaded.timeout.connect(self._kernels_loaded)
        window.doc.volume_changed.connect(self._volume)
        window.slices_updated.connect(lambda: self._arrived("slices"))
        window.path_updated.connect(lambda: self._arrived("path"))
        window.path_failed.connect(lambda _msg: self._arrived("path"))
        window.view3d.surface_shown.connect(lambda: self._arrived("surface"))
        window.controller.failed.connect(self._failed)

    def _volume(self, volume: object) -> None:
        if volume is not None and not self.done and not self._fallback.isActive():
            self._fallback.start()

    def _failed(self, stage: str, _exc: object, _tb: str) -> None:
        if stage == "load":  # nothing to draw: the kernels may load
            self._release()
        elif stage in ("surface", "path"):
            self._arrived(stage)

    def _arrived(self, what: str) -> None:
        self._seen.add(what)
        if self.done or self.window.doc.volume is None:
            return
        wanted = {"slices", "surface"} | ({"path"} if self.window.doc.plan is not None else set())
        if wanted <= self._seen:
            self._drain()

    def _drain(self) -> None:
        """After the drawing steps still queued (the views are drawn when none is left)."""
        if self.done:
            return
        if self.window.ui_steps.pending:
            QTimer.singleShot(1, self._drain)
            return
        self._release()

    def _release(self) -> None:
        if self.done:
            return
        self.done = True
        self._fallback.stop()
        self.drawn.emit()
        self._load.start()

    def _load_kernels(self) -> None:
        jit.release()
        self._loaded.start()

    def _kernels_loaded(self) -> None:
        if jit.deferred():
            return
        self._loaded.stop()
        freeze_kernels()

    def close(self) -> None:
        """The window closes: nothing is deferred any more (nothing loaded for it either)."""
        self._fallback.stop()
        self._loaded.stop()
        loading_due = self._load.isActive()
        self._load.stop()
        if not self.done or loading_due:
            self.done = True
            jit.stop_deferring()
