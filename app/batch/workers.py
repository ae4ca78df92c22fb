"""Running rows here: in this process or on a pool of worker processes, with Ctrl-C and
``kill -9`` handled.

**Ctrl-C** (:class:`Interrupt`): the first stops scheduling; the rows running finish (their
outputs are whole and recorded), rows not started are reported "not run". A second Ctrl-C
cancels the running rows too (worker processes killed; in this process the row is abandoned,
its staging folder removed). Either way the batch then writes its tables and exits 130.
SIGTERM and SIGHUP (``timeout``, systemd, a closed terminal) count as Ctrl-C
(:mod:`ctdrill.interrupts`; exit 143 and 129). Worker processes never see these signals
themselves (they are blocked when the pool starts and ignored in the workers), so no traceback
comes from them and no row is cut mid-write by them.

**kill -9 of the batch** leaves no live process behind: each worker watches the batch process
(a ``pidfd`` where Linux has one, else polling) and kills itself when it is gone, and has the
kernel kill it when its own parent (the forkserver) dies (``PR_SET_PDEATHSIG``). With the
workers gone, the forkserver and multiprocessing's resource tracker see their pipes close and
exit.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import select
import signal
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from typing import TYPE_CHECKING, Any

from ctdrill.app.batch.task import RowOutcome, RowTask, one_line, run_row
from ctdrill.interrupts import INTERRUPT_SIGNALS, Interrupted

if TYPE_CHECKING:
    from multiprocessing.context import BaseContext

#: Modules the forkserver imports once for every worker it forks.
PRELOAD = (
    "ctdrill.app.batch.task",
    "ctdrill.app.batch.workers",
    "ctdrill.app.export_run",
    "ctdrill.app.export_plot",
    "matplotlib.figure",
    "matplotlib.backends.backend_agg",
)
#: How often the scheduling loop looks at Ctrl-C, and a worker without a pidfd at its parent.
POLL_S = 0.2
#: The status of a row not run (never started, or cancelled by a second Ctrl-C).
NOT_RUN = "error: not run (the batch was interrupted)"
_PR_SET_PDEATHSIG = 1

Done = Callable[[RowOutcome], None]


class Interrupt:
    """Ctrl-C during a batch: :attr:`stopping` after the first, :attr:`cancelling` after the
    second. Use as a context manager (the handler is installed in the main thread only)."""

    def __init__(self, *, raise_on_cancel: bool = False) -> None:
        self.count = 0
        #: The first signal's number (0: none yet).
        self.signum = 0
        self.raise_on_cancel = raise_on_cancel
        self._old: Any = None

    @property
    def stopping(self) -> bool:
        """Ctrl-C was pressed: start no more rows."""
        return self.count >= 1

    @property
    def cancelling(self) -> bool:
        """Ctrl-C was pressed twice: cancel the running rows."""
        return self.count >= 2

    def _handle(self, signum: int, frame: object) -> None:
        self.count += 1
        self.signum = self.signum or signum
        if self.cancelling and self.raise_on_cancel:
            raise Interrupted(signum)

    @property
    def exit_code(self) -> int:
        """``128 +`` the first signal's number: 130 Ctrl-C, 143 SIGTERM, 129 SIGHUP."""
        return 128 + (self.signum or int(signal.SIGINT))

    def __enter__(self) -> Interrupt:
        if threading.current_thread() is threading.main_thread():
            self._old = {
                sig: signal.signal(sig, self._handle)
                for sig in INTERRUPT_SIGNALS
                if signal.getsignal(sig) is not signal.SIG_IGN
            }
        return self

    def __exit__(self, *exc: object) -> None:
        if self._old is not None:
            for sig, old in self._old.items():
                signal.signal(sig, old)
            self._old = None


def run_serial(tasks: Sequence[RowTask], on_done: Done, stop: Interrupt) -> None:
    """Run the tasks one after another in this process until Ctrl-C.

    The first Ctrl-C lets the running row finish; a second abandons it (``stop`` raises
    KeyboardInterrupt in it: its staging folder is removed, its earlier output kept).
    """
    stop.raise_on_cancel = True
    for task in tasks:
        if stop.stopping:
            return
        try:
            on_done(run_row(task))
        except KeyboardInterrupt:
            return


def _parent_watch(parent_pid: int) -> None:
    """Kill this process when ``parent_pid`` is gone (runs in a daemon thread)."""
    try:
        fd = os.pidfd_open(parent_pid)
    except (AttributeError, OSError):
        fd = -1
    if fd >= 0:
        select.select([fd], [], [])  # readable when the process has exited
    else:
        while True:
            try:
                os.kill(parent_pid, 0)
            except ProcessLookupError:
                break
            except PermissionError:
                pass
            time.sleep(POLL_S)
    os.kill(os.getpid(), signal.SIGKILL)


def _die_with_parent() -> None:
    """Ask the kernel to kill this process when its parent dies (Linux)."""
    with contextlib.suppress(OSError, AttributeError):
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)


