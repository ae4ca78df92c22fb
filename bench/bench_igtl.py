"""OpenIGTLink out: the send rate to a reading server, and what a stalled peer costs a session.

* Send rate: a simulated rehearsal of the demo (push:20), paced to the wall clock as
  ``ctdrill rehearse --igtl`` runs it, streamed to a pyigtl ``OpenIGTLinkServer`` in this
  process (a stand-in for 3D Slicer that unpacks every message); the rate is counted at the
  receiver from the ``DrillTip`` header timestamps.
* Cost to the session: the same session unpaced (the simulator as fast as the CPU allows, so
  the wall time is the host loop's own cost) without a stream (the peer), streaming to the
  reading server, and streaming to a stalled peer (it accepts and never reads); the longest
  observer call (``IgtlStream.observe``, what the host loop waits for each 10 ms block) and
  the stream's ``close`` at the session's end. Then a paced session to a stalled peer.
"""

from __future__ import annotations

import json
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

from bench.report import Section, table
from ctdrill.app.igtl.frames import IgtlTarget, StreamGeometry
from ctdrill.app.igtl.stream import MAX_RATE_HZ, STALL_TIMEOUT_S, IgtlStream
from ctdrill.app.rehearse import load_table
from ctdrill.haptics.run import run_session
from ctdrill.haptics.session import parse_operator
from ctdrill.haptics.sim import SimulatedDevice

ROOT = Path(__file__).resolve().parents[1]
DEMO = ROOT / "assets" / "demo"


#: A pyigtl server in a process of its own (as 3D Slicer is): prints its port, records the
#: DrillTip header timestamps until its stdin closes, then prints them as JSON.
SERVER = """
import json, sys, pyigtl
stamps = []
class Rec(dict):
    def __setitem__(self, key, value):
        if key == "DrillTip":
            stamps.append(value.timestamp)
        super().__setitem__(key, value)
server = pyigtl.OpenIGTLinkServer(port=0, local_server=True)
server.incoming_messages = Rec()
print(server.server_address[1], flush=True)
sys.stdin.read()
server.stop()
print(json.dumps(stamps), flush=True)
"""


class _Server:
    """:data:`SERVER` in a subprocess."""

    def __init__(self) -> None:
        self.proc = subprocess.Popen(
            [sys.executable, "-c", SERVER], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True
        )
        assert self.proc.stdout is not None
        self.port = int(self.proc.stdout.readline())

    def stamps(self) -> np.ndarray:
        """Stop the server: the DrillTip timestamps it received."""
        time.sleep(0.3)  # the last frames arrive
        out, _ = self.proc.communicate("", timeout=30)
        return np.array(json.loads(out.strip().splitlines()[-1]))


class _StalledPeer:
    """Accepts connections and never reads (a small receive buffer)."""

    def __init__(self) -> None:
        self.listener = socket.socket()
        self.listener.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1024)
        self.listener.bind(("127.0.0.1", 0))
        self.listener.listen(8)
        self.port = int(self.listener.getsockname()[1])
        self.conns: list[socket.socket] = []
        threading.Thread(target=self._accept, daemon=True).start()

    def _accept(self) -> None:
        while True:
            try:
                self.conns.append(self.listener.accept()[0])
            except OSError:
                return

    def close(self) -> None:
        for c in [*self.conns, self.listener]:
            c.close()


def _session(loaded: Any, port: int | None, *, duration_s: float, pace: bool) -> dict[str, Any]:
    stream = None
    if port is not None:
        geometry = StreamGeometry.of_plan(loaded.path.plan)
        stream = IgtlStream(IgtlTarget("127.0.0.1", port), geometry)
    calls: list[float] = []
    wall0: list[float] = []

    def observe(block: Any) -> None:
        t = time.perf_counter()
        if stream is not None:
            stream.observe(block)
        calls.append(time.perf_counter() - t)
        if pace:  # as IgtlStream(pace=True) does, outside the timed call
            if not wall0:
                wall0.extend((time.monotonic(), block[0].time_s))
            ahead = (block[-1].time_s - wall0[1]) - (time.monotonic() - wall0[0])
            if ahead > 0.0:
                time.sleep(ahead)

    device = SimulatedDevice(seed=0)
    start = time.perf_counter()
    result = run_session(
        device, loaded.table, parse_operator("push:20"), duration_s, on_samples=observe
    )
    wall = time.perf_counter() - start
    start = time.perf_counter()
    report = None if stream is None else stream.close()
    closing = time.perf_counter() - start
    device.close()
    return {
        "wall": wall,
        "close": closing,
        "calls": np.array(calls),
        "report": report,
        "complete": result.complete,
        "samples": result.samples,
    }


