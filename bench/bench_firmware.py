"""The reference firmware (``firmware/``, the C core) against the Python device it replaces.

* Per-tick cost, in-process: the whole emulated device tick (protocol, renderer, force
  controller, the simulated master, telemetry) in the C core (double and float builds, the loop
  in C) and in Python (:class:`DeviceEmulator`), cutting a slab at a 6 N push.
* Real time: ``ctdrill emulate --core c`` and ``--core python`` in a subprocess, one after the
  other in this run, with a host session over the pty (a SerialDevice beating every 10 ms and
  pushing 6 N): every tick's lateness (p50/p99/p99.9/max, 10 us bins). The Python loop runs the
  due ticks at ~1 ms wakeups; the C core's pacer sleeps to each tick's own due time.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bench.report import Section, headline_row, table
from ctdrill.haptics.ccore import CDeviceEmulator
from ctdrill.haptics.core import DeviceCore
from ctdrill.haptics.emulator import DeviceEmulator
from ctdrill.haptics.host import HostDevice
from ctdrill.haptics.profile_table import ProfileTable
from ctdrill.haptics.protocol import OperatorKind
from ctdrill.haptics.serial_device import SerialDevice
from ctdrill.haptics.sim import SimLink

ROOT = Path(__file__).resolve().parents[1]
SLAB = ProfileTable.slab(
    s0_n=4.0, s1_n=0.25, s2_n=0.125, top_mm=0.0, bottom_mm=40.0, stop_depth_mm=30.0
)
STATS = re.compile(
    r"(\d+) ticks, (\d+) wakeups, (\d+) overruns, (\d+) resyncs \((\d+) ms slipped\); "
    r"per-tick lateness p50 (\d+) us, "
    r"p99 (\d+) us, p99.9 (\d+) us, max (\d+) us; tick cost ([\d.]+) us"
)
#: Goals of issue 39 (benchmarks, not timed tests).
GOAL_TICK_US = 1.0
GOAL_P99_US = 100.0


def _armed(core: DeviceCore) -> DeviceCore:
    dev = HostDevice(SimLink(core), token_seed=0)
    dev.hello()
    dev.upload_profile(SLAB)
    dev.arm()
    dev.set_operator(int(OperatorKind.PUSH), 6.0)
    core.take_output()
    return core


def _tick_costs(n: int, repeats: int) -> list[list[str]]:
    rows = []

    for label, make in (
        ("C core, double (`--core c`)", lambda: CDeviceEmulator(nonce_seed=0)),
        (
            "C core, float (the microcontroller's)",
            lambda: CDeviceEmulator(nonce_seed=0, precision="single"),
        ),
        ("Python device (`--core python`)", lambda: DeviceEmulator(nonce_seed=0)),
    ):
        samples = []
        for _ in range(repeats):
            core = _armed(make())
            t0 = time.perf_counter()
            for _ in range(n // 400):
                core.run_ticks(400)
                core.take_output()
            samples.append((time.perf_counter() - t0) / (n // 400 * 400) * 1e6)
        samples.sort()
        rows.append(
            [
                label,
                f"{samples[len(samples) // 2]:.3f}",
                f"{samples[len(samples) // 4]:.3f}-{samples[(3 * len(samples)) // 4]:.3f}",
            ]
        )
    return rows


def _emulate(link: Path, core: str, duration_s: float, *, rt: bool) -> subprocess.Popen[str]:
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "ctdrill.app.cli",
            "emulate",
            "--core",
            core,
            "--pty-link",
            str(link),
            "--duration-s",
            f"{duration_s}",
        ],
        cwd=ROOT,
        env={**os.environ, "CTDRILL_EMULATE_RT": "1" if rt else "0"},
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    assert proc.stdout is not None
    line = proc.stdout.readline()
    if not line.startswith("emulating on"):
        _, err = proc.communicate(timeout=30)
        raise RuntimeError(f"ctdrill emulate --core {core} did not start: {err}")
    return proc


def _cpu_times() -> tuple[int, int]:
    """``(busy, total)`` jiffies of all the machine's CPUs (``/proc/stat``; zeros elsewhere)."""
    try:
        with open("/proc/stat", encoding="ascii") as fh:
            fields = [int(v) for v in fh.readline().split()[1:]]
    except (OSError, ValueError):
        return 0, 0
    idle = fields[3] + (fields[4] if len(fields) > 4 else 0)  # idle + iowait
    return sum(fields[:8]) - idle, sum(fields[:8])


