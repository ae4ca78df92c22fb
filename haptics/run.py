"""The host loop of a rehearsal: arm, stream heartbeats and the operator, log and watch telemetry.

The host runs in blocks of ``block_s`` (10 ms): send a heartbeat and the operator's input (the
first one with the ARM: the hand starts at the tick the device arms), let the block's time pass
(:meth:`Device.wait`), read the telemetry and hand the rows to a sink (``session.csv``, flushed
block by block). The same loop runs against the simulator and a serial device (real time).

The host does not trust the device to be right: every block it checks the telemetry
(:class:`ctdrill.haptics.watch.TelemetryWatch`: a report it cannot trust, which is not
recorded, the drill past the stop, a fault, a device silent for longer than the host's own
bound or back without the session) and ends the session on the first finding, or when its own
step failed (a write or read error, a sink that cannot write, an unacknowledged ARM or DISARM).

It then sends STOP and DISARM (unless an injected ``link-loss`` cut the line), records the
event in ``faults`` and returns a result with ``complete = False``, ``outcome = "fault"`` and
the reason: ``ctdrill rehearse`` exits 3. Telemetry from before the ARM's ACK is discarded.
"""

from __future__ import annotations

import contextlib
import math
import random
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

from ctdrill.haptics.device import (
    Device,
    DeviceError,
    DeviceRefused,
    TelemetrySample,
    simulator_controls,
)
from ctdrill.haptics.hands import Hand, hand_for
from ctdrill.haptics.profile_table import ProfileTable
from ctdrill.haptics.protocol import DeviceState, OperatorKind
from ctdrill.haptics.retract import arm_retracted
from ctdrill.haptics.session import (
    STATE_NAMES,
    FaultSpec,
    Operator,
    Row,
    SessionInputError,
    sample_row,
)
from ctdrill.haptics.watch import TelemetryWatch, fault_names
from ctdrill.interrupts import held, signal_name, signum_of

GARBAGE_BYTES = 64
#: Outcomes of a session.
OUTCOMES = ("complete", "fault", "cancelled", "interrupted")


@dataclass
class SessionResult:
    """What a session did (the session fields of ``summary.json``)."""

    stop_depth_mm: float
    max_drill_mm: float = 0.0
    max_master_mm: float = 0.0
    max_force_cmd_n: float = 0.0
    tick_rate_hz: float = 0.0
    overruns: int = 0
    samples: int = 0
    final_state: str = "idle"
    faults: list[dict[str, Any]] = field(default_factory=list)
    complete: bool = False
    outcome: str = "fault"
    reason: str | None = None
    #: Session time of the first sample in the stopped state, s (None: never stopped).
    time_to_stop_s: float | None = None
    #: The last sample's master and drill depth, rendered force and hand-force estimate.
    final_master_mm: float | None = None
    final_drill_mm: float | None = None
    final_force_cmd_n: float | None = None
    final_hand_est_n: float | None = None
    #: How the handle a previous session left deep was retracted before ARM (None: it was not).
    retraction: dict[str, float] | None = None
    #: The longest interval between two heartbeats the host sent, s (host clock): near the
    #: device's watchdog it says the host itself was late (a machine too busy to run it),
    #: beyond it with an injected ``delay`` or ``link-loss``.
    max_heartbeat_gap_s: float = 0.0
    #: The hand's largest offset past the drill while stopped, mm; the force and flags then.
    max_hand_past_drill_mm: float | None = None
    worst_wall_force_n: float | None = None
    worst_wall_faults: int = 0

    def to_json(self) -> dict[str, Any]:
        """JSON-ready dict."""
        return {
            "complete": self.complete,
            "outcome": self.outcome,
            "reason": self.reason,
            "stop_depth_mm": self.stop_depth_mm,
            "max_drill_mm": self.max_drill_mm,
            "max_master_mm": self.max_master_mm,
            "max_force_cmd_n": self.max_force_cmd_n,
            "tick_rate_hz": self.tick_rate_hz,
            "overruns": self.overruns,
            "samples": self.samples,
            "final_state": self.final_state,
            "faults": self.faults,
            "time_to_stop_s": self.time_to_stop_s,
            "final_master_mm": self.final_master_mm,
            "final_drill_mm": self.final_drill_mm,
            "final_force_cmd_n": self.final_force_cmd_n,
            "final_hand_est_n": self.final_hand_est_n,
            "retraction": self.retraction,
            "max_heartbeat_gap_s": self.max_heartbeat_gap_s,
            "max_hand_past_drill_mm": self.max_hand_past_drill_mm,
            "worst_wall_force_n": self.worst_wall_force_n,
            "worst_wall_flags": fault_names(self.worst_wall_faults),
        }


