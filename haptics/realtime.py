"""Run the device emulator at real time on a file descriptor (a pty master): ``ctdrill emulate``.

Device time is 10 kHz ticks on the monotonic clock: each wakeup (about every millisecond) reads
what the host wrote, runs the ticks that have come due one after the other (the host's bytes
handed to the device at the first tick count that is a multiple of
:data:`RECEIVE_EVERY_TICKS`), writes the device's frames and sleeps. A tick's *lateness* is how
long after its due time it ran, measured for every tick (the clock is read before each one):
with ~1 ms wakeups the ticks due since the last wakeup all run late by up to a wakeup period,
so the median is about half of it. A wakeup that finds more than :data:`OVERRUN_S` of ticks
due counts as an overrun (reported in TELEMETRY).

After a stall of the emulator itself longer than :data:`RESYNC_S` (a machine too busy to run
it) the clock slips instead of replaying the backlog: the emulator reads the host's bytes only
at its wakeups, so a replayed backlog would have the device run tens of milliseconds without
hearing a live host and trip its watchdog on the emulator's own stall, not the host's. Device
time then runs slower than the wall clock by the stalls (``resyncs`` and ``slipped_s``; the
host sees a tick rate below 10 kHz).
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import select
import signal
import stat
import time
import tty
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

from ctdrill.haptics.core import DeviceCore, make_core
from ctdrill.haptics.errors import HapticsInputError

OVERRUN_S = 0.005
#: The host's bytes are handed to the device only while its tick count is a multiple of this
#: (every millisecond of device time, the 1 ms frames of a USB serial adapter): a frame is
#: handled at the same tick phase whatever the machine's timing, on either core, so a host
#: whose commands ride with its ARM (:meth:`ctdrill.haptics.host.HostDevice.arm`) gets a
#: session deterministic in device time (firmware/host/fw_host.c: ``RECEIVE_EVERY_TICKS``).
RECEIVE_EVERY_TICKS = 10
#: A stall longer than this slips the clock (well under the 50 ms watchdog: several host frames).
RESYNC_S = 0.020
WAKE_S = 0.001
#: Lateness histogram: bins of this width, s, up to :data:`LATE_MAX_S` (later ticks in the last).
LATE_BIN_S = 10e-6
LATE_MAX_S = 1.0


class PtyLinkError(HapticsInputError):
    """The pty link path cannot be created."""


def _late_bins() -> list[int]:
    return [0] * (round(LATE_MAX_S / LATE_BIN_S) + 1)


@dataclass
class RealtimeStats:
    """What the real-time loop measured.

    Attributes
    ----------
    wakeups, ticks, overruns, resyncs, dropped_bytes : int
    slipped_s : float
        Device time given up to the emulator's own stalls, s.
    busy_s : float
        Time spent running ticks (the renderer, controller and plant), s.
    late_bins : list of int
        Histogram of every tick's lateness, :data:`LATE_BIN_S` bins (the whole run).
    late_max_s : float
        The latest tick's lateness, s.
    """

    wakeups: int = 0
    ticks: int = 0
    overruns: int = 0
    resyncs: int = 0
    slipped_s: float = 0.0
    dropped_bytes: int = 0
    busy_s: float = 0.0
    late_bins: list[int] = field(default_factory=_late_bins)
    late_max_s: float = 0.0

    def record_lateness(self, late_s: float) -> None:
        """Count one tick that ran ``late_s`` after its due time."""
        i = int(late_s / LATE_BIN_S) if late_s > 0.0 else 0
        self.late_bins[min(i, len(self.late_bins) - 1)] += 1
        if late_s > self.late_max_s:
            self.late_max_s = late_s

    def lateness_percentile_s(self, q: float) -> float:
        """Upper edge of the histogram bin holding the ``q`` quantile of tick lateness, s."""
        total = sum(self.late_bins)
        if total == 0:
            return 0.0
        target = q * total
        seen = 0
        for i, count in enumerate(self.late_bins):
            seen += count
            if seen >= target and count:
                return min((i + 1) * LATE_BIN_S, self.late_max_s)
        return self.late_max_s

    def summary(self) -> str:
        """One line: counts, per-tick lateness percentiles (us), the cost per tick (us)."""
        pct = self.lateness_percentile_s
        per_tick = self.busy_s / self.ticks * 1e6 if self.ticks else 0.0
        return (
            f"{self.ticks} ticks, {self.wakeups} wakeups, {self.overruns} overruns, "
            f"{self.resyncs} resyncs ({self.slipped_s * 1e3:.0f} ms slipped); "
            f"per-tick lateness p50 {pct(0.5) * 1e6:.0f} us, "
            f"p99 {pct(0.99) * 1e6:.0f} us, p99.9 {pct(0.999) * 1e6:.0f} us, "
            f"max {self.late_max_s * 1e6:.0f} us; tick cost {per_tick:.2f} us"
        )


def run_realtime(
    fd: int,
    emulator: DeviceCore,
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
    emulator : DeviceCore
        The device (:mod:`ctdrill.haptics.core`).
    should_stop : callable
        Polled every wakeup.
    duration_s : float, optional
        Stop after this long (benchmarks, tests).
    wake_s : float
        Sleep between wakeups, s.
    """
    st = stats if stats is not None else RealtimeStats()
    os.set_blocking(fd, False)
    pacer = getattr(emulator, "serve_realtime", None)
    if pacer is not None:  # a compiled core paces its own ticks (haptics/ccore.py)
        pacer(fd, should_stop=should_stop, duration_s=duration_s, stats=st)
        return st
    hz = emulator.tick_hz
    t0 = time.monotonic() - emulator.ticks / hz
    end = None if duration_s is None else time.monotonic() + duration_s
    pending = b""
    inbox = b""  # the host's bytes not yet handed to the device
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
            inbox += data
        if inbox and emulator.ticks % RECEIVE_EVERY_TICKS == 0:
            emulator.receive(inbox)
            inbox = b""
        due = int((now - t0) * hz) - emulator.ticks
        if due > 0:
            late = now - (t0 + (emulator.ticks + 1) / hz)
            if late > OVERRUN_S:
                st.overruns += 1
                emulator.overruns += 1
            stall = 0.0
            if late > RESYNC_S:  # the emulator stalled: slip, do not replay (module docstring)
                st.resyncs += 1
                st.slipped_s += late
                stall = late  # the one tick run now was due that long ago
                t0 = now - (emulator.ticks + 1) / hz
                due = 1
            busy = 0.0
            for _ in range(due):  # one at a time: each tick's own lateness is measured
                start = time.monotonic()
                st.record_lateness(stall or start - (t0 + (emulator.ticks + 1) / hz))
                emulator.run_ticks(1)
                if inbox and emulator.ticks % RECEIVE_EVERY_TICKS == 0:
                    emulator.receive(inbox)
                    inbox = b""
                busy += time.monotonic() - start
            st.busy_s += busy
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