def _session(core: str, duration_s: float, *, rt: bool = True) -> list[str]:
    with tempfile.TemporaryDirectory() as tmp:
        link = Path(tmp) / "dev"
        proc = _emulate(link, core, duration_s + 10.0, rt=rt)
        load0 = os.getloadavg()[0]
        cpu0 = _cpu_times()
        dev = SerialDevice(str(link))
        dev.hello()
        dev.upload_profile(SLAB)
        dev.arm()
        dev.poll()
        t0 = time.monotonic()
        while time.monotonic() - t0 < duration_s:
            dev.heartbeat()
            dev.set_operator(int(OperatorKind.PUSH), 6.0)
            dev.wait(0.01)
            dev.poll()
        cpu1 = _cpu_times()
        dev.close()
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=30)
    match = STATS.search(err)
    if match is None:
        raise RuntimeError(f"emulator statistics not found in: {err!r}")
    ticks, _wakeups, overruns, resyncs, _slipped, p50, p99, p999, mx, cost = match.groups()
    pacer = "real-time priority" if "pacer: real-time priority" in err else "timesharing"
    if core == "python":
        pacer = "timesharing, ~1 ms wakeups"
    return [
        f"`--core {core}`",
        pacer,
        ticks,
        overruns,
        resyncs,
        p50,
        p99,
        p999,
        mx,
        cost,
        f"{(load0 + os.getloadavg()[0]) / 2:.1f}",
        _busy(cpu0, cpu1),
    ]


def _busy(before: tuple[int, int], after: tuple[int, int]) -> str:
    """CPUs busy over a run (every process: this session's own emulator and host included),
    of how many."""
    busy, total = after[0] - before[0], after[1] - before[1]
    n = os.cpu_count() or 1
    return f"{busy / total * n:.1f} of {n}" if total > 0 else "?"


def run(quick: bool) -> Section:
    """Measure and report (quick: fewer ticks, 1 s real-time runs)."""
    n = 4_000 if quick else 200_000
    costs = _tick_costs(n, repeats=3 if quick else 7)
    seconds = 1.0 if quick else 5.0
    realtime = [
        _session("c", seconds),
        _session("c", seconds, rt=False),
        _session("python", seconds),
    ]
    c_us, py_us = float(costs[0][1]), float(costs[2][1])
    c_p99, py_p99 = float(realtime[0][6]), float(realtime[2][6])
    text = [
        f"Whole emulated device tick (protocol, renderer, force controller, the simulated "
        f"master, telemetry every 10 ticks), in-process, median of repeats over {n} ticks of "
        "cutting a 4 N slab at a 6 N push (IQR in brackets):",
        "",
        table(["core", "us per tick", "IQR"], costs),
        "",
        f"The C core's tick costs {c_us:.3f} us against the Python device's {py_us:.2f} us "
        f"({py_us / c_us:.0f}x). The firmware's own share on a Cortex-M4F is in "
        "docs/firmware.md (`make firmware-cycles`).",
        "",
        f"Real time, {seconds:g} s of a host session over the pty per core (SerialDevice, "
        "heartbeat and a 6 N push every 10 ms), one core after the other in this run; "
        "lateness is how long after its due time each tick ran (every tick, 10 us bins); "
        "load = the 1-minute load average around the run; CPUs busy = how many of the "
        "machine's CPUs were busy on average during the run (/proc/stat, every process: the "
        "emulator and this host session take a few per cent of one). The C core's pacer sleeps "
        "to each tick's due time at the lowest real-time priority where the system grants it "
        "(`SCHED_FIFO` 1; the second row declines it, `CTDRILL_EMULATE_RT=0`); the Python "
        "loop runs the due ticks at ~1 ms wakeups, so half a millisecond is its median's floor.",
        "",
        table(
            [
                "emulator",
                "pacer",
                "ticks",
                "overruns",
                "resyncs",
                "lateness p50 (us)",
                "p99 (us)",
                "p99.9 (us)",
                "max (us)",
                "tick cost (us)",
                "load",
                "CPUs busy",
            ],
            realtime,
        ),
    ]
    shortfalls = []
    if c_us > GOAL_TICK_US:
        shortfalls.append(f"one C tick costs {c_us:.2f} us (goal {GOAL_TICK_US:g} us)")
    if c_p99 > GOAL_P99_US:
        shortfalls.append(
            f"`emulate --core c` ran late by {c_p99:.0f} us at p99 (goal {GOAL_P99_US:g} us on "
            f"an idle machine; load {realtime[0][-2]}, {realtime[0][-1]} CPUs busy here)"
        )
    return Section(
        title="Firmware: the C core against the Python device",
        markdown="\n".join(text),
        shortfalls=tuple(shortfalls),
        headline=(
            headline_row(
                "device tick, C core vs Python (us)",
                f"{c_us:.3f}",
                f"{py_us:.2f}",
                f"{py_us / c_us:.0f}x",
                f"<= {GOAL_TICK_US:g} us",
            ),
            headline_row(
                "emulator lateness p99, --core c vs python (us)",
                f"{c_p99:.0f}",
                f"{py_p99:.0f}",
                f"{py_p99 / max(c_p99, 1.0):.1f}x",
                f"<= {GOAL_P99_US:g} us (idle)",
            ),
        ),
    )
