"""The firmware's C core on the host, loaded with :mod:`ctypes` (``ctdrill emulate --core c``,
the equality and fuzz tests); built on first use by :mod:`ctdrill.haptics.ccore_build`.

:class:`CDeviceEmulator` has the interface of :class:`ctdrill.haptics.emulator.DeviceEmulator`
that the real-time loop and the tests use (``receive``, ``run_ticks``, ``take_output``,
``ticks``, ``overruns``); the device and its simulated master run in C
(``firmware/host/fw_host.c`` implements the hardware table with the plant of
:mod:`ctdrill.haptics.plant`), and :meth:`CDeviceEmulator.serve_realtime` paces its ticks in C.
"""

from __future__ import annotations

import ctypes
import os
import random
import sys
import time
from collections.abc import Callable
from typing import Protocol

from ctdrill.haptics.ccore_build import (
    RECORD_COLUMNS,
    CoreUnavailableError,
    Precision,
    build_core,
    compiler,
    load_core,
)
from ctdrill.haptics.tick import TICK_HZ

__all__ = [
    "RECORD_COLUMNS",
    "CDeviceEmulator",
    "CoreUnavailableError",
    "LatenessStats",
    "Precision",
    "build_core",
    "compiler",
    "load_core",
]


class LatenessStats(Protocol):
    """What the pacer fills (:class:`ctdrill.haptics.realtime.RealtimeStats`)."""

    wakeups: int
    ticks: int
    overruns: int
    resyncs: int
    slipped_s: float
    dropped_bytes: int
    busy_s: float
    late_bins: list[int]
    late_max_s: float


