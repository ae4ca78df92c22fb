"""Run the device emulator at real time on a file descriptor (a pty master): ``ctdrill emulate``.

Device time is 10 kHz ticks on the monotonic clock: each wakeup (about every millisecond) reads
what the host wrote, runs the ticks that have come due in one batch, writes the device's frames
and sleeps. A tick's *lateness* is how long after its due time it ran; a wakeup that finds more
than :data:`OVERRUN_S` of ticks due counts as an overrun (reported in TELEMETRY). After a stall
longer than :data:`RESYNC_S` the clock is resynchronised instead of replaying the backlog.
"""

from __future__ import annotations

import contextlib
import os
import select
import signal
import time
import tty
from collections import deque
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

from ctdrill.haptics.emulator import DeviceEmulator
from ctdrill.haptics.errors import HapticsInputError

OVERRUN_S = 0.005
RESYNC_S = 0.5
WAKE_S = 0.001


class PtyLinkError(HapticsInputError):
    """The pty link path cannot be created."""


@dataclass
class RealtimeStats:
    """What the real-time loop measured.

    Attributes
    ----------
    wakeups, ticks, overruns, resyncs, dropped_bytes : int
    busy_s : float
        Time spent running ticks (the renderer, controller and plant), s.
    lateness_s : deque of float
        Lateness of the first tick of each wakeup, s (the most recent 200 000).
    """

    wakeups: int = 0
    ticks: int = 0
    overruns: int = 0
    resyncs: int = 0
    dropped_bytes: int = 0
    busy_s: float = 0.0
    lateness_s: deque[float] = field(default_factory=lambda: deque(maxlen=200_000))

    def summary(self) -> str:
        """One line: counts, lateness percentiles (us) and the cost per tick (us)."""
        late = sorted(self.lateness_s)

        def pct(q: float) -> float:
            return late[min(len(late) - 1, int(q * len(late)))] * 1e6 if late else 0.0

        per_tick = self.busy_s / self.ticks * 1e6 if self.ticks else 0.0
        return (
            f"{self.ticks} ticks, {self.wakeups} wakeups, {self.overruns} overruns, "
            f"{self.resyncs} resyncs; lateness p50 {pct(0.5):.0f} us, p99 {pct(0.99):.0f} us, "
            f"max {pct(1.0):.0f} us; tick cost {per_tick:.2f} us"
        )


def run_realtime(
    fd: int,
    emulator: DeviceEmulator,
    *,
    should_stop: Callable[[], bool],
    duration_s: float | None = None,
    wake_s: float = WAKE_S,
    stats: RealtimeStats | None = None,
) -> RealtimeStats:
    """Serve ``emulator`` on ``fd`` until ``should_stop()`` or ``duration_s`` elapses.

    Parameters
    ----------
    fd : int
        Non-blocking byte stream (pty master).
    emulator : DeviceEmulator
    should_stop : callable
        Polled every wakeup.
    duration_s : float, optional
        Stop after this long (benchmarks, tests).
    wake_s : float
        Sleep between wakeups, s.
    """
    st = stats if stats is not None else RealtimeStats()
    os.set_blocking(fd, False)
    hz = emulator.tick_hz
    t0 = time.monotonic() - emulator.ticks / hz
    end = None if duration_s is None else time.monotonic() + duration_s
    pending = b""
    next_wake = time.monotonic()
    while not should_stop():
        now = time.monotonic()
        if end is not None and now >= end:
            break
        st.wakeups += 1
        readable, _, _ = select.select([fd], [], [], 0)
        if readable:
            try:
                data = os.read(fd, 65536)
            except (BlockingIOError, InterruptedError):
                data = b""
            except OSError:  # EIO: no process has the slave open
                data = b""
            if data:
                emulator.receive(data)
        due = int((now - t0) * hz) - emulator.ticks
        if due > 0:
            late = now - (t0 + (emulator.ticks + 1) / hz)
            st.lateness_s.append(late)
            if late > RESYNC_S:
                st.resyncs += 1
                emulator.overruns += 1
                t0 = now - emulator.ticks / hz
                due = 1
            elif late > OVERRUN_S:
                st.overruns += 1
                emulator.overruns += 1
            b0 = time.perf_counter()
            emulator.run_ticks(due)
            st.busy_s += time.perf_counter() - b0
            st.ticks += due
        out = pending + emulator.take_output()
        if out:
            try:
                written = os.write(fd, out)
            except (BlockingIOError, InterruptedError):
                written = 0
            except OSError:
                written = len(out)  # nobody is listening: the bytes are lost, like on a wire
            pending = out[written:]
            if len(pending) > 65536:  # the host is not reading: drop, like a full UART FIFO
                st.dropped_bytes += len(pending)
                pending = b""
        # Sleep to the next wakeup on a fixed 1 ms grid (an oversleep shortens the next sleep).
        next_wake = max(next_wake + wake_s, time.monotonic() - wake_s)
        pause = next_wake - time.monotonic()
        if pause > 0.0:
            time.sleep(pause)
    return st


@contextlib.contextmanager
def pty_link(path: Path) -> Iterator[int]:
    """Open a pty, symlink ``path`` to its slave, yield the master fd; clean up on exit.

    The slave is put in raw mode (no echo, no line discipline) and kept open so the link
    survives hosts connecting and disconnecting.
    """
    if path.is_symlink() or path.exists():
        if not path.is_symlink():
            raise PtyLinkError(f"--pty-link {path}: exists and is not a symlink; pick another path")
        path.unlink()
    master, slave = os.openpty()
    tty.setraw(slave)
    try:
        try:
            path.symlink_to(os.ttyname(slave))
        except OSError as exc:
            raise PtyLinkError(
                f"--pty-link {path}: cannot create the link ({exc.strerror})"
            ) from exc
        yield master
    finally:
        with contextlib.suppress(OSError):
            if path.is_symlink():
                path.unlink()
        os.close(master)
        os.close(slave)


def serve_pty(
    path: Path, *, duration_s: float | None = None, start_mm: float = 0.0
) -> RealtimeStats:
    """``ctdrill emulate``: serve a fresh emulator on a pty linked at ``path`` until SIGTERM/SIGINT.

    Prints one line ``emulating on PATH -> /dev/pts/N`` once the link exists.
    """
    stop = [False]

    def _on_signal(signum: int, frame: object) -> None:
        stop[0] = True

    old_term = signal.signal(signal.SIGTERM, _on_signal)
    old_int = signal.signal(signal.SIGINT, _on_signal)
    try:
        with pty_link(path) as fd:
            print(f"emulating on {path} -> {os.readlink(path)}", flush=True)
            return run_realtime(
                fd,
                DeviceEmulator(start_mm=start_mm),
                should_stop=lambda: stop[0],
                duration_s=duration_s,
            )
    finally:
        signal.signal(signal.SIGTERM, old_term)
        signal.signal(signal.SIGINT, old_int)