def _iqr(values: list[float], unit: float = 1.0, fmt: str = "{:.3f}") -> str:
    q1, med, q3 = (np.percentile(values, q) * unit for q in (25, 50, 75))
    return f"{fmt.format(med)} [{fmt.format(q1)}-{fmt.format(q3)}]"


def _paced_row(label: str, r: dict[str, Any], received: np.ndarray | None) -> list[object]:
    rep = r["report"]
    rx = ""
    if received is not None and len(received) > 1:
        rx = f"{(len(received) - 1) / (received[-1] - received[0]):.1f}"
    return [
        label,
        f"{r['wall']:.2f}",
        r["samples"],
        f"{np.percentile(r['calls'], 99) * 1e6:.0f}",
        f"{r['calls'].max() * 1e6:.0f}",
        "" if rep is None else f"{rep.sent} of {rep.frames}",
        "" if rep is None else rep.send_rate_hz,
        rx,
        f"{r['close'] * 1e3:.1f}",
        "" if rep is None or rep.error is None else rep.error,
    ]


def run(quick: bool) -> Section:
    """Measure and report (quick: short sessions, one repeat)."""
    loaded = load_table(DEMO / "ct", DEMO / "plan.json")
    paced_s, unpaced_s, repeats = (0.3, 0.3, 1) if quick else (5.0, 3.0, 5)

    def stalled(duration_s: float, pace: bool) -> dict[str, Any]:
        peer = _StalledPeer()
        try:
            return _session(loaded, peer.port, duration_s=duration_s, pace=pace)
        finally:
            peer.close()

    def reading(duration_s: float, pace: bool) -> tuple[dict[str, Any], np.ndarray]:
        server = _Server()
        try:
            return _session(loaded, server.port, duration_s=duration_s, pace=pace), server.stamps()
        finally:
            server.proc.kill()

    none_paced = _session(loaded, None, duration_s=paced_s, pace=True)
    read_paced, received = reading(paced_s, True)
    stall_paced = stalled(paced_s, True)
    rows: dict[str, list[dict[str, Any]]] = {"none": [], "reading": [], "stalled": []}
    for _ in range(repeats):  # interleaved: each configuration sees the same load
        rows["none"].append(_session(loaded, None, duration_s=unpaced_s, pace=False))
        rows["reading"].append(reading(unpaced_s, False)[0])
        rows["stalled"].append(stalled(unpaced_s, False))

    text = [
        f"Paced as `ctdrill rehearse --igtl` runs the simulator: a {paced_s:g} s session of the "
        "demo (push:20), one per row. The server is a pyigtl `OpenIGTLinkServer` in a process "
        "of its own; its rate is counted from the DrillTip header timestamps it received. The "
        "observer columns are the host loop's waits for `IgtlStream.observe` in each 10 ms "
        "block (the pacing sleep excluded).",
        "",
        table(
            [
                "stream to",
                "session wall (s)",
                "samples",
                "observer p99 (us)",
                "observer max (us)",
                "frames sent",
                "rate, sender (Hz)",
                "rate, receiver (Hz)",
                "close (ms)",
                "stream error",
            ],
            [
                _paced_row("no stream (peer)", none_paced, None),
                _paced_row("a reading server", read_paced, received),
                _paced_row("a stalled peer", stall_paced, None),
            ],
        ),
        "",
        f"Unpaced (the simulator as fast as the CPU allows: the wall time is the host loop's "
        f"own cost): {unpaced_s:g} s of device time, {repeats} repeats interleaved (median "
        f"[IQR]). The sender sends at most {MAX_RATE_HZ:g} frames a second; the stall timeout "
        f"is {STALL_TIMEOUT_S:g} s, so a stalled peer is found only at the close here.",
        "",
    ]
    base = float(np.median([r["wall"] for r in rows["none"]]))
    body = []
    for name, label in (
        ("none", "no stream (peer)"),
        ("reading", "a reading server"),
        ("stalled", "a stalled peer"),
    ):
        runs = rows[name]
        walls = [r["wall"] for r in runs]
        calls = np.concatenate([r["calls"] for r in runs])
        body.append(
            [
                label,
                _iqr(walls),
                f"{float(np.median(walls)) / base:.2f}",
                f"{np.percentile(calls, 99) * 1e6:.0f}",
                f"{calls.max() * 1e6:.0f}",
                _iqr([r["close"] for r in runs]),
                all(r["complete"] for r in runs),
            ]
        )
    text.append(
        table(
            [
                "stream to",
                "session wall (s)",
                "/ no stream",
                "observer p99 (us)",
                "observer max (us)",
                "close (s)",
                "complete",
            ],
            body,
        )
    )
    return Section(title="OpenIGTLink out: send rate, stalled peer", markdown="\n".join(text))
