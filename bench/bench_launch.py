"""The window's launch: what waits for the first draw, and what the first draw leaves for later.

``ctdrill gui --ct assets/demo/ct --plan assets/demo/plan.json`` started as a fresh process
(``bench/window_launch.py``, as ``bench_window`` launches it), timed from the launch to every
view drawn, with the process's CPU time then and the garbage collector's pauses until then
(the window's imports are frozen for it: ``preload.import_window``). numba and the compiled
kernels load after the first draw, in the background (``app/gui/first_draw.py``): whether numba
was imported when the views were drawn, when the kernels were loaded, and the longest gap
between ticks of a 5 ms timer on the UI thread from the views drawn until then (goal: no
stall over 50 ms). Peer in the same run, round-robin: a fresh process importing the libraries
the window draws its first series with (PySide6's widgets, matplotlib's Qt canvas, pyvista),
the least any such window pays before it shows.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

from bench.bench_window import DEMO, launch
from bench.report import Section, Timing, headline_row, table

ROOT = Path(__file__).resolve().parents[1]
#: The launch's goal (issue 37), s; the longest UI stall allowed while the kernels load, s.
GOAL_S = 2.0
GOAL_STALL_S = 0.05
#: The libraries the window's first draw needs (numba, pydicom and SciPy it does not).
FLOOR_IMPORTS = "import PySide6.QtWidgets, matplotlib.backends.backend_qtagg, pyvista"
MARKS = (
    "window shown",
    "views drawn",
    "cpu to views drawn",
    "gc pauses to views drawn",
    "kernels loaded",
    "longest UI gap while kernels load",
)


def _floor_s() -> float:
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-c", FLOOR_IMPORTS], check=True, cwd=ROOT)
    return time.perf_counter() - t0


def _load() -> str:
    one, five, _ = os.getloadavg()
    return f"{one:.1f} (5-min {five:.1f})"


def run(quick: bool) -> Section:
    """Launch the window on the demo a few times, round-robin with the floor."""
    repeats = 1 if quick else 5
    load_before = _load()
    ct, plan = DEMO / "ct", DEMO / "plan.json"
    if not quick:
        launch(ct, plan)  # untimed: bytecode written, caches warm
    runs, floors = [], []
    for _ in range(repeats):
        floors.append(_floor_s())
        runs.append(launch(ct, plan))
    load_after = _load()
    cells = [Timing.from_samples([r[m] for r in runs]) for m in MARKS]
    numba_at_drawn = sum(int(r["numba imported at views drawn"]) for r in runs)
    floor = Timing.from_samples(floors)
    drawn, cpu, stall = cells[1], cells[2], cells[5]
    unit = ["s", "s", "s", "ms", "s", "ms"]
    rows = [[m, c.fmt(u)] for m, c, u in zip(MARKS, cells, unit, strict=True)]
    rows.append(["numba imported when the views were drawn", f"{numba_at_drawn} of {len(runs)}"])
    rows.append(["floor: the first draw's libraries imported alone", floor.fmt("s")])
    headline = (
        headline_row(
            "#37 window: `ctdrill gui` on the demo, launch to every view drawn (bench_launch)",
            f"{drawn.median_s:.2f} s (CPU {cpu.median_s:.2f} s)",
            f"first draw's libraries alone {floor.median_s:.2f} s",
            f"{drawn.median_s / floor.median_s:.2f} (ours / floor)",
            f"<= {GOAL_S:g} s",
        ),
        headline_row(
            "#37 window: longest UI stall while the kernels load after the first draw",
            f"{1e3 * stall.median_s:.0f} ms (max {1e3 * max(c for c in stall_samples(runs)):.0f})",
            "",
            "",
            f"<= {1e3 * GOAL_STALL_S:.0f} ms",
        ),
    )
    shortfalls = []
    if drawn.median_s > GOAL_S:
        shortfalls.append(
            f"launch: the demo drew every view {drawn.median_s:.2f} s after its launch "
            f"(goal {GOAL_S:g} s; CPU {cpu.median_s:.2f} s; the first draw's libraries alone "
            f"{floor.median_s:.2f} s) at load {load_after}"
        )
    if stall.median_s > GOAL_STALL_S:
        shortfalls.append(
            f"launch: the UI stalled {1e3 * stall.median_s:.0f} ms while the kernels loaded "
            f"(goal {1e3 * GOAL_STALL_S:.0f} ms) at load {load_after}"
        )
    md = "\n\n".join(
        [
            __doc__.split("\n\n", 1)[1].strip() if __doc__ else "",
            f"Load average before {load_before}, after {load_after}; {len(runs)} launches, "
            "round-robin with the floor.",
            table(["mark (since the launch)", "median [IQR]"], rows),
        ]
    )
    return Section(
        title="The window's launch: first draw without numba, kernels after (bench_launch)",
        markdown=md,
        shortfalls=tuple(shortfalls),
        headline=headline,
    )


def stall_samples(runs: list[dict[str, float]]) -> list[float]:
    """The longest UI gap of each launch while its kernels loaded, s."""
    return [r["longest UI gap while kernels load"] for r in runs]
