"""A hostile device for tests: the emulator with one lie in what it reports (issue 29).

:class:`HostileEmulator` behaves as the device until ``after_s`` of device time after ARM,
then tells its lie in every TELEMETRY frame (or once, for a FAULT report); the ``limits-*`` and
``version-*`` lies are told at HELLO. ``python -m tests.haptics.hostile --pty-link PATH --lie
NAME`` serves it on a pseudo-terminal like ``ctdrill emulate`` and, on SIGTERM, writes what it
measured (when it first lied and when a STOP reached it, on its monotonic clock) to
``--report FILE``.
"""

from __future__ import annotations

import argparse
import json
import math
import signal
import time
from dataclasses import replace
from pathlib import Path

from ctdrill.haptics.emulator import DeviceEmulator
from ctdrill.haptics.protocol import (
    Disarm,
    FaultReport,
    Limits,
    Message,
    NakReason,
    Packet,
    Stop,
    Telemetry,
    Version,
    encode,
)
from ctdrill.haptics.realtime import pty_link, run_realtime

#: The lies told in TELEMETRY (or as a FAULT report) once armed, and the kind of fault the host
#: must end the session with.
TELEMETRY_LIES = {
    "nan-force": "device_fault",
    "inf-force": "device_fault",
    "inf-master": "device_fault",
    "nan-hand": "device_fault",
    "state-5": "device_fault",
    "state-255": "device_fault",
    "fault-bit-0100": "device_fault",
    "fault-bit-8000": "device_fault",
    "other-table": "device_fault",
    "fault-report": "device_fault",
    "time-backwards": "device_clock",
    "time-frozen": "device_clock",
    "time-jump-2-64": "device_clock",
    "time-fast": "device_clock",
    "silent": "telemetry_silent",
    # values outside the device's LIMITS or its physics (finite, well formed)
    "force-cmd-150": "device_fault",
    "force-cmd-minus-45": "device_fault",
    "hand-300": "device_fault",
    "hand-minus-130": "device_fault",
    "master-95": "device_fault",
    "drill-minus-40": "device_fault",
    "velocity-5e4": "device_fault",
}
#: The lies told at HELLO: the host refuses the device before anything is uploaded.
HELLO_LIES = ("limits-watchdog-65535", "limits-peak-nan", "limits-travel", "version-rate-0")


class HostileEmulator(DeviceEmulator):
    """The emulator, lying from ``after_s`` of device time after ARM (module docstring)."""

    def __init__(self, lie: str, *, after_s: float = 0.2, nonce_seed: int | None = 0) -> None:
        if lie not in TELEMETRY_LIES and lie not in HELLO_LIES:
            raise ValueError(f"unknown lie {lie!r}")
        super().__init__(nonce_seed=nonce_seed)
        self.lie = lie
        self.after_s = after_s
        self.lie_from_us: int | None = None
        #: Monotonic clock when the first lie left and when the first STOP arrived, s.
        self.first_lie_at: float | None = None
        self.stop_at: float | None = None

    def _lying(self, now_us: int) -> bool:
        r = self.renderer
        if self.lie_from_us is None and r.state in (1, 2):  # armed: start counting
            self.lie_from_us = round((r.t_arm_s + self.after_s) * 1e6)
        return self.lie_from_us is not None and now_us >= self.lie_from_us

    def _tell(self, message: Message, now_us: int) -> tuple[Message | None, int]:
        lie = self.lie
        if isinstance(message, Limits):
            if lie == "limits-watchdog-65535":
                return replace(message, watchdog_ms=65535), now_us
            if lie == "limits-peak-nan":
                return replace(message, peak_force_n=math.nan), now_us
            if lie == "limits-travel":
                return replace(message, travel_min_mm=10.0), now_us
        if isinstance(message, Version) and lie == "version-rate-0":
            return replace(message, tick_rate_hz=0), now_us
        if not isinstance(message, Telemetry) or not self._lying(now_us):
            return message, now_us
        assert self.lie_from_us is not None
        if self.first_lie_at is None:
            self.first_lie_at = time.monotonic()
            if lie == "fault-report":
                self._out += encode(
                    FaultReport(0x0100, message.state),
                    seq=self._next_seq(),
                    session=self.session,
                    time_us=now_us,
                )
        since_us = now_us - self.lie_from_us
        lies: dict[str, dict[str, float | int]] = {
            "nan-force": {"force_cmd_n": math.nan},
            "inf-force": {"force_cmd_n": math.inf},
            "inf-master": {"master_mm": math.inf},
            "nan-hand": {"force_est_n": math.nan},
            "state-5": {"state": 5},
            "state-255": {"state": 255},
            "fault-bit-0100": {"faults": message.faults | 0x0100},
            "fault-bit-8000": {"faults": message.faults | 0x8000},
            "other-table": {"table_crc32": message.table_crc32 ^ 1},
            "time-fast": {"tick": (message.tick + 2 * since_us // 100) & 0xFFFFFFFF},
            "force-cmd-150": {"force_cmd_n": 150.0},
            "force-cmd-minus-45": {"force_cmd_n": -45.0},
            "hand-300": {"force_est_n": 300.0},
            "hand-minus-130": {"force_est_n": -130.0},
            "master-95": {"master_mm": 95.0},
            "drill-minus-40": {"drill_mm": -40.0},
            "velocity-5e4": {"velocity_mm_s": 5e4},
        }
        changes = lies.get(lie, {})
        if lie == "silent":
            return None, now_us
        if lie == "time-backwards":
            now_us -= 5000
        elif lie == "time-frozen":
            now_us = self.lie_from_us
        elif lie == "time-jump-2-64":
            now_us = 2**64 - 1
        elif lie == "time-fast":
            now_us += 2 * since_us  # ticks and time three times the real pace, consistent
        return replace(message, **changes), now_us  # type: ignore[arg-type]

    def _next_seq(self) -> int:
        self._seq = (self._seq + 1) & 0xFFFFFFFF
        return self._seq

    def _send(self, message: Message, *, session: int | None = None) -> None:
        told, now_us = self._tell(message, self.ticks * 1_000_000 // self.tick_hz)
        if told is None:
            return
        self._out += encode(
            told,
            seq=self._next_seq(),
            session=self.session if session is None else session,
            time_us=now_us,
        )

    def _command(self, msg: Message, now: float) -> NakReason | None:
        if isinstance(msg, Stop) and self.stop_at is None:
            self.stop_at = time.monotonic()
        return super()._command(msg, now)

    def _safe_command(self, msg: Stop | Disarm, packet: Packet) -> None:
        if isinstance(msg, Stop) and self.stop_at is None:
            self.stop_at = time.monotonic()
        super()._safe_command(msg, packet)


def main() -> int:
    """Serve a hostile device on a pty until SIGTERM; write the report."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--pty-link", type=Path, required=True)
    parser.add_argument("--lie", required=True)
    parser.add_argument("--after-s", type=float, default=0.3)
    parser.add_argument("--report", type=Path)
    args = parser.parse_args()
    stop = [False]
    signal.signal(signal.SIGTERM, lambda *_: stop.__setitem__(0, True))
    device = HostileEmulator(args.lie, after_s=args.after_s, nonce_seed=None)
    with pty_link(args.pty_link) as fd:
        print(f"emulating on {args.pty_link}", flush=True)
        run_realtime(fd, device, should_stop=lambda: stop[0])
    if args.report is not None:
        report = {
            "first_lie_at": device.first_lie_at,
            "stop_at": device.stop_at,
            "state": device.renderer.state,
            "faults": device.renderer.faults,
        }
        args.report.write_text(json.dumps(report))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
