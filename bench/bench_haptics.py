"""Haptics: renderer cost per tick, real-time emulator lateness, telemetry throughput over a pty.

* Per-tick cost (in-process, monotonic clock): the device renderer alone (cutting law, limits,
  watchdog) against its peer, the O(1) force law ``ctdrill.model.profile.force_n``, and the whole
  emulated device tick (renderer + force controller + plant + telemetry framing).
* Real time: ``ctdrill emulate`` in a subprocess at 10 kHz device time, batching the due ticks
  at each ~1 ms wakeup; the lateness of every tick (p50/p99/p99.9/max) with no host connected
  and while a SerialDevice runs a session over the pty (2 cores shared by both processes).
* Host telemetry throughput: TELEMETRY frames and bytes per second received by the host.
"""

from __future__ import annotations

import re
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from bench.report import Section, figure_path, table, time_it
from ctdrill.haptics.emulator import DeviceEmulator
from ctdrill.haptics.profile_table import ProfileTable
from ctdrill.haptics.protocol import OperatorKind, Telemetry, encode
from ctdrill.haptics.renderer import Renderer
from ctdrill.haptics.serial_device import SerialDevice
from ctdrill.haptics.sim import SimulatedDevice
from ctdrill.haptics.tick import TICK_S
from ctdrill.model.profile import Profile, force_n

ROOT = Path(__file__).resolve().parents[1]
SLAB = ProfileTable.slab(
    s0_n=4.0, s1_n=0.25, s2_n=0.125, top_mm=0.0, bottom_mm=40.0, stop_depth_mm=30.0
)
#: Bytes of one TELEMETRY frame on the wire (COBS and the delimiter included).
TELEMETRY_WIRE_BYTES = len(
    encode(Telemetry(0, 0.0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0, 0), seq=1, session=1)
)
STATS = re.compile(
    r"(\d+) ticks, (\d+) wakeups, (\d+) overruns, (\d+) resyncs \((\d+) ms slipped\); "
    r"per-tick lateness p50 (\d+) us, "
    r"p99 (\d+) us, p99.9 (\d+) us, max (\d+) us; tick cost ([\d.]+) us"
)


def _per_tick_costs(n: int, repeats: int) -> list[list[str]]:
    renderer = Renderer()
    renderer.load(SLAB.begin_message(), SLAB.rows())
    renderer.arm(0.0, 0.0)
    state = {"t": 0.0}

    def run_renderer() -> None:
        r = renderer
        t = state["t"]
        for _ in range(n):
            t += TICK_S
            r.last_host_s = t
            r.tick(t, t * 1.0, 1.0)  # cutting at 1 mm/s
        state["t"] = t

    depth = SLAB.depth_mm
    profile = Profile(
        depth_mm=depth,
        s0_n=SLAB.s0_n.astype(float),
        sk_n=np.vstack([SLAB.s1_n, SLAB.s2_n]).astype(float),
        freqs_hz=np.array([30.0, 60.0]),
        s_t=np.ones_like(depth),
        hu_mean=np.zeros_like(depth),
        ke_per_mm_s=0.25,
        n_clipped=0,
        n_samples=1,
        calibration="bench",
    )

    def run_law() -> None:
        t = 0.0
        for _ in range(n):
            t += TICK_S
            force_n(profile, t, 1.0, t)

    def armed_emulator() -> DeviceEmulator:
        dev = SimulatedDevice()
        dev.hello()
        dev.upload_profile(SLAB)
        dev.arm()
        dev.set_operator(int(OperatorKind.PUSH), 6.0)
        dev.emulator.take_output()
        return dev.emulator

    def run_device() -> None:
        # A fresh device each run (set-up < 1 % of the run): cutting the slab at 2 mm/s.
        emu = armed_emulator()
        emu.renderer.watchdog_s = 1e9  # no host in this benchmark
        emu.run_ticks(n)
        emu.take_output()

    rows = []
    for name, fn in (
        ("force law `model.profile.force_n` (peer)", run_law),
        ("device renderer `Renderer.tick`", run_renderer),
        ("whole device tick (renderer + controller + plant + telemetry)", run_device),
    ):
        timing = time_it(fn, repeats=repeats)
        us = timing.median_s / n * 1e6
        rows.append(
            [name, f"{us:.2f}", f"{timing.p25_s / n * 1e6:.2f}-{timing.p75_s / n * 1e6:.2f}"]
        )
    return rows


def _emulate(link: Path, duration_s: float) -> subprocess.Popen[str]:
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "ctdrill.app.cli",
            "emulate",
            "--pty-link",
            str(link),
            "--duration-s",
            f"{duration_s}",
        ],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    assert proc.stdout is not None
    proc.stdout.readline()
    return proc


def _finish(proc: subprocess.Popen[str]) -> tuple[str, ...]:
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=30)
    match = STATS.search(err)
    if match is None:
        raise RuntimeError(f"emulator statistics not found in: {err!r}")
    return match.groups()