class _Loop:
    """One armed session's state (:func:`run_session`)."""

    def __init__(
        self,
        device: Device,
        operator: Operator,
        faults: Sequence[FaultSpec],
        seed: int,
        result: SessionResult,
        sink: Callable[[list[Row]], None] | None,
        on_samples: Callable[[list[TelemetrySample]], None] | None,
        hand: Hand,
    ) -> None:
        self.device = device
        self.sim = simulator_controls(device)
        self.on_samples = on_samples
        self.operator = operator
        self.hand = hand
        self.rng = random.Random(seed)
        self.result = result
        self.sink = sink
        self.start = device.clock_s()
        self.pending = sorted(faults, key=lambda f: f.time_s)
        self.link_up = True
        self.hold_until = -1.0
        self.held: list[tuple[int, float]] = []
        self.t0_device: float | None = None
        self.last: TelemetrySample | None = None
        self.prev_faults = 0
        self.rate_first: tuple[int, float] | None = None
        self.rate_last: tuple[int, float] | None = None
        self.watch: TelemetryWatch | None = None
        self.last_beat_s: float | None = None

    def now(self) -> float:
        return self.device.clock_s() - self.start

    def inject(self, now: float) -> None:
        """Carry out the injected faults that have come due."""
        while self.pending and self.pending[0].time_s <= now + 1e-9:
            fault = self.pending.pop(0)
            self.result.faults.append(
                {
                    "time_s": round(now, 4),
                    "source": "injected",
                    "kind": fault.kind,
                    "spec": fault.spec,
                }
            )
            if fault.kind == "link-loss":
                self.link_up = False
            elif fault.kind == "garbage" and self.link_up and self.sim is not None:
                self.sim.write_raw(bytes(self.rng.randrange(256) for _ in range(GARBAGE_BYTES)))
            elif fault.kind == "delay":
                self.hold_until = now + fault.duration_ms / 1000.0
            elif fault.kind == "reset" and self.link_up and self.sim is not None:
                self.sim.sim_reset()

    def operate(self, kind: int, value: float) -> None:
        """The simulated hand's input (a device without simulator controls takes none)."""
        if self.sim is not None:
            self.sim.set_operator(kind, value)

    def send(self, now: float) -> None:
        """The block's heartbeat and operator input (held while a delay is injected)."""
        kind, value = self.hand.command(now)
        if not self.link_up:
            return
        if now < self.hold_until - 1e-9:
            self.held.append((kind, value))
            return
        for held_kind, held_value in self.held:
            self.device.heartbeat()
            self.operate(held_kind, held_value)
        self.held.clear()
        self.device.heartbeat()
        self.operate(kind, value)
        beat_s = self.device.clock_s()
        if self.last_beat_s is not None:
            gap = beat_s - self.last_beat_s
            self.result.max_heartbeat_gap_s = max(self.result.max_heartbeat_gap_s, gap)
        self.last_beat_s = beat_s

    def take(self, samples: list[TelemetrySample]) -> None:
        """Log a block's telemetry: rows to the sink, maxima, raised flags."""
        result = self.result
        rows: list[Row] = []
        for s in samples:
            if self.t0_device is None:
                self.t0_device = s.time_s
            self.last = s
            t = s.time_s - self.t0_device
            rows.append(sample_row(t, s))
            self.hand.observe(t, s)
            result.max_drill_mm = max(result.max_drill_mm, s.drill_mm)
            result.max_master_mm = max(result.max_master_mm, s.master_mm)
            result.max_force_cmd_n = max(result.max_force_cmd_n, s.force_cmd_n)
            if s.state == DeviceState.STOPPED:
                if result.time_to_stop_s is None:
                    result.time_to_stop_s = round(t, 4)
                past, worst = s.master_mm - s.drill_mm, result.max_hand_past_drill_mm
                if worst is None or past > worst:
                    result.max_hand_past_drill_mm = max(past, 0.0)
                    result.worst_wall_force_n, result.worst_wall_faults = s.force_cmd_n, s.faults
            new_bits = s.faults & ~self.prev_faults
            if new_bits:
                result.faults.append(
                    {
                        "time_s": round(t, 4),
                        "source": "device",
                        "kind": "flags",
                        "flags": fault_names(new_bits),
                    }
                )
            self.prev_faults = s.faults
        result.samples += len(rows)
        if self.last is not None and samples:
            mark = (self.last.tick, self.device.clock_s())
            self.rate_first = mark if self.rate_first is None else self.rate_first
            self.rate_last = mark
        if self.sink is not None and rows:
            self.sink(rows)
        if self.on_samples is not None and samples:
            self.on_samples(samples)

    def finish(self) -> None:
        """Tick rate, overruns and the final state from the last telemetry."""
        result = self.result
        first, last = self.rate_first, self.rate_last
        if first is not None and last is not None and last[1] > first[1]:
            ticks = (last[0] - first[0]) & 0xFFFFFFFF
            result.tick_rate_hz = round(ticks / (last[1] - first[1]), 1)
        sample = self.last
        if sample is not None:
            result.overruns = sample.overruns
            result.final_state = STATE_NAMES.get(sample.state, "?")
            result.final_master_mm = sample.master_mm
            result.final_drill_mm = sample.drill_mm
            result.final_force_cmd_n = sample.force_cmd_n
            result.final_hand_est_n = sample.force_est_n

    def abort(
        self, kind: str, message: str, *, outcome: str = "fault", signal: str | None = None
    ) -> None:
        """End the session: STOP and DISARM (each awaited), record why, log the last rows;
        ``signal`` names the signal that interrupted it (recorded in the event)."""
        event: dict[str, Any] = {
            "time_s": round(self.now(), 4),
            "source": "host",
            "kind": kind,
            "message": message,
        }
        if signal is not None:
            event["signal"] = signal
        if self.link_up:
            sent_s = self.device.clock_s()
            for name, step in (("stop", self.device.stop), ("disarm", self.device.disarm)):
                try:
                    step()
                    event[f"{name}_acknowledged"] = True
                    event[f"{name}_acknowledged_after_s"] = round(self.device.clock_s() - sent_s, 4)
                except (DeviceError, OSError) as exc:
                    event[f"{name}_acknowledged"] = False
                    event[f"{name}_error"] = str(exc)
        else:
            event["stop_acknowledged"] = event["disarm_acknowledged"] = False
            event["stop_error"] = "not sent: the link is cut (injected link-loss)"
        self.result.faults.append(event)
        self.result.complete = False
        self.result.outcome = outcome
        self.result.reason = f"{kind}: {message}"
        with contextlib.suppress(DeviceError, OSError, ValueError):
            watch = self.watch or TelemetryWatch(self.result.stop_depth_mm, self.device.clock_s())
            # the device's last words (its safe state), as far as they can be trusted
            self.take(watch.trusted(self.device.poll(), self.device.clock_s()))
        self.finish()

    def run(
        self,
        duration_s: float,
        block_s: float,
        watch: TelemetryWatch,
        should_stop: Callable[[], bool] | None,
        until: Callable[[], bool] | None = None,
    ) -> None:
        """Blocks until ``duration_s`` (or ``until()``); ends early (and safely) on the first
        violation."""
        device = self.device
        while True:
            now = self.now()
            if now >= duration_s - 1e-9 or (until is not None and until()):
                break
            if should_stop is not None and should_stop():
                self.abort("cancelled", "stopped by the user", outcome="cancelled")
                return
            self.inject(now)
            self.send(now)
            device.wait(block_s)
            samples = device.poll()
            found = watch.check(
                samples, device.clock_s(), device.lost_session(), device.untrusted()
            )
            self.take(samples if found is None else samples[: found.recorded])
            if found is not None:
                self.abort(found.kind, found.dated(self.t0_device, self.now()))
                return
        self.finish()
        if self.link_up:
            try:
                device.disarm()
            except (DeviceError, OSError) as exc:
                self.abort("host_error", f"DISARM at the end was not acknowledged: {exc}")
                return
        self.result.complete = True
        self.result.outcome = "complete"
        self.result.reason = None


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
    should_stop: Callable[[], bool] | None = None,
    until: Callable[[], bool] | None = None,
    on_samples: Callable[[list[TelemetrySample]], None] | None = None,
    hand: Hand | None = None,
    notice: Callable[[str], None] | None = None,
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
    should_stop : callable, optional
        Polled every block; True ends the session (STOP, DISARM; outcome ``cancelled``).
    until : callable, optional
        Polled every block; True ends the session as if its time were up (DISARM; outcome
        ``complete``): the window ends a rehearsal once the device holds its auto-stop.
    on_samples : callable, optional
        Receives each block's telemetry samples (all fields, e.g. the hand-force estimate).
    hand : Hand, optional
        Who drives the session (:mod:`ctdrill.haptics.hands`); default: the hand that carries
        out ``operator`` (:func:`~ctdrill.haptics.hands.hand_for`).
    notice : callable, optional
        Receives a line when the host must retract a handle a previous session left deep
        before it can arm (:func:`ctdrill.haptics.retract.arm_retracted`).

    Returns
    -------
    SessionResult
        ``complete`` True only when the session ran its duration and was disarmed; otherwise
        ``outcome`` and ``reason`` say why it ended (the device was sent STOP and DISARM).

    Raises
    ------
    DeviceError
        Before ARM (no answer, VERSION or LIMITS outside the host's bounds, a refused upload or
        ARM, a handle not retracted): nothing was armed.
    """
    if not (math.isfinite(duration_s) and duration_s > 0.0):
        raise SessionInputError(f"--duration-s must be > 0, got {duration_s}")
    result = SessionResult(stop_depth_mm=float(table.stop_depth_mm))
    info = device.hello()
    device.upload_profile(table)
    driver = hand if hand is not None else hand_for(operator, table)
    loop = _Loop(device, operator, faults, seed, result, sink, on_samples, driver)
    loop.operate(int(OperatorKind.NONE), 0.0)
    first = driver.command(0.0) if loop.sim is not None else None  # sent with the ARM
    try:
        retraction = arm_retracted(device, notice=notice, limits=info.limits, operator=first)
    except DeviceRefused:
        raise  # NAK: the device did not arm
    except (DeviceError, OSError) as exc:  # the ARM may have reached the device: end it safely
        loop.abort("host_error", f"ARM was not acknowledged: {exc}")
        return result
    result.retraction = None if retraction is None else retraction.to_json()
    loop.start = device.clock_s()
    watch = TelemetryWatch.for_session(info, result.stop_depth_mm, table.crc32, device.clock_s())
    loop.watch = watch
    try:
        loop.run(duration_s, block_s, watch, should_stop, until)
    except KeyboardInterrupt as exc:  # Ctrl-C, or SIGTERM/SIGHUP (ctdrill.interrupts)
        name = signal_name(signum_of(exc))
        with held(reraise=False):  # a second signal does not cut the STOP and DISARM short
            why = (
                f"interrupted by the user ({name})" if name == "SIGINT" else f"interrupted ({name})"
            )
            loop.abort("interrupted", why, outcome="interrupted", signal=name)
    except (DeviceError, OSError, ValueError) as exc:  # the host's own step failed
        loop.abort("host_error", str(exc) or type(exc).__name__)
    except BaseException as exc:  # a bug: make the device safe first, then let it surface
        loop.abort("host_error", f"internal error: {exc!r}")
        raise
    return result