def link_lock_path(path: Path) -> Path:
    """The lock an emulator holds beside its link ``path`` while it runs: ``PATH.lock``."""
    return path.with_name(path.name + ".lock")


def _lock_text(fd: int) -> list[str]:
    """What a lock file says: ``[pid, pty]`` (or less, when unreadable or still empty)."""
    with contextlib.suppress(OSError, ValueError):
        return os.pread(fd, 4096, 0).decode("utf-8").split()
    return []


@contextlib.contextmanager
def _link_lock(path: Path) -> Iterator[int]:
    """Hold ``PATH.lock`` (an exclusive ``flock``; inside, the holder's pid and the pty it
    links, written by :func:`pty_link`) while the link is served and yield its descriptor;
    refuse when another process holds it. The kernel releases it when the process ends,
    however it ends: a lock left by a killed emulator is taken over."""
    lock = link_lock_path(path)
    while True:
        try:
            fd = os.open(lock, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
        except OSError as exc:
            raise PtyLinkError(
                f"--pty-link {path}: cannot create its lock {lock} ({exc.strerror})"
            ) from exc
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            said = _lock_text(fd)
            owner = said[0] if said and said[0].isdigit() else "unknown"
            os.close(fd)
            raise PtyLinkError(
                f"--pty-link {path}: a running emulator (pid {owner}) serves this link; stop "
                "it or pick another path"
            ) from None
        try:  # its previous holder may have removed the file between our open and flock
            here, there = os.fstat(fd), os.stat(lock)
            if (here.st_dev, here.st_ino) == (there.st_dev, there.st_ino):
                break
        except FileNotFoundError:
            pass
        os.close(fd)
    try:
        yield fd
    finally:
        with contextlib.suppress(OSError):
            os.unlink(lock)
        os.close(fd)


def _refuse_live_link(path: Path, stale_target: str | None) -> None:
    """Remove a stale link at ``path``; refuse anything else (a file, a link to something that
    exists: a terminal that some process holds open, as another emulator's pty is).

    ``stale_target`` is the pty a dead emulator's lock names: its link is stale even if
    another program has been given a pty of the same number since."""
    if not (path.is_symlink() or path.exists()):
        return
    if not path.is_symlink():
        raise PtyLinkError(f"--pty-link {path}: exists and is not a symlink; pick another path")
    target = os.readlink(path)
    if target == stale_target:
        path.unlink()
        return
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        path.unlink()  # stale: its target is gone (a pty closed by its process)
        return
    except OSError as exc:
        raise PtyLinkError(
            f"--pty-link {path}: links to {target}, which cannot be checked ({exc.strerror}); "
            "pick another path"
        ) from exc
    what = "a terminal that a running program holds open" if stat.S_ISCHR(mode) else "a file"
    raise PtyLinkError(
        f"--pty-link {path}: links to {target}, {what} (another emulator's link?); stop that "
        "program or remove the link, or pick another path"
    )


@contextlib.contextmanager
def pty_link(path: Path) -> Iterator[int]:
    """Open a pty, symlink ``path`` to its slave, yield the master fd; clean up on exit.

    The slave is put in raw mode (no echo, no line discipline) and kept open so the link
    survives hosts connecting and disconnecting. While it runs the emulator holds
    ``PATH.lock`` (:func:`link_lock_path`: its pid and pty inside). A ``path`` that a running
    emulator serves (its lock is held) or that links to anything that exists (a pty another
    process holds open) is refused; only a stale link (its target gone, or the pty a dead
    emulator's lock names) is replaced. On exit the link is removed if it is still this
    emulator's, then the lock.
    """
    with _link_lock(path) as lock:
        said = _lock_text(lock)  # a dead emulator's: its pid and pty
        _refuse_live_link(path, said[1] if len(said) > 1 else None)
        master, slave = os.openpty()
        tty.setraw(slave)
        name = os.ttyname(slave)
        os.ftruncate(lock, 0)
        os.pwrite(lock, f"{os.getpid()} {name}\n".encode(), 0)
        try:
            try:
                path.symlink_to(name)
            except OSError as exc:
                raise PtyLinkError(
                    f"--pty-link {path}: cannot create the link ({exc.strerror})"
                ) from exc
            yield master
        finally:
            with contextlib.suppress(OSError):
                if path.is_symlink() and os.readlink(path) == name:
                    path.unlink()
            os.close(master)
            os.close(slave)


def serve_pty(
    path: Path, *, duration_s: float | None = None, start_mm: float = 0.0, core: str = "python"
) -> RealtimeStats:
    """``ctdrill emulate``: serve a fresh device ``core`` (:data:`ctdrill.haptics.core.CORES`)
    on a pty linked at ``path`` until SIGTERM/SIGINT.

    Prints one line ``emulating on PATH -> /dev/pts/N`` once the link exists.
    """
    stop = [False]

    def _on_signal(signum: int, frame: object) -> None:
        stop[0] = True

    old_term = signal.signal(signal.SIGTERM, _on_signal)
    old_int = signal.signal(signal.SIGINT, _on_signal)
    try:
        device = make_core(core, start_mm=start_mm)  # a core that cannot be built: no link
        with pty_link(path) as fd:
            print(f"emulating on {path} -> {os.readlink(path)}", flush=True)
            return run_realtime(fd, device, should_stop=lambda: stop[0], duration_s=duration_s)
    finally:
        signal.signal(signal.SIGTERM, old_term)
        signal.signal(signal.SIGINT, old_int)