def _realtime(duration_s: float) -> tuple[list[list[str]], list[list[str]]]:
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        link = Path(tmp) / "dev"
        proc = _emulate(link, duration_s + 5.0)
        time.sleep(duration_s)
        idle = _finish(proc)
        rows.append(["no host connected", *idle])

        proc = _emulate(link, duration_s + 5.0)
        dev = SerialDevice(str(link))
        dev.hello()
        dev.upload_profile(SLAB)
        dev.arm()
        dev.poll()
        frames = 0
        t0 = time.monotonic()
        while time.monotonic() - t0 < duration_s:
            dev.heartbeat()
            dev.set_operator(int(OperatorKind.PUSH), 6.0)
            dev.wait(0.01)
            frames += len(dev.poll())
        elapsed = time.monotonic() - t0
        dev.close()
        busy = _finish(proc)
        rows.append(["host session over the pty", *busy])
    rate = frames / elapsed
    throughput = [
        [
            f"{elapsed:.1f}",
            f"{frames}",
            f"{rate:.0f}",
            f"{rate * TELEMETRY_WIRE_BYTES / 1000:.1f}",
            f"{rate / 1000:.3f}",
        ]
    ]
    return rows, throughput


FIGURE_NAME = "haptics_session.png"


def _session_figure(operator: str, duration_s: float) -> str:
    """A simulated rehearsal on the demo phantom: depths and rendered force against time."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ctdrill.app.rehearse import load_table
    from ctdrill.haptics.run import run_session
    from ctdrill.haptics.session import parse_operator

    demo = ROOT / "assets" / "demo"
    loaded = load_table(demo / "ct", demo / "plan.json")
    rows: list[tuple[float, float, float, float, str, float]] = []
    result = run_session(
        SimulatedDevice(), loaded.table, parse_operator(operator), duration_s, sink=rows.extend
    )
    t = [r[0] for r in rows]
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(6.4, 5.0), sharex=True)
    ax1.plot(t, [r[1] for r in rows], label="master (hand)")
    ax1.plot(t, [r[2] for r in rows], label="drill")
    ax1.axhline(result.stop_depth_mm, color="k", ls="--", lw=0.8, label="stop depth")
    ax1.set_ylabel("depth (mm)")
    ax1.legend(fontsize=7)
    ax2.plot(t, [r[3] for r in rows], lw=0.6)
    ax2.set_ylabel("rendered force (N)")
    ax2.set_xlabel("time (s)")
    ax1.set_title(f"Simulated rehearsal, demo phantom, {loaded.path.calibration.name}, {operator}")
    fig.tight_layout()
    fig.savefig(figure_path(FIGURE_NAME), dpi=110)
    plt.close(fig)
    return (
        f"Figure: `ctdrill rehearse` on the demo phantom in the simulator ({operator}, "
        f"{duration_s:g} s): the drill stops at {result.max_drill_mm:.2f} mm "
        f"(stop depth {result.stop_depth_mm:.2f} mm, {loaded.path.stop_reason}) while the hand "
        f"is pushed on to {result.max_master_mm:.2f} mm against the wall."
    )


def run(quick: bool) -> Section:
    """Measure and report (quick: fewer ticks, 1 s real-time runs)."""
    n = 5_000 if quick else 50_000
    costs = _per_tick_costs(n, repeats=3 if quick else 7)
    realtime, throughput = _realtime(1.0 if quick else 5.0)
    law_us = float(costs[0][1])
    text = [
        f"Per-tick cost, in-process, median of repeats over {n} ticks (IQR in brackets); the "
        "budget at 10 kHz is 100 us per tick.",
        "",
        table(
            ["what", "us per tick", "IQR"],
            [[*r[:2], r[2]] for r in costs],
        ),
        "",
        f"The renderer costs {float(costs[1][1]) / law_us:.1f}x the bare force law and the whole "
        f"emulated device tick {float(costs[2][1]) / law_us:.1f}x; a whole tick uses "
        f"{float(costs[2][1]):.1f} % of the 100 us period.",
        "",
        "Real-time emulator (`ctdrill emulate`, subprocess, 10 kHz device time, the due ticks "
        "run one after the other at each ~1 ms wakeup). Lateness = how long after its due time "
        "each tick ran, measured for every tick (10 us histogram bins): the ticks that came due "
        "since the last wakeup all run at once, so half a wakeup period is the floor of the "
        "median. An overrun is a wakeup more than 5 ms late.",
        "",
        table(
            [
                "run",
                "ticks",
                "wakeups",
                "overruns",
                "resyncs",
                "slipped (ms)",
                "lateness p50 (us)",
                "p99 (us)",
                "p99.9 (us)",
                "max (us)",
                "tick cost (us)",
            ],
            realtime,
        ),
        "",
        "Host telemetry over the pty (SerialDevice, heartbeat every 10 ms):",
        "",
        table(
            [
                "seconds",
                "TELEMETRY frames",
                "frames/s",
                f"kB/s ({TELEMETRY_WIRE_BYTES} B/frame)",
                "ratio to 1 kHz",
            ],
            throughput,
        ),
    ]
    text += ["", _session_figure("push:12", 3.0 if quick else 6.0)]
    return Section(
        title="Haptics: device tick, real-time emulator, pty link",
        markdown="\n".join(text),
        figures=(str(figure_path(FIGURE_NAME)),),
    )
