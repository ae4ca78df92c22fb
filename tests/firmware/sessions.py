"""Recorded device sessions for the equality tests: scripted hosts (the bytes a host sends and
the tick at which each arrives) and the per-tick outputs of the Python device on them.

A script is a list of ``(tick, bytes)``: the bytes arrive after ``tick`` control ticks. The same
script drives the Python emulator (:class:`DeviceEmulator`) and the C core
(:class:`CDeviceEmulator`); each records per tick :data:`RECORD_COLUMNS` (plant position,
force command, drill depth, motor current, hand estimate, ``state | faults << 8``) and every
byte it sends. The sessions cover cutting through breakthroughs (air gaps in the table), the
stop's wall, the thermal limit, a watchdog trip on a delayed host, a link loss, a STOP, a
power-cycle, garbage on the line and a retraction.
"""

from __future__ import annotations

import random
from array import array

import numpy as np

from ctdrill.haptics.ccore import RECORD_COLUMNS, CDeviceEmulator, Precision
from ctdrill.haptics.codes import OperatorKind
from ctdrill.haptics.emulator import DeviceEmulator
from ctdrill.haptics.profile_table import ProfileTable
from ctdrill.haptics.protocol import (
    Arm,
    Disarm,
    Heartbeat,
    Hello,
    Message,
    SimOperator,
    SimReset,
    Stop,
    encode,
)

Script = list[tuple[int, bytes]]
NCOL = len(RECORD_COLUMNS)


def layered_table(stop_depth_mm: float) -> ProfileTable:
    """Cortex, trabecular bone, an air gap (a breakthrough), dense bone, another gap, bone."""
    depth = np.arange(0.0, 20.0, 0.1)
    s0 = np.select(
        [depth < 3, depth < 8, depth < 9, depth < 12, depth < 13], [6.0, 2.0, 0.0, 8.0, 0.0], 3.0
    )
    return ProfileTable(
        depth_step_mm=0.1,
        s0_n=s0,
        s1_n=0.12 * s0,
        s2_n=0.05 * s0,
        ke_per_mm_s=0.25,
        freqs_hz=np.array([30.0, 60.0]),
        stop_depth_mm=stop_depth_mm,
    )


class _Host:
    """Builds a script: frames numbered and addressed like ctdrill's host."""

    def __init__(self, seed: int) -> None:
        self.nonces = random.Random(seed)
        self.session = 0
        self.seq = 0
        self.script: Script = []

    def send(self, tick: int, msg: Message, *, session: int | None = None) -> None:
        self.seq += 1
        s = self.session if session is None else session
        self.script.append((tick, encode(msg, seq=self.seq, session=s)))

    def raw(self, tick: int, data: bytes) -> None:
        self.script.append((tick, data))

    def hello(self, tick: int) -> None:
        self.seq = 0
        self.send(tick, Hello(3, 0xBEEF))
        self.session = self.nonces.randrange(1, 1 << 32)

    def upload_and_arm(self, tick: int, table: ProfileTable) -> None:
        for msg in table.upload_messages():
            self.send(tick, msg)
        self.send(tick, Arm(table.crc32))

    def beats(self, start: int, stop: int, *, operator: tuple[int, float] | None) -> None:
        """HEARTBEAT (and SIM_OPERATOR) every 10 ms from ``start`` to ``stop`` (ticks)."""
        for t in range(start, stop, 100):
            self.send(t, Heartbeat())
            if operator is not None:
                self.send(t, SimOperator(*operator))


