"""Run headless work off the UI thread and hand the result back on it.

A :class:`Job` wraps a plain function; its ``done`` / ``failed`` signals are delivered on the
thread that owns the job's signal object (the UI thread), queued. Each job carries a
generation number so a stale result (the user moved the target again, or cancelled) is dropped
by the receiver instead of being drawn.
"""

from __future__ import annotations

import traceback
from collections import deque
from collections.abc import Callable
from typing import Any

from PySide6.QtCore import QCoreApplication, QEvent, QObject, QRunnable, QThreadPool, QTimer, Signal


class JobSignals(QObject):
    """Signals of one job: ``done(generation, result)`` or ``failed(generation, exc, tb)``."""

    done = Signal(int, object)
    failed = Signal(int, object, str)


def _ran() -> None:
    """What a job holds once it ran (its function released)."""
    raise RuntimeError("this job has run")


class Job(QRunnable):
    """Call ``fn()`` in the thread pool and emit its result."""

    def __init__(self, fn: Callable[[], Any], generation: int) -> None:
        super().__init__()
        self.fn = fn
        self.generation = generation
        self.signals = JobSignals()
        self.setAutoDelete(True)

    def run(self) -> None:  # runs in a pool thread
        # the function (and what it holds: a volume, a plan) goes with the run: PySide keeps
        # the started runnable referenced, and a closure kept with it held a whole CT after
        # another series opened, until a full garbage collection found it
        fn, self.fn = self.fn, _ran
        try:
            try:
                result = fn()
            except Exception as exc:  # delivered to the UI, which decides what is bad input
                del fn
                self.signals.failed.emit(self.generation, exc, traceback.format_exc())
                return
            del fn
            self.signals.done.emit(self.generation, result)
        except RuntimeError:  # the receiver was destroyed (window closed): nobody to tell
            return


class Runner(QObject):
    """Latest-wins runner: ``submit`` starts a job and invalidates every earlier one.

    ``on_done(result)`` and ``on_failed(exc, tb)`` are called on the UI thread, only for the
    latest job; ``cancel()`` drops whatever is running. ``busy`` is True while the latest job
    runs.
    """

    def __init__(
        self,
        on_done: Callable[[Any], None],
        on_failed: Callable[[BaseException, str], None],
        *,
        pool: QThreadPool | None = None,
        parent: QObject | None = None,
    ) -> None:
        super().__init__(parent)
        self._on_done = on_done
        self._on_failed = on_failed
        self._pool = pool if pool is not None else QThreadPool.globalInstance()
        self._generation = 0
        self._running: set[int] = set()
        self._keep: dict[int, Job] = {}
        #: Coalescing (:meth:`submit_latest`): the job to start when the running one reports.
        self._next: Callable[[], Any] | None = None

    @property
    def busy(self) -> bool:
        """True while the latest submitted job has not reported (or one waits to start)."""
        return self._generation in self._running or self._next is not None

    def submit(self, fn: Callable[[], Any]) -> int:
        """Start ``fn`` in the pool; returns its generation."""
        self._generation += 1
        gen = self._generation
        job = Job(fn, gen)
        job.signals.done.connect(self._done)
        job.signals.failed.connect(self._failed)
        self._running.add(gen)
        self._keep[gen] = job  # keep the signal object alive until it reports
        self._pool.start(job)
        return gen

    def submit_latest(self, fn: Callable[[], Any]) -> None:
        """Run ``fn`` as soon as no job of this runner runs: now when idle, else right after
        the running one, replacing any job waiting. One job at a time, never a queue of stale
        ones, and every finished job reports: a drag that outpaces the computation sees each
        result as it comes, the latest plan computed next."""
        if self._running:
            self._next = fn
        else:
            self.submit(fn)

    def cancel(self) -> None:
        """Forget the running job: its result will be dropped."""
        self._generation += 1
        self._next = None

    def _finish(self, gen: int) -> bool:
        self._running.discard(gen)
        self._keep.pop(gen, None)
        latest = gen == self._generation
        if self._next is not None and not self._running:
            fn, self._next = self._next, None
            self.submit(fn)
        return latest

    def _done(self, gen: int, result: object) -> None:
        if self._finish(gen):
            self._on_done(result)

    def _failed(self, gen: int, exc: object, tb: str) -> None:
        if self._finish(gen) and isinstance(exc, BaseException):
            self._on_failed(exc, tb)