def worker_init(batch_pid: int) -> None:
    """Every worker's initializer: ignore Ctrl-C, die with the forkserver and with the batch."""
    for sig in INTERRUPT_SIGNALS:
        signal.signal(sig, signal.SIG_IGN)
    parent = os.getppid()
    _die_with_parent()
    if os.getppid() != parent:  # the parent died before the request took effect
        os.kill(os.getpid(), signal.SIGKILL)
    threading.Thread(target=_parent_watch, args=(batch_pid,), daemon=True).start()


@contextlib.contextmanager
def sigint_blocked() -> Iterator[None]:
    """SIGINT blocked in this thread meanwhile: processes started now (the forkserver, the
    workers) inherit the block, so the terminal's Ctrl-C never reaches them."""
    if not hasattr(signal, "pthread_sigmask"):
        yield
        return
    old = signal.pthread_sigmask(signal.SIG_BLOCK, set(INTERRUPT_SIGNALS))
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def pool_context() -> BaseContext:
    """A ``forkserver`` context (imports the export once: :data:`PRELOAD`), started with
    SIGINT blocked; ``spawn`` where there is no forkserver."""
    import multiprocessing

    if "forkserver" not in multiprocessing.get_all_start_methods():
        return multiprocessing.get_context("spawn")
    from multiprocessing import forkserver, resource_tracker

    server = multiprocessing.get_context("forkserver")
    server.set_forkserver_preload(list(PRELOAD))
    # the resource tracker first: starting it unblocks SIGINT and SIGTERM in this thread
    # (multiprocessing's own block around its start), which would let them reach the
    # forkserver's preload imports (a KeyboardInterrupt traceback, then EOFError here)
    resource_tracker.ensure_running()
    with sigint_blocked():
        forkserver.ensure_running()
    return server


def _kill_workers(pool: Any) -> None:
    for proc in list(getattr(pool, "_processes", {}).values()):
        with contextlib.suppress(OSError, ValueError):
            proc.kill()


def run_processes(tasks: Sequence[RowTask], workers: int, on_done: Done, stop: Interrupt) -> None:
    """Run the tasks on a pool of ``workers`` processes until Ctrl-C.

    At most ``workers`` rows are handed to the pool at a time, so a Ctrl-C waits for the
    rows running and no more. A worker process that dies (killed, out of memory, a crash in
    a library) breaks the pool: the rows it held are run again each in a pool of its own (a
    row that kills that one too is reported failed) and a new pool takes the rest; the batch
    goes on (not after Ctrl-C: those rows are "not run").
    """
    from concurrent.futures import ProcessPoolExecutor
    from concurrent.futures.process import BrokenProcessPool

    ctx = pool_context()
    queue = list(tasks)
    broken: list[RowTask] = []
    while queue and not stop.stopping:
        left = len(queue)
        _run_pool(queue, workers, ctx, on_done, stop, broken)
        if len(queue) == left and queue:  # the pool broke before taking a row
            broken.append(queue.pop(0))
    for task in broken:
        if stop.stopping:
            return
        with ProcessPoolExecutor(
            max_workers=1, mp_context=ctx, initializer=worker_init, initargs=(os.getpid(),)
        ) as alone:
            try:
                outcome = alone.submit(run_row, task).result()
            except BrokenProcessPool:
                outcome = RowOutcome(
                    row=task.row,
                    status="error: the worker process running this row died (killed, out of "
                    "memory or crashed); run the row alone with ctdrill export to see why",
                    seconds=0.0,
                )
        on_done(outcome)


def _run_pool(
    queue: list[RowTask],
    workers: int,
    ctx: BaseContext,
    on_done: Done,
    stop: Interrupt,
    broken: list[RowTask],
) -> None:
    """Run rows from ``queue`` (taken as they start) on one pool until it breaks or Ctrl-C;
    rows whose worker died go to ``broken``."""
    from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
    from concurrent.futures.process import BrokenProcessPool

    with ProcessPoolExecutor(
        max_workers=workers, mp_context=ctx, initializer=worker_init, initargs=(os.getpid(),)
    ) as pool:
        pending: dict[Future[RowOutcome], RowTask] = {}
        healthy = True
        while (queue and healthy and not stop.stopping) or pending:
            while queue and healthy and len(pending) < workers and not stop.stopping:
                try:
                    with sigint_blocked():  # a worker started now never sees Ctrl-C
                        fut = pool.submit(run_row, queue[0])
                except BrokenProcessPool:
                    healthy = False
                    break
                pending[fut] = queue.pop(0)
            if stop.cancelling:
                _kill_workers(pool)
            if not pending:
                break
            finished, _ = wait(pending, timeout=POLL_S, return_when=FIRST_COMPLETED)
            for fut in finished:
                task = pending.pop(fut)
                try:
                    outcome = fut.result()
                except BrokenProcessPool:
                    healthy = False
                    if not stop.stopping:
                        broken.append(task)
                    continue
                except Exception as exc:  # the task could not be sent or its result read
                    outcome = RowOutcome(
                        row=task.row,
                        status=one_line(
                            f"error: internal error (a bug, please report it): "
                            f"{type(exc).__name__}: {exc}"
                        ),
                        seconds=0.0,
                    )
                on_done(outcome)
