"""SIGTERM and SIGHUP taken as Ctrl-C: a closed terminal, ``timeout`` or systemd end a command
as Ctrl-C does, its records written.

Python turns SIGINT into :class:`KeyboardInterrupt`; :func:`install` (``ctdrill``'s ``main``)
turns SIGTERM and SIGHUP into :class:`Interrupted`, a ``KeyboardInterrupt`` that names its
signal, so every path that handles Ctrl-C (the rehearsal's STOP and DISARM and its
``summary.json``, the batch's ``status.csv``, an output folder's staging removed) handles them
the same way. The exit code is ``128 + signal number``, the shells' convention: 130 for
SIGINT, 143 for SIGTERM, 129 for SIGHUP (:func:`exit_code_of`).

While records are being written after an interrupt, :func:`held` records further signals
instead of raising them (a second SIGTERM from systemd, an impatient Ctrl-C), so that the
records appear whole.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator
from types import FrameType
from typing import Any

#: The signals taken as Ctrl-C.
INTERRUPT_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


class Interrupted(KeyboardInterrupt):
    """A terminating signal taken as Ctrl-C; ``signum`` names it."""

    def __init__(self, signum: int) -> None:
        super().__init__(signal_name(signum))
        self.signum = signum


def signal_name(signum: int) -> str:
    """``SIGTERM`` for 15, and so on."""
    try:
        return signal.Signals(signum).name
    except ValueError:
        return f"signal {signum}"


def signum_of(exc: BaseException) -> int:
    """The signal behind an interrupt (SIGINT for a plain ``KeyboardInterrupt``)."""
    return exc.signum if isinstance(exc, Interrupted) else int(signal.SIGINT)


def exit_code_of(exc: BaseException) -> int:
    """``128 + signal number``: 130 for Ctrl-C, 143 for SIGTERM, 129 for SIGHUP."""
    return 128 + signum_of(exc)


def exit_code_for_signal(name: str | None) -> int:
    """The exit code of an interrupt recorded by its signal's name (None: SIGINT)."""
    try:
        return 128 + int(signal.Signals[name or "SIGINT"])
    except KeyError:
        return 128 + int(signal.SIGINT)


def _raise(signum: int, frame: FrameType | None) -> None:
    raise Interrupted(signum)


def install() -> None:
    """Make SIGTERM and SIGHUP raise :class:`Interrupted` in the main thread (SIGINT keeps
    Python's ``KeyboardInterrupt``). Signals set to be ignored (``nohup``) stay ignored."""
    if threading.current_thread() is not threading.main_thread():
        return
    for sig in (signal.SIGTERM, signal.SIGHUP):
        if signal.getsignal(sig) is not signal.SIG_IGN:
            signal.signal(sig, _raise)


def uninstall() -> None:
    """Give SIGTERM and SIGHUP back their default action (the window: a Qt event loop)."""
    if threading.current_thread() is not threading.main_thread():
        return
    for sig in (signal.SIGTERM, signal.SIGHUP):
        if signal.getsignal(sig) is _raise:
            signal.signal(sig, signal.SIG_DFL)


class Holding:
    """The signals :func:`held` recorded (:attr:`caught`), and a way to let them through
    for a while (:meth:`released`)."""

    def __init__(self) -> None:
        self.caught: list[int] = []
        self._previous: dict[int, Any] = {}

    def _record(self, signum: int, frame: FrameType | None) -> None:
        self.caught.append(signum)

    def _hold(self) -> None:
        for sig in self._previous:
            signal.signal(sig, self._record)

    def _restore(self) -> None:
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)

    @contextlib.contextmanager
    def released(self) -> Iterator[None]:
        """Meanwhile the signals act as before :func:`held` (e.g. a session that handles
        its own interrupt)."""
        self._restore()
        try:
            yield
        finally:
            self._hold()


@contextlib.contextmanager
def held(*, reraise: bool = True) -> Iterator[Holding]:
    """Meanwhile, SIGINT, SIGTERM and SIGHUP are recorded (:attr:`Holding.caught`), not
    raised; on leaving, the first recorded is raised as :class:`Interrupted` (``reraise``) or
    dropped. Outside the main thread it does nothing."""
    holding = Holding()
    if threading.current_thread() is not threading.main_thread():
        yield holding
        return
    for sig in INTERRUPT_SIGNALS:
        current = signal.getsignal(sig)
        if current is not signal.SIG_IGN:
            holding._previous[sig] = current
    holding._hold()
    try:
        yield holding
    finally:
        holding._restore()
    if holding.caught and reraise:
        raise Interrupted(holding.caught[0])