class Debouncer(QObject):
    """Call ``fn`` once, ``delay_ms`` after the last ``poke()``; at 0 ms, once the events
    posted before it are served (a posted event, handled before the zero-interval timers of
    the drawing steps queued with the edit: the computation starts before them, not after)."""

    def __init__(self, fn: Callable[[], None], delay_ms: int, parent: QObject | None = None):
        super().__init__(parent)
        self._fn = fn
        self._posted = False
        self._timer = QTimer(self)
        self._timer.setSingleShot(True)
        self._timer.setInterval(delay_ms)
        self._timer.timeout.connect(fn)

    def poke(self) -> None:
        """(Re)start the delay."""
        if self._timer.interval() > 0:
            self._timer.start()
        elif not self._posted:
            self._posted = True
            QCoreApplication.postEvent(self, QEvent(_FIRE))

    def event(self, event: QEvent) -> bool:
        if event.type() == _FIRE:
            if self._posted:  # not cancelled meanwhile
                self._posted = False
                self._fn()
            return True
        return super().event(event)

    def set_interval(self, delay_ms: int) -> None:
        """Wait ``delay_ms`` after the last poke from now on."""
        self._timer.setInterval(delay_ms)

    def cancel(self) -> None:
        """Drop a scheduled call."""
        self._timer.stop()
        self._posted = False

    @property
    def pending(self) -> bool:
        """True while a call is scheduled."""
        return self._timer.isActive() or self._posted


#: The event a 0 ms :class:`Debouncer` posts to itself.
_FIRE = QEvent.Type(QEvent.registerEventType())


class StepQueue(QObject):
    """Run queued UI-thread steps one per event-loop pass, in order.

    A zero-interval timer runs one step per timeout, so the events and timers that fall due
    in between (paints, input, other timers) are served between two steps instead of after
    all of them: the UI thread is held for the longest single step, not for their sum.
    """

    def __init__(self, parent: QObject | None = None) -> None:
        super().__init__(parent)
        self._steps: deque[Callable[[], None]] = deque()
        self._held: set[object] = set()
        self._timer = QTimer(self)
        self._timer.setInterval(0)
        self._timer.timeout.connect(self._step)

    def push(self, fn: Callable[[], None], *, first: bool = False) -> None:
        """Queue ``fn()`` after every step queued before it (``first``: before them)."""
        if first:
            self._steps.appendleft(fn)
        else:
            self._steps.append(fn)
        if not self._timer.isActive():
            self._timer.start()

    @property
    def pending(self) -> int:
        """Number of steps not run yet, and of drawings held back (:meth:`hold`)."""
        return len(self._steps) + len(self._held)

    def hold(self, key: object) -> None:
        """A drawing to be queued later (it waits for a result) counts as pending until
        :meth:`release` (the window is not drawn before it)."""
        self._held.add(key)

    def release(self, key: object) -> None:
        """The held drawing ``key`` was queued (or is no longer due)."""
        self._held.discard(key)

    def _step(self) -> None:
        if not self._steps:
            self._timer.stop()
            return
        fn = self._steps.popleft()
        if not self._steps:
            self._timer.stop()
        fn()


class RunnerGroup:
    """Several runners seen as one (the slice views' one per view)."""

    def __init__(self, runners: dict[str, Runner]) -> None:
        self._runners = runners

    @property
    def busy(self) -> bool:
        """True while any of them runs."""
        return any(r.busy for r in self._runners.values())

    def cancel(self) -> None:
        """Drop every running job."""
        for r in self._runners.values():
            r.cancel()