def sessions(total_ticks: int = 1_000_000, seed: int = 0) -> Script:
    """One power-on's host traffic over ``total_ticks`` (>= 10^6 for the equality test)."""
    h = _Host(seed)
    push = int(OperatorKind.PUSH)
    feed = int(OperatorKind.FEED)
    none = int(OperatorKind.NONE)
    t = 1000  # 0.1 s of idle telemetry from power-on
    # 1. cut at 20 N through both breakthroughs to the stop at 15 mm; 70 N at the wall until the
    #    thermal limit lets the hand through (1.3 s at 70 N); let go; then the link is lost
    h.hello(t)
    h.upload_and_arm(t, layered_table(15.0))
    h.beats(t, t + 60_000, operator=(push, 20.0))
    t += 60_000
    h.beats(t, t + 25_000, operator=(push, 70.0))
    t += 25_000
    h.beats(t, t + 5_000, operator=(push, 0.0))
    t += 5_000
    t += 20_000  # link loss: nothing more from this host (the watchdog trips 50 ms later)
    # 2. a second host: pulls the handle back, uploads, feeds at 3 mm/s; its frames are held
    #    for 80 ms once (the watchdog trips), then it stops the device
    h.hello(t)
    h.beats(t, t + 15_000, operator=(feed, -50.0))
    t += 15_000
    h.beats(t, t + 1_000, operator=(none, 0.0))
    t += 1_000
    h.upload_and_arm(t, layered_table(10.0))
    h.beats(t, t + 60_000, operator=(feed, 3.0))
    t += 60_000
    t += 800  # held frames: the watchdog trips
    h.beats(t, t + 2_000, operator=(feed, 3.0))
    t += 2_000
    h.upload_and_arm(t, layered_table(10.0))  # NOT_RETRACTED: deep beyond the new front
    h.send(t + 100, Stop())
    h.send(t + 200, Disarm())
    t += 1_000
    # 3. garbage on the line, refused frames, a power-cycle, and a long session with a pull
    rng = random.Random(seed)
    h.raw(t, bytes(rng.randrange(256) for _ in range(64)))
    h.raw(t + 10, b"\x01" * 300 + b"\x00")
    h.send(t + 20, Heartbeat(), session=h.session ^ 1)
    h.send(t + 30, SimReset())
    t += 1_000
    h.hello(t)
    h.beats(t, t + 15_000, operator=(feed, -50.0))
    t += 15_000
    h.beats(t, t + 1_000, operator=(none, 0.0))
    t += 1_000
    h.upload_and_arm(t, layered_table(19.0))
    while t < total_ticks - 40_000:
        h.beats(t, t + 30_000, operator=(push, 12.0))
        t += 30_000
        h.beats(t, t + 10_000, operator=(push, -5.0))
        t += 10_000
        h.beats(t, t + 20_000, operator=(push, 30.0))
        t += 20_000
    h.beats(t, total_ticks, operator=(push, 0.0))
    h.send(total_ticks - 1, Stop())
    return h.script


def _segments(script: Script, total_ticks: int) -> list[tuple[int, bytes]]:
    """``(ticks to run, bytes to deliver after them)`` in order; the last delivers nothing."""
    out = []
    done = 0
    by_tick: dict[int, bytearray] = {}
    for tick, data in script:
        by_tick.setdefault(tick, bytearray()).extend(data)
    for tick in sorted(by_tick):
        if tick >= total_ticks:
            break
        out.append((tick - done, bytes(by_tick[tick])))
        done = tick
    out.append((total_ticks - done, b""))
    return out


def record_python(script: Script, total_ticks: int, *, seed: int = 0) -> tuple[np.ndarray, bytes]:
    """The Python device on ``script``: per-tick records (``total_ticks`` x 6) and its bytes."""
    emu = DeviceEmulator(nonce_seed=seed)
    rec = array("d")
    extend = rec.extend
    out = bytearray()
    r, c, p = emu.renderer, emu.controller, emu.plant
    for n, data in _segments(script, total_ticks):
        for _ in range(n):
            emu.control_tick()
            r = emu.renderer
            if r.new_faults:
                emu._report_faults()
            if emu.ticks % 10 == 0:
                emu._telemetry()
            c = emu.controller
            extend(
                (
                    p.x_m * 1e3,
                    r.force_cmd_n,
                    r.drill_mm,
                    c.current_a,
                    c.hand_est_n,
                    r.state | r.faults << 8,
                )
            )
        if data:
            emu.receive(data)
        out += emu.take_output()
    return np.frombuffer(rec, dtype=np.float64).reshape(-1, NCOL), bytes(out)


def record_c(
    script: Script, total_ticks: int, *, seed: int = 0, precision: Precision = "double"
) -> tuple[np.ndarray, bytes]:
    """The C core (closed loop with its simulated master) on ``script``, as
    :func:`record_python`."""
    emu = CDeviceEmulator(nonce_seed=seed, precision=precision)
    rec = np.zeros((total_ticks, NCOL))
    out = bytearray()
    done = 0
    for n, data in _segments(script, total_ticks):
        while n > 0:
            step = min(n, 10_000)
            emu.run_recorded(step, rec[done:].ctypes.data)
            done += step
            n -= step
            out += emu.take_output()
        if data:
            emu.receive(data)
        out += emu.take_output()
    return rec, bytes(out)


def replay_c(
    script: Script, counts: np.ndarray, *, seed: int = 0, precision: Precision = "single"
) -> np.ndarray:
    """The C core open-loop on recorded encoder readings ``counts`` (int32, one per tick plus
    one): the same bytes at the same ticks, per-tick records as :func:`record_python`."""
    total = len(counts) - 1
    emu = CDeviceEmulator(nonce_seed=seed, precision=precision)
    rec = np.zeros((total, NCOL))
    done = 0
    for n, data in _segments(script, total):
        if n:
            emu.replay(counts[done:].ctypes.data, n, rec[done:].ctypes.data)
            done += n
        if data:
            emu.receive(data)
        emu.take_output()
    return rec