class CDeviceEmulator:
    """The device of :class:`~ctdrill.haptics.emulator.DeviceEmulator` run by the C core.

    Parameters
    ----------
    start_mm : float
        Initial master depth, mm.
    nonce_seed : int, optional
        Seeds the session nonces as the Python emulator does (the same sessions for the same
        seed); default: the OS random source.
    precision : {"double", "single"}
        The core's ``real_t``.
    """

    tick_hz = TICK_HZ
    dt_s = 1.0 / TICK_HZ
    _RECEIVE_CHUNK = 4096  # at most 170 HELLOs: the nonce queue (512) never runs dry

    def __init__(
        self,
        *,
        start_mm: float = 0.0,
        nonce_seed: int | None = None,
        precision: Precision = "double",
        sanitize: bool = False,
    ) -> None:
        self._lib = load_core(precision, sanitize=sanitize)
        self.precision = precision
        self._nonces: random.Random = (
            random.SystemRandom() if nonce_seed is None else random.Random(nonce_seed)
        )
        handle = self._lib.fw_host_new(float(start_mm), 0x2545F491)
        if not handle:
            raise MemoryError("fw_host_new")
        self._h = ctypes.c_void_p(handle)
        self._out = ctypes.create_string_buffer(1 << 20)
        self._fill_nonces()

    def __del__(self) -> None:
        h = getattr(self, "_h", None)
        if h is not None and h.value:
            self._lib.fw_host_free(h)
            self._h = ctypes.c_void_p(None)

    def _fill_nonces(self) -> None:
        queued = self._lib.fw_host_nonces_queued(self._h)
        for _ in range(512 - queued):
            self._lib.fw_host_push_nonce(self._h, self._nonces.randrange(1, 1 << 32))

    @property
    def handle(self) -> ctypes.c_void_p:
        """The C device (``fw_host *``)."""
        return self._h

    @property
    def ticks(self) -> int:
        """Control ticks run since power-on."""
        return int(self._lib.fw_host_ticks(self._h))

    @ticks.setter
    def ticks(self, value: int) -> None:
        raise AttributeError("the C core counts its own ticks")

    @property
    def now_s(self) -> float:
        """Device clock, s."""
        return self.ticks * self.dt_s

    @property
    def overruns(self) -> int:
        """Late wakeups (reported in TELEMETRY)."""
        return int(self._lib.fw_host_overruns(self._h))

    @overruns.setter
    def overruns(self, value: int) -> None:
        self._lib.fw_host_set_overruns(self._h, value & 0xFFFFFFFF)

    @property
    def frames_rejected(self) -> int:
        """Host frames refused since power-on."""
        return int(self._lib.fw_host_frames_rejected(self._h))

    @property
    def session(self) -> int:
        """The current session nonce (0: none)."""
        return int(self._lib.fw_host_session(self._h))

    @property
    def state(self) -> int:
        """The renderer's state (a :class:`~ctdrill.haptics.codes.DeviceState`)."""
        return int(self._lib.fw_host_state(self._h))

    @property
    def position_mm(self) -> float:
        """The simulated stage's true position, mm."""
        return float(self._lib.fw_host_position_mm(self._h))

    def set_device_seq(self, seq: int) -> None:
        """Set the device's frame counter as after ``seq`` frames (tests of its wrap)."""
        self._lib.fw_host_set_device_seq(self._h, seq & 0xFFFFFFFF)

    def receive(self, data: bytes) -> None:
        """Bytes from the host, handled at the current device time."""
        step = self._RECEIVE_CHUNK
        for i in range(0, len(data), step):
            piece = bytes(data[i : i + step])
            self._lib.fw_host_receive(self._h, piece, len(piece))
            self._fill_nonces()

    def run_ticks(self, n: int) -> None:
        """Run ``n`` control ticks (telemetry every 10)."""
        while n > 0:
            step = min(n, 10_000)  # 57 kB of telemetry at most between two drains
            self._lib.fw_host_run(self._h, step, None)
            self._drain()
            n -= step

    def run_recorded(self, n: int, record: object) -> None:
        """Run ``n`` ticks writing one row of :data:`RECORD_COLUMNS` per tick into ``record``
        (a C-contiguous float64 buffer of ``n * 6`` values, e.g. a NumPy array's ``ctypes``
        data pointer)."""
        self._lib.fw_host_run(self._h, n, record)
        self._drain()

    def replay(self, counts: object, n: int, record: object) -> None:
        """Run the core open-loop on ``n + 1`` given encoder readings (int32 counts of 0.1 um;
        tick ``i`` reads ``counts[i]``, its telemetry ``counts[i + 1]``), recording as
        :meth:`run_recorded`."""
        self._lib.fw_host_replay(self._h, counts, n, record)
        self._drain()

    def _drain(self) -> None:
        self._kept = getattr(self, "_kept", b"") + self._take()

    def _take(self) -> bytes:
        n = self._lib.fw_host_take(self._h, self._out, len(self._out))
        return ctypes.string_at(self._out, n) if n else b""

    def take_output(self) -> bytes:
        """Bytes the device has written since the last call."""
        out = getattr(self, "_kept", b"") + self._take()
        self._kept = b""
        return out

    # ------------------------------------------------------------ real time

    def serve_realtime(
        self,
        fd: int,
        *,
        should_stop: Callable[[], bool],
        duration_s: float | None = None,
        stats: LatenessStats,
    ) -> None:
        """Serve on ``fd`` at real time with the ticks paced in C (``fw_host_serve``: each tick
        waits for its own due time, 0.1 ms apart, instead of the Python loop's 1 ms wakeups),
        in slices of :data:`SLICE_S` between which ``should_stop`` is polled; fills
        ``stats`` as :func:`ctdrill.haptics.realtime.run_realtime` does.

        The pacer asks for the lowest real-time priority (``SCHED_FIFO`` 1; granted to root,
        ``CAP_SYS_NICE`` or an rtprio limit; ``CTDRILL_EMULATE_RT=0`` declines it) and says on
        stderr whether it got it: without it the ticks wake as late as the machine's load
        makes them."""
        n_bins = len(stats.late_bins)  # 10 us bins (the C pacer's too)
        bins = (ctypes.c_uint64 * n_bins)()
        st = _RtStats()
        st.late_bins = ctypes.cast(bins, ctypes.POINTER(ctypes.c_uint64))
        st.n_bins = n_bins
        end = None if duration_s is None else time.monotonic_ns() + round(duration_s * 1e9)
        want_rt = int(os.environ.get("CTDRILL_EMULATE_RT", "1") != "0")
        said = False
        while not should_stop():
            now = time.monotonic_ns()
            if end is not None and now >= end:
                break
            until = now + round(SLICE_S * 1e9)
            self._lib.fw_host_serve(
                self._h, fd, until if end is None else min(until, end), ctypes.byref(st), want_rt
            )
            if not said and st.started:
                said = True
                sys.stderr.write(
                    "pacer: real-time priority (SCHED_FIFO 1)\n"
                    if st.realtime
                    else "pacer: no real-time priority (timesharing: ticks wake as late as the "
                    "load makes them)\n"
                )
        stats.wakeups += st.wakeups
        stats.ticks += st.ticks
        stats.overruns += st.overruns
        stats.resyncs += st.resyncs
        stats.slipped_s += st.slipped_s
        stats.dropped_bytes += st.dropped_bytes
        stats.busy_s += st.busy_s
        stats.late_max_s = max(stats.late_max_s, st.late_max_s)
        for i, count in enumerate(bins):
            if count:
                stats.late_bins[i] += count


#: The compiled pacer returns to Python this often (signals, ``should_stop``), s.
SLICE_S = 0.01


class _RtStats(ctypes.Structure):
    """``fw_rt_stats`` of firmware/host/fw_host.c."""

    _fields_ = list(
        zip(
            [
                "wakeups",
                "ticks",
                "overruns",
                "resyncs",
                "dropped_bytes",
                "slipped_s",
                "busy_s",
                "late_max_s",
                "t0_ns",
                "started",
                "realtime",
                "late_bins",
                "n_bins",
                "pending",
                "pending_len",
            ],
            (
                *(ctypes.c_uint64,) * 5,
                *(ctypes.c_double,) * 3,
                ctypes.c_int64,
                ctypes.c_int32,
                ctypes.c_int32,
                ctypes.POINTER(ctypes.c_uint64),
                ctypes.c_uint32,
                ctypes.c_uint8 * 65536,
                ctypes.c_uint32,
            ),
            strict=True,
        )
    )
