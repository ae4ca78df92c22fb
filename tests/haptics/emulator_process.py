"""``ctdrill emulate`` in a subprocess on a pseudo-terminal, for the serial-path tests."""

from __future__ import annotations

import itertools
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

from ctdrill.haptics.device import TelemetrySample
from ctdrill.haptics.protocol import DeviceState, Fault, OperatorKind
from ctdrill.haptics.realtime import RESYNC_S
from ctdrill.haptics.renderer import WATCHDOG_S
from ctdrill.haptics.serial_device import SerialDevice

ROOT = Path(__file__).resolve().parents[2]
DEMO = ROOT / "assets" / "demo"


def demo_rehearsal(out: Path, operator: str, duration_s: str, *extra: str) -> list[str]:
    """``ctdrill rehearse`` arguments for the demo phantom and plan into ``out``."""
    return [
        "rehearse",
        "--dicom",
        str(DEMO / "ct"),
        "--plan",
        str(DEMO / "plan.json"),
        "--out",
        str(out),
        "--operator",
        operator,
        "--duration-s",
        duration_s,
        *extra,
    ]


def spawn_emulator(link: Path) -> subprocess.Popen[str]:
    """Start ``ctdrill emulate --pty-link link`` and return its process once it serves."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "ctdrill.app.cli", "emulate", "--pty-link", str(link)],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    assert proc.stdout is not None
    line = proc.stdout.readline()
    assert line.startswith(f"emulating on {link} -> /dev/pts/"), line
    return proc


@contextmanager
def emulator_process(link: Path, *, killed: bool = False) -> Iterator[subprocess.Popen[str]]:
    """Run the device emulator linked at ``link`` (a serial port stand-in); yield its process.

    On exit it is stopped with SIGTERM (after SIGCONT, should a test have frozen it) and must
    end cleanly: exit code 0, its closing report on stderr, and the link removed (unless the
    case ``killed`` it).
    """
    proc = spawn_emulator(link)
    try:
        yield proc
    finally:
        if proc.poll() is None:
            proc.send_signal(signal.SIGCONT)
            proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=10)
    if killed:
        return
    assert proc.returncode == 0, err
    assert "emulator stopped" in err
    assert not link.exists() and not link.is_symlink()  # the link is cleaned up


@contextmanager
def emulator_on_pty(link: Path) -> Iterator[Path]:
    """:func:`emulator_process`, yielding the link."""
    with emulator_process(link):
        yield link


#: How long a wait for the device may run before the test fails as hung, s of wall time (a
#: guard only: every check counts device ticks).
HANG_GUARD_S = 30.0
#: The longest host heartbeat gap that cannot trip the device's watchdog: the emulator reads the
#: host's bytes within :data:`~ctdrill.haptics.realtime.RESYNC_S` of their arrival (a longer
#: stall of its own slips its clock), so a device-time gap over the watchdog needs a host gap
#: over ``WATCHDOG_S - RESYNC_S``.
HOST_ON_TIME_S = WATCHDOG_S - RESYNC_S
#: Runs of a real-time case before a host too busy to keep its heartbeats fails it.
REAL_TIME_ATTEMPTS = 3


class HostLate(Exception):
    """The host (this test, or the rehearsal it runs) was starved past the device's watchdog:
    the device went safe, as it must, and the run says nothing about the link. Run again."""


def host_late(tripped: bool, max_gap_s: float) -> bool:
    """A watchdog trip that the host's own heartbeat gap explains."""
    return tripped and max_gap_s > HOST_ON_TIME_S


def with_fresh_emulator(
    tmp_path: Path,
    case: Callable[[Path, subprocess.Popen[str]], None],
    *,
    killed: bool = False,
) -> None:
    """Run ``case(link, emulator process)`` against a new emulator, again (at most
    :data:`REAL_TIME_ATTEMPTS` times) when it raises :class:`HostLate`: on a loaded machine a
    real-time case may lose a run to the scheduler, never to a bug (a trip with the host on
    time fails at once). ``killed``: the case kills the emulator (no clean exit expected)."""
    late: list[str] = []
    for attempt in range(REAL_TIME_ATTEMPTS):
        link = tmp_path / f"ctdrill-device-{attempt}"
        try:
            with emulator_process(link, killed=killed) as proc:
                case(link, proc)
            return
        except HostLate as exc:
            late.append(str(exc))
    raise AssertionError(f"the host was late in every run: {late}")


@dataclass
class Beats:
    """Telemetry received while the host beat, and the host's largest gap between heartbeats
    (s of its own clock): a gap near the 50 ms watchdog trips the device legitimately."""

    samples: list[TelemetrySample] = field(default_factory=list)
    max_gap_s: float = 0.0

    def span_ticks(self) -> int:
        """Device ticks between the first and the last sample."""
        return self.samples[-1].tick - self.samples[0].tick if self.samples else 0


def beat(
    dev: SerialDevice,
    force_n: float,
    ticks: int,
    until: Callable[[list[TelemetrySample]], bool] = lambda _s: True,
) -> Beats:
    """Heartbeat and push ``force_n`` every 10 ms until the telemetry spans ``ticks`` device
    ticks and ``until(samples)`` holds: waits counted in device time, which a loaded host slows
    down together with the device, never in wall time. A watchdog trip that the host's own
    heartbeat gap explains raises :class:`HostLate`."""
    out = Beats()
    guard = time.monotonic() + HANG_GUARD_S
    last = time.monotonic()
    while not (out.span_ticks() >= ticks and until(out.samples)):
        if time.monotonic() > guard:
            states = sorted({s.state for s in out.samples[-50:]})
            raise AssertionError(
                f"no {ticks} ticks of telemetry meeting the condition within {HANG_GUARD_S} s "
                f"(got {out.span_ticks()} ticks, last states {states}, host gap "
                f"{out.max_gap_s * 1e3:.0f} ms)"
            )
        dev.heartbeat()
        now = time.monotonic()
        out.max_gap_s, last = max(out.max_gap_s, now - last), now
        dev.set_operator(int(OperatorKind.PUSH), force_n)
        dev.wait(0.01)
        out.samples += dev.poll()
        tripped = any(  # the watchdog tripped during this beat
            a.state != DeviceState.SAFE
            and b.state == DeviceState.SAFE
            and b.faults & Fault.WATCHDOG
            for a, b in itertools.pairwise(out.samples)
        )
        gap = max(out.max_gap_s, time.monotonic() - last)  # the beat not yet sent counts
        if host_late(tripped, gap):
            raise HostLate(f"heartbeat gap {gap * 1e3:.0f} ms")
    return out


def silent(dev: SerialDevice, until: Callable[[list[TelemetrySample]], bool]) -> list:
    """Telemetry read without sending anything, until ``until(samples)`` holds."""
    samples: list[TelemetrySample] = []
    guard = time.monotonic() + HANG_GUARD_S
    while not until(samples):
        assert time.monotonic() < guard, f"the device did not get there within {HANG_GUARD_S} s"
        dev.wait(0.01)
        samples += dev.poll()
    return samples
