"""The test suite: ``make test``'s pytest run timed per directory, and the model tests alone.

Issue 37's goals: ``make test`` under 8 minutes on 2 idle cores with nothing dropped, and the
model tests (``tests/model``) under 60 s. Each run is a fresh ``python -m pytest`` process with
the plugin :mod:`bench.suite_cpu`, which records each test's CPU time (the process's every
thread plus the child processes it waited for) and wall time. The machine is shared: wall time
grows with the load, CPU time barely, so CPU is the figure to compare across runs; a serial
run's idle wall time is its CPU time plus what the tests wait for (subprocess time-outs,
sleeps), which this table shows as the wall time at the stated load.

Peer: the slowest module of the suite (``tests/imaging/test_path_checks.py``, brute-force lips
of 59 040 points transformed by ``(N, 3) @ (3, 3)`` products) with one OpenBLAS thread, as
``tests/conftest.py`` sets for every test process, against two threads (the library's default
on this 2-core machine), run one after the other in the same way.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from bench.report import Section, headline_row, table
from bench.suite_cpu import COLLECT, OUT_ENV

ROOT = Path(__file__).resolve().parents[1]
#: The goals of issue 37 (seconds).
SUITE_GOAL_S = 8 * 60.0
MODEL_GOAL_S = 60.0
#: CPU seconds ``make test`` spends before pytest: ruff 0.5, mypy 49.6 (a cold cache, as on a
#: fresh clone) and the kernels' warm-up 11.6 (measured 2026-11-29, one run each).
PRE_PYTEST_S = 62.0
#: The slowest module, the BLAS-thread peer's subject.
PEER_MODULE = "tests/imaging/test_path_checks.py"


@dataclass(frozen=True)
class PytestRun:
    """One ``python -m pytest`` process: its per-test rows, wall and CPU (its process tree)."""

    rows: tuple[dict[str, Any], ...]
    wall_s: float
    cpu_s: float
    returncode: int
    summary: str


def run_pytest(args: list[str], *, env_extra: dict[str, str] | None = None) -> PytestRun:
    """One ``python -m pytest -q`` over ``args`` with the CPU plugin."""
    with tempfile.TemporaryDirectory(prefix="ctdrill-bench-suite-") as tmp:
        out = Path(tmp) / "rows.jsonl"
        env = {**os.environ, OUT_ENV: str(out), "PYTHONPATH": str(ROOT)}
        if os.environ.get("DISPLAY"):
            env["QT_QPA_PLATFORM"] = "xcb"  # make bench runs under xvfb-run, as make test does
        env.update(env_extra or {})
        cmd = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider"]
        cmd += ["-p", "bench.suite_cpu", *args]
        before = os.times()
        t0 = time.perf_counter()
        proc = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True)
        wall = time.perf_counter() - t0
        after = os.times()
        text = out.read_text(encoding="utf-8") if out.is_file() else ""
        rows = tuple(json.loads(line) for line in text.splitlines())
    cpu = (after.children_user - before.children_user) + (
        after.children_system - before.children_system
    )
    tail = proc.stdout.strip().splitlines()[-1:] or [""]
    return PytestRun(rows, wall, cpu, proc.returncode, tail[0].strip("= "))


def by_directory(rows: tuple[dict[str, Any], ...]) -> dict[str, list[float]]:
    """``tests/<dir>`` (or ``tests/*.py``, ``<collect>``) -> [tests, CPU s, wall s]."""
    out: dict[str, list[float]] = defaultdict(lambda: [0.0, 0.0, 0.0])
    for row in rows:
        node = str(row["id"])
        parts = node.split("::")[0].split("/")
        key = (
            COLLECT if node == COLLECT else "/".join(parts[:2]) if len(parts) > 2 else "tests/*.py"
        )
        acc = out[key]
        acc[0] += 0 if node == COLLECT else 1
        acc[1] += float(row["self_s"]) + float(row["child_s"])
        acc[2] += float(row["wall_s"])
    return dict(sorted(out.items()))


def _cpu(row: dict[str, Any]) -> float:
    return float(row["self_s"]) + float(row["child_s"])


def _run_row(label: str, r: PytestRun) -> tuple[str, ...]:
    return (label, r.summary, f"{r.cpu_s:.1f}", f"{r.wall_s:.1f}")


def run(quick: bool) -> Section:
    """Time the suite (or, quick, one small module), the model tests and the BLAS peer."""
    suite_args = ["tests/model/test_calibration.py"] if quick else ["-m", "not bench_smoke"]
    model_args = ["tests/model/test_band.py"] if quick else ["tests/model"]
    peer_args = ["tests/model/test_band.py"] if quick else [PEER_MODULE]
    load0 = os.getloadavg()[0]
    suite = run_pytest(suite_args)
    model = run_pytest(model_args)
    peer_one = run_pytest(peer_args, env_extra={"OPENBLAS_NUM_THREADS": "1"})
    peer_two = run_pytest(peer_args, env_extra={"OPENBLAS_NUM_THREADS": "2"})
    load = 0.5 * (load0 + os.getloadavg()[0])

    dirs = by_directory(suite.rows)
    dir_rows = [(f"`{d}`", f"{n:.0f}", f"{c:.1f}", f"{w:.1f}") for d, (n, c, w) in dirs.items()]
    tot = [sum(v[i] for v in dirs.values()) for i in range(3)]
    dir_rows.append(("**total**", f"{tot[0]:.0f}", f"{tot[1]:.1f}", f"{tot[2]:.1f}"))
    tests = [r for r in suite.rows if r["id"] != COLLECT]
    slow = sorted(tests, key=lambda r: -_cpu(r))[:10]
    slow_rows = [(f"`{r['id']}`", f"{_cpu(r):.2f}", f"{float(r['wall_s']):.2f}") for r in slow]
    estimate_s = PRE_PYTEST_S + suite.cpu_s
    ratio = peer_two.cpu_s / max(peer_one.cpu_s, 1e-9)
    names = (
        ("`tests/model/test_calibration.py`", "`tests/model/test_band.py`")
        if quick
        else ("suite (`-m 'not bench_smoke'`)", "`tests/model`")
    )
    md = [
        f"Load average {load:.1f} on the 2-core machine during these runs. Each row is one "
        "fresh `python -m pytest -q -p no:cacheprovider` process (make test's command, serial); "
        "CPU is user + system of the process tree.",
        "",
        table(
            ["run", "result", "CPU s", "wall s"],
            [
                _run_row(names[0], suite),
                _run_row(names[1], model),
                _run_row("peer module, 1 OpenBLAS thread", peer_one),
                _run_row("peer module, 2 OpenBLAS threads", peer_two),
            ],
        ),
        "",
        f"Peer module `{peer_args[0]}`: 2 OpenBLAS threads cost {ratio:.2f} x the CPU of one.",
        "",
        "Per directory (CPU and wall summed over each test's set-up, call and tear-down):",
        "",
        table(["directory", "tests", "CPU s", "wall s"], dir_rows),
        "",
        "The ten most expensive tests by CPU:",
        "",
        table(["test", "CPU s", "wall s"], slow_rows),
        "",
        f"Estimated idle wall of `make test`: {PRE_PYTEST_S:.0f} s before pytest (ruff, mypy, "
        f"warm-up) + the suite's CPU {suite.cpu_s:.0f} s = {estimate_s:.0f} s against the goal "
        f"of {SUITE_GOAL_S:.0f} s (tests that wait on time-outs add to it).",
    ]
    shortfalls = []
    if suite.returncode != 0:
        shortfalls.append(f"the suite's run did not pass: {suite.summary}")
    if not quick and estimate_s > SUITE_GOAL_S:
        shortfalls.append(
            f"make test estimated at {estimate_s:.0f} s idle (CPU), goal {SUITE_GOAL_S:.0f} s"
        )
    if not quick and model.cpu_s > MODEL_GOAL_S:
        shortfalls.append(f"tests/model take {model.cpu_s:.0f} s CPU, goal {MODEL_GOAL_S:.0f} s")
    headline = (
        headline_row(
            "#37 make test's pytest, CPU (serial)",
            f"{suite.cpu_s:.0f} s",
            goal=f"make test <= {SUITE_GOAL_S:.0f} s idle",
        ),
        headline_row(
            "#37 tests/model, CPU", f"{model.cpu_s:.1f} s", goal=f"<= {MODEL_GOAL_S:.0f} s"
        ),
        headline_row(
            f"#37 {peer_args[0]}, CPU with 1 OpenBLAS thread",
            f"{peer_one.cpu_s:.1f} s",
            f"{peer_two.cpu_s:.1f} s (2 threads)",
            f"{ratio:.2f}",
        ),
    )
    return Section("The test suite", "\n".join(md), (), tuple(shortfalls), headline)
