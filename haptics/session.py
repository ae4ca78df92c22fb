"""A rehearsal session: upload, arm, drive a simulated operator, log telemetry, inject faults.

The host runs in blocks of ``block_s`` (10 ms): send a heartbeat and the operator's input,
let the block's time pass (:meth:`Device.wait`), read the telemetry and hand the rows to a sink
(``session.csv`` is written and flushed block by block). The same loop runs against the
simulator (device time, deterministic for a given seed) and a serial device (real time).

Operators (``--operator``): ``push:N`` constant hand force N newtons; ``feed:V`` the hand
moves at a constant feed V mm/s (a stiff hand, its force capped at 78 N); ``script:FILE`` a CSV
``time_s,force_n`` (linear between rows, held after the last).

Faults (``--fault``, repeatable): ``link-loss@T`` the host's frames stop reaching the device
from T s on; ``garbage@T`` 64 random bytes (from the seed) on the link at T; ``delay@T:MS`` the
host's frames are held from T for MS ms then delivered late; ``reset@T`` the device reboots
at T. The device reaching its safe state, and every fault it reports, is logged too.
"""

from __future__ import annotations

import csv
import itertools
import math
import random
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

from ctdrill.haptics.device import Device, TelemetrySample
from ctdrill.haptics.errors import HapticsInputError
from ctdrill.haptics.profile_table import ProfileTable
from ctdrill.haptics.protocol import DeviceState, Fault, OperatorKind

SESSION_COLUMNS = ("time_s", "master_mm", "drill_mm", "force_cmd_n", "state")
STATE_NAMES = {int(s): s.name.lower() for s in DeviceState}
FAULT_KINDS = ("link-loss", "garbage", "delay", "reset")
MAX_HAND_N = 78.0
GARBAGE_BYTES = 64


class SessionInputError(HapticsInputError):
    """A bad ``--operator`` or ``--fault`` specification or operator script."""


@dataclass(frozen=True)
class Operator:
    """The simulated hand.

    Attributes
    ----------
    kind : str
        ``push``, ``feed`` or ``script``.
    value : float
        Force N (push) or feed mm/s (feed); unused for script.
    script : tuple of (time_s, force_n)
        Script rows, times increasing (script only).
    spec : str
        The specification it was parsed from.
    """

    kind: str
    value: float = 0.0
    script: tuple[tuple[float, float], ...] = ()
    spec: str = ""

    def force_at_n(self, t_s: float) -> float:
        """Hand force at session time ``t_s`` (push and script), N."""
        if self.kind == "push":
            return self.value
        rows = self.script
        if t_s <= rows[0][0]:
            return rows[0][1]
        for (t0, f0), (t1, f1) in itertools.pairwise(rows):
            if t_s <= t1:
                return f0 + (f1 - f0) * (t_s - t0) / (t1 - t0)
        return rows[-1][1]


def _number(text: str, what: str, spec: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise SessionInputError(f"{spec}: {what} must be a finite number, got {text!r}")
    return value


def load_script(path: Path) -> tuple[tuple[float, float], ...]:
    """Read an operator script CSV with columns ``time_s,force_n``."""
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise SessionInputError(f"operator script {path}: cannot read ({exc.strerror})") from exc
    reader = csv.reader(text.splitlines())
    header = next(reader, None)
    if header is None or [h.strip() for h in header[:2]] != ["time_s", "force_n"]:
        raise SessionInputError(f"operator script {path}: the first line must be 'time_s,force_n'")
    rows: list[tuple[float, float]] = []
    for lineno, row in enumerate(reader, start=2):
        if not row or not "".join(row).strip():
            continue
        if len(row) < 2:
            raise SessionInputError(f"operator script {path}:{lineno}: expected time_s,force_n")
        t = _number(row[0], f"time_s at line {lineno}", f"operator script {path}")
        f = _number(row[1], f"force_n at line {lineno}", f"operator script {path}")
        if rows and t <= rows[-1][0]:
            raise SessionInputError(f"operator script {path}:{lineno}: time_s must increase")
        if abs(f) > MAX_HAND_N:
            raise SessionInputError(
                f"operator script {path}:{lineno}: |force_n| must be <= {MAX_HAND_N:g} N"
            )
        rows.append((t, f))
    if not rows:
        raise SessionInputError(f"operator script {path}: no rows after the header")
    return tuple(rows)


def parse_operator(spec: str) -> Operator:
    """``push:N``, ``feed:V`` or ``script:FILE``."""
    kind, sep, arg = spec.partition(":")
    if not sep or kind not in ("push", "feed", "script") or not arg:
        raise SessionInputError(
            f"--operator {spec!r}: use push:N (newtons), feed:V (mm/s) or script:FILE"
        )
    if kind == "script":
        return Operator("script", script=load_script(Path(arg)), spec=spec)
    value = _number(arg, "the value", f"--operator {spec!r}")
    if kind == "push" and abs(value) > MAX_HAND_N:
        raise SessionInputError(f"--operator {spec!r}: force must be within +-{MAX_HAND_N:g} N")
    if kind == "feed" and abs(value) > 200.0:
        raise SessionInputError(f"--operator {spec!r}: feed must be within +-200 mm/s")
    return Operator(kind, value=value, spec=spec)


@dataclass(frozen=True)
class FaultSpec:
    """An injected fault: ``kind`` at session time ``time_s`` (``delay``: for ``duration_ms``)."""

    kind: str
    time_s: float
    duration_ms: float = 0.0
    spec: str = ""


def parse_fault(spec: str) -> FaultSpec:
    """``link-loss@T``, ``garbage@T``, ``delay@T:MS`` or ``reset@T``."""
    kind, sep, rest = spec.partition("@")
    if not sep or kind not in FAULT_KINDS:
        raise SessionInputError(
            f"--fault {spec!r}: use link-loss@T, garbage@T, delay@T:MS or reset@T (T in s)"
        )
    t_text, _, ms_text = rest.partition(":")
    t = _number(t_text, "the time", f"--fault {spec!r}")
    if t < 0.0:
        raise SessionInputError(f"--fault {spec!r}: the time must be >= 0 s")
    ms = 0.0
    if kind == "delay":
        ms = _number(ms_text, "the delay (ms)", f"--fault {spec!r}")
        if ms <= 0.0:
            raise SessionInputError(f"--fault {spec!r}: the delay must be > 0 ms")
    elif ms_text:
        raise SessionInputError(f"--fault {spec!r}: only delay takes ':MS'")
    return FaultSpec(kind, t, ms, spec)


@dataclass
class SessionResult:
    """What a session did (the summary.json fields)."""

    stop_depth_mm: float
    max_drill_mm: float = 0.0
    max_master_mm: float = 0.0
    max_force_cmd_n: float = 0.0
    tick_rate_hz: float = 0.0
    overruns: int = 0
    samples: int = 0
    final_state: str = "idle"
    faults: list[dict[str, Any]] = field(default_factory=list)

    def to_json(self) -> dict[str, Any]:
        """JSON-ready dict."""
        return {
            "stop_depth_mm": self.stop_depth_mm,
            "max_drill_mm": self.max_drill_mm,
            "max_master_mm": self.max_master_mm,
            "max_force_cmd_n": self.max_force_cmd_n,
            "tick_rate_hz": self.tick_rate_hz,
            "overruns": self.overruns,
            "samples": self.samples,
            "final_state": self.final_state,
            "faults": self.faults,
        }


Row = tuple[float, float, float, float, str]


class SessionCsv:
    """``session.csv`` writer, flushed after every block."""

    def __init__(self, path: Path) -> None:
        self._file: IO[str] = path.open("w", encoding="utf-8", newline="")
        self._writer = csv.writer(self._file, lineterminator="\n")
        self._writer.writerow(SESSION_COLUMNS)
        self._file.flush()

    def write(self, rows: Sequence[Row]) -> None:
        """Append rows and flush."""
        self._writer.writerows(
            (f"{t:.4f}", f"{m:.5f}", f"{d:.5f}", f"{f:.4f}", s) for t, m, d, f, s in rows
        )
        self._file.flush()

    def close(self) -> None:
        """Close the file."""
        self._file.close()


def _fault_names(bits: int) -> list[str]:
    return [f.name.lower() for f in Fault if bits & f]


def run_session(
    device: Device,
    table: ProfileTable,
    operator: Operator,
    duration_s: float,
    *,
    faults: Sequence[FaultSpec] = (),
    seed: int = 0,
    block_s: float = 0.01,
    sink: Callable[[list[Row]], None] | None = None,
) -> SessionResult:
    """Run one rehearsal on ``device``; rows go to ``sink`` block by block.

    Parameters
    ----------
    device : Device
        Connected device (not yet armed).
    table : ProfileTable
        Uploaded before arming; ``table.stop_depth_mm`` is enforced by the device.
    operator : Operator
    duration_s : float
        Session length after arming, s (host clock).
    faults : sequence of FaultSpec
    seed : int
        Seeds the garbage bytes; with the simulator the session is then reproducible.
    block_s : float
        Host loop period, s (heartbeat every block; must be well under the 50 ms watchdog).
    sink : callable, optional
        Receives the rows ``(time_s, master_mm, drill_mm, force_cmd_n, state)`` of each block.

    Returns
    -------
    SessionResult
    """
    if not (math.isfinite(duration_s) and duration_s > 0.0):
        raise SessionInputError(f"--duration-s must be > 0, got {duration_s}")
    rng = random.Random(seed)
    result = SessionResult(stop_depth_mm=float(table.stop_depth_mm))
    device.hello()
    device.upload_profile(table)
    device.poll()
    kind = OperatorKind.FEED if operator.kind == "feed" else OperatorKind.PUSH
    device.set_operator(int(OperatorKind.NONE), 0.0)
    device.arm()
    start = device.clock_s()
    t0_device: float | None = None
    last: TelemetrySample | None = None
    # (tick, host clock) at the end of the first and the latest block with telemetry
    rate_first: tuple[int, float] | None = None
    rate_last: tuple[int, float] | None = None
    pending = sorted(faults, key=lambda f: f.time_s)
    link_up = True
    hold_until = -1.0
    held: list[tuple[int, float]] = []
    prev_state = int(DeviceState.CUTTING)
    prev_faults = 0
    while True:
        now = device.clock_s() - start
        if now >= duration_s - 1e-9:
            break
        while pending and pending[0].time_s <= now + 1e-9:
            fault = pending.pop(0)
            result.faults.append(
                {
                    "time_s": round(now, 4),
                    "source": "injected",
                    "kind": fault.kind,
                    "spec": fault.spec,
                }
            )
            if fault.kind == "link-loss":
                link_up = False
            elif fault.kind == "garbage" and link_up:
                device.write_raw(bytes(rng.randrange(256) for _ in range(GARBAGE_BYTES)))
            elif fault.kind == "delay":
                hold_until = now + fault.duration_ms / 1000.0
            elif fault.kind == "reset" and link_up:
                device.sim_reset()
        value = operator.value if kind == OperatorKind.FEED else operator.force_at_n(now)
        if link_up:
            if now < hold_until - 1e-9:
                held.append((int(kind), value))
            else:
                for held_kind, held_value in held:
                    device.heartbeat()
                    device.set_operator(held_kind, held_value)
                held.clear()
                device.heartbeat()
                device.set_operator(int(kind), value)
        device.wait(block_s)
        samples = device.poll()
        rows: list[Row] = []
        for s in samples:
            if t0_device is None:
                t0_device = s.time_s
            last = s
            rows.append(
                (s.time_s - t0_device, s.master_mm, s.drill_mm, s.force_cmd_n, STATE_NAMES[s.state])
            )
            result.max_drill_mm = max(result.max_drill_mm, s.drill_mm)
            result.max_master_mm = max(result.max_master_mm, s.master_mm)
            result.max_force_cmd_n = max(result.max_force_cmd_n, s.force_cmd_n)
            new_bits = s.faults & ~prev_faults
            if new_bits:
                result.faults.append(
                    {
                        "time_s": round(s.time_s - t0_device, 4),
                        "source": "device",
                        "kind": "flags",
                        "flags": _fault_names(new_bits),
                    }
                )
            if s.state != prev_state and s.state in (DeviceState.SAFE, DeviceState.IDLE):
                result.faults.append(
                    {
                        "time_s": round(s.time_s - t0_device, 4),
                        "source": "device",
                        "kind": "state",
                        "state": STATE_NAMES[s.state],
                        "flags": _fault_names(s.faults),
                    }
                )
            prev_state, prev_faults = s.state, s.faults
        result.samples += len(rows)
        if last is not None and samples:
            mark = (last.tick, device.clock_s())
            rate_first = mark if rate_first is None else rate_first
            rate_last = mark
        if sink is not None and rows:
            sink(rows)
    if rate_first is not None and rate_last is not None and rate_last[1] > rate_first[1]:
        ticks = (rate_last[0] - rate_first[0]) & 0xFFFFFFFF
        result.tick_rate_hz = round(ticks / (rate_last[1] - rate_first[1]), 1)
    if last is not None:
        result.overruns = last.overruns
        result.final_state = STATE_NAMES[last.state]
    if link_up:
        device.disarm()
    return result
