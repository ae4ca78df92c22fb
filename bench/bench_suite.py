"""The test suite: ``make test`` timed whole, its pytest run per directory, the model tests alone.

Issue 37's goals: ``make test`` under 8 minutes on 2 idle cores with nothing dropped, and the
model tests (``tests/model``) under 60 s. The whole target is run as ``make test`` runs it, each
step timed: ruff, the kernels' warm-up into an empty numba cache, then mypy from an empty cache
beside pytest on 2 workers (pytest-xdist, ``--dist loadscope``: the window tests one after
another in one worker). Each pytest process loads the plugin :mod:`bench.suite_cpu`, which
records each test's CPU time (the worker's every thread plus the child processes it waited for)
and wall time. The machine is shared: wall time grows with the load, CPU time barely.

Peer: the same pytest command on one process (``-p no:xdist``, serial, what ``make test`` ran
before), in the same run; its wall time against the 2 workers' is the parallel speed-up at the
load stated. And the slowest module of the serial suite (``tests/imaging/test_path_checks.py``,
points transformed by ``(N, 3) @ (3, 3)`` products) with one OpenBLAS thread, as
``tests/conftest.py`` sets for every test process, against two.
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
#: make test's pytest command (the Makefile's ``test`` target) and its workers' options.
PYTEST_ARGS = ("-m", "not bench_smoke")
WORKER_ARGS = ("-n", "2", "--dist", "loadscope")
#: The slowest module of the serial suite, the BLAS-thread peer's subject.
PEER_MODULE = "tests/imaging/test_path_checks.py"


@dataclass(frozen=True)
class Step:
    """One process of ``make test``: its exit code, wall and CPU seconds (its waited-for tree)."""

    returncode: int
    wall_s: float
    cpu_s: float
    tail: str


@dataclass(frozen=True)
class PytestRun:
    """One ``python -m pytest`` process: its per-test rows, wall and CPU (its process tree)."""

    rows: tuple[dict[str, Any], ...]
    wall_s: float
    cpu_s: float
    returncode: int
    summary: str

    def worker_cpu_s(self) -> dict[str, float]:
        """Worker (``gw0``, ``gw1``; ``main`` when serial) -> CPU of its rows."""
        out: dict[str, float] = defaultdict(float)
        for r in self.rows:
            out[str(r.get("worker") or "main")] += _cpu(r)
        return dict(sorted(out.items()))


def _start(cmd: list[str], env: dict[str, str], log: Path) -> tuple[subprocess.Popen[bytes], float]:
    with open(log, "wb") as f:
        proc = subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=f, stderr=subprocess.STDOUT)
    return proc, time.perf_counter()


def _wait(proc: subprocess.Popen[bytes], t0: float, log: Path) -> Step:
    """Reap ``proc`` with ``wait4`` for its own resource usage (children it waited for included)."""
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    proc.returncode = os.waitstatus_to_exitcode(status)
    lines = log.read_text(encoding="utf-8", errors="replace").strip().splitlines()
    return Step(proc.returncode, wall, usage.ru_utime + usage.ru_stime, (lines[-1:] or [""])[0])


def _env(extra: dict[str, str] | None = None) -> dict[str, str]:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    if os.environ.get("DISPLAY"):
        env["QT_QPA_PLATFORM"] = "xcb"  # make bench runs under xvfb-run, as make test does
    env.update(extra or {})
    return env


def run_step(cmd: list[str], *, env_extra: dict[str, str] | None = None) -> Step:
    """Run one command to its end."""
    with tempfile.TemporaryDirectory(prefix="ctdrill-bench-suite-") as tmp:
        log = Path(tmp) / "out.txt"
        proc, t0 = _start(cmd, _env(env_extra), log)
        return _wait(proc, t0, log)


def run_pytest(
    args: list[str],
    *,
    env_extra: dict[str, str] | None = None,
    beside: tuple[list[str], dict[str, str]] | None = None,
) -> tuple[PytestRun, Step | None]:
    """One ``python -m pytest -q`` over ``args`` with the CPU plugin, and the command
    ``beside`` (with its extra environment) started just before it and awaited after it."""
    with tempfile.TemporaryDirectory(prefix="ctdrill-bench-suite-") as tmp:
        out = Path(tmp) / "rows.jsonl"
        cmd = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider"]
        cmd += ["-p", "bench.suite_cpu", *args]
        other = None
        if beside is not None:
            other = _start(beside[0], _env(beside[1]), Path(tmp) / "beside.txt")
        proc, t0 = _start(cmd, _env({**(env_extra or {}), OUT_ENV: str(out)}), Path(tmp) / "o")
        step = _wait(proc, t0, Path(tmp) / "o")
        other_step = _wait(*other, Path(tmp) / "beside.txt") if other is not None else None
        text = out.read_text(encoding="utf-8") if out.is_file() else ""
        rows = tuple(json.loads(line) for line in text.splitlines())
    run = PytestRun(rows, step.wall_s, step.cpu_s, step.returncode, step.tail.strip("= "))
    return run, other_step


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


def _step_row(label: str, s: Step | None) -> tuple[str, ...]:
    if s is None:
        return (label, "not run (quick)", "", "")
    return (label, f"exit {s.returncode}", f"{s.cpu_s:.1f}", f"{s.wall_s:.1f}")


def run(quick: bool) -> Section:
    """``make test`` step by step (or, quick, one small module), its serial peer, the model
    tests and the BLAS peer."""
    suite_args = ["tests/model/test_calibration.py"] if quick else list(PYTEST_ARGS)
    model_args = ["tests/model/test_band.py"] if quick else ["tests/model"]
    peer_args = ["tests/model/test_band.py"] if quick else [PEER_MODULE]
    ruff = str(Path(sys.executable).with_name("ruff"))
    load0 = os.getloadavg()[0]
    with tempfile.TemporaryDirectory(prefix="ctdrill-bench-caches-") as caches:
        # a fresh clone's caches: numba's (the warm-up fills it, the tests read it) and mypy's
        fresh = {"NUMBA_CACHE_DIR": str(Path(caches) / "numba")}
        lint_targets = ["bench/bench_suite.py"] if quick else ["."]
        fmt = run_step([ruff, "format", "--check", *lint_targets])
        lint = run_step([ruff, "check", *lint_targets])
        warm = (
            None
            if quick
            else run_step([sys.executable, "-m", "ctdrill.app.search.warmup"], env_extra=fresh)
        )
        mypy_cmd = ["bash", "scripts/typecheck.sh"]
        beside = None if quick else (mypy_cmd, {"MYPY_CACHE_DIR": str(Path(caches) / "mypy")})
        load1 = os.getloadavg()[0]
        suite, mypy = run_pytest(
            [*suite_args, *WORKER_ARGS], env_extra=None if quick else fresh, beside=beside
        )
        load2 = os.getloadavg()[0]
        serial, _ = run_pytest([*suite_args, "-p", "no:xdist"], env_extra=None if quick else fresh)
    load3 = os.getloadavg()[0]
    model, _ = run_pytest([*model_args, "-p", "no:xdist"])
    peer_one, _ = run_pytest(
        [*peer_args, "-p", "no:xdist"], env_extra={"OPENBLAS_NUM_THREADS": "1"}
    )
    peer_two, _ = run_pytest(
        [*peer_args, "-p", "no:xdist"], env_extra={"OPENBLAS_NUM_THREADS": "2"}
    )
    load4 = os.getloadavg()[0]

    pre = [s for s in (fmt, lint, warm) if s is not None]
    pre_wall = sum(s.wall_s for s in pre)
    pre_cpu = sum(s.cpu_s for s in pre)
    make_wall = pre_wall + max(suite.wall_s, mypy.wall_s if mypy else 0.0)
    workers = suite.worker_cpu_s()
    mypy_cpu = mypy.cpu_s if mypy else 0.0
    # idle estimate: each worker on a core, mypy sharing them while it runs
    idle_pytest = max(max(workers.values(), default=0.0), (suite.cpu_s + mypy_cpu) / 2)
    idle_estimate = pre_cpu + idle_pytest
    speedup = serial.wall_s / max(suite.wall_s, 1e-9)
    ratio = peer_two.cpu_s / max(peer_one.cpu_s, 1e-9)
    ok = [s.returncode == 0 for s in pre] + [suite.returncode == 0, serial.returncode == 0]
    ok.append(mypy is None or mypy.returncode == 0)
    dirs = by_directory(suite.rows)
    dir_rows = [(f"`{d}`", f"{n:.0f}", f"{c:.1f}", f"{w:.1f}") for d, (n, c, w) in dirs.items()]
    tot = [sum(v[i] for v in dirs.values()) for i in range(3)]
    dir_rows.append(("**total**", f"{tot[0]:.0f}", f"{tot[1]:.1f}", f"{tot[2]:.1f}"))
    tests = [r for r in suite.rows if r["id"] != COLLECT]
    slow = sorted(tests, key=lambda r: -_cpu(r))[:10]
    slow_rows = [(f"`{r['id']}`", f"{_cpu(r):.2f}", f"{float(r['wall_s']):.2f}") for r in slow]
    names = ("`tests/model/test_calibration.py`", "`tests/model/test_band.py`")
    if not quick:
        names = ("suite (`-m 'not bench_smoke'`)", "`tests/model`")
    md = [
        f"Load average on the 2-core machine: {load0:.1f} before ruff, {load1:.1f} when pytest "
        f"started, {load2:.1f} after it, {load3:.1f} after the serial peer, {load4:.1f} at the "
        "end. Each row is one process; CPU is user + system of its waited-for process tree "
        "(pytest's with its workers). make test's "
        "steps in its order, its caches empty as on a fresh clone (numba's, mypy's):",
        "",
        table(
            ["step", "result", "CPU s", "wall s"],
            [
                _step_row("`ruff format --check`", fmt),
                _step_row("`ruff check`", lint),
                _step_row("warm-up (`python -m ctdrill.app.search.warmup`)", warm),
                _step_row("mypy (`bash scripts/typecheck.sh`), beside pytest", mypy),
                _run_row(f"pytest {names[0]}, `{' '.join(WORKER_ARGS)}`", suite),
                (
                    "**make test**",
                    "",
                    f"{pre_cpu + suite.cpu_s + mypy_cpu:.1f}",
                    f"{make_wall:.1f}",
                ),
                _run_row(f"peer: pytest {names[0]}, serial (`-p no:xdist`)", serial),
                _run_row(f"pytest {names[1]}, serial", model),
                _run_row("BLAS peer module, 1 OpenBLAS thread", peer_one),
                _run_row("BLAS peer module, 2 OpenBLAS threads", peer_two),
            ],
        ),
        "",
        f"Wall time of the serial peer over the 2 workers' at the loads above: {speedup:.2f}. "
        "CPU of each worker's tests (the plugin's rows): "
        + ", ".join(f"{w} {c:.1f} s" for w, c in workers.items())
        + f". Idle estimate of make test from CPU (each worker on a core, mypy sharing them): "
        f"{pre_cpu:.0f} s before pytest + {idle_pytest:.0f} s = {idle_estimate:.0f} s, goal "
        f"{SUITE_GOAL_S:.0f} s (tests that wait on time-outs add to it).",
        "",
        "make test's 2 workers: the window tests (`tests/app/gui`) are one work unit, run one "
        "after another in one worker (the scheduler in `tests/conftest.py`), every other module "
        "a unit of its own, given to whichever worker is free; every wait of a window test on "
        "a condition allows 30 s (`LOAD_TIMEOUT_MS`). On a shared machine the workers get the "
        "cores' share the other processes leave, so the wall ratio against the serial peer "
        "follows the load of each run; the idle estimate reads CPU.",
        "",
        f"BLAS peer module `{peer_args[0]}`: 2 OpenBLAS threads cost {ratio:.2f} x the CPU of one.",
        "",
        "Per directory, the 2-worker run (CPU and wall summed over each test's set-up, call and "
        "tear-down; the collection once a worker):",
        "",
        table(["directory", "tests", "CPU s", "wall s"], dir_rows),
        "",
        "The ten most expensive tests by CPU:",
        "",
        table(["test", "CPU s", "wall s"], slow_rows),
    ]
    shortfalls = []
    if not all(ok):
        shortfalls.append(
            f"a step of make test did not pass: pytest {suite.summary}; serial {serial.summary}"
            + (f"; mypy exit {mypy.returncode}" if mypy else "")
        )
    if not quick and make_wall > SUITE_GOAL_S:
        shortfalls.append(
            f"make test took {make_wall:.0f} s at load {load1:.1f}-{load2:.1f} "
            f"(idle estimate from CPU {idle_estimate:.0f} s), goal {SUITE_GOAL_S:.0f} s"
        )
    if not quick and model.wall_s > MODEL_GOAL_S:
        shortfalls.append(
            f"tests/model took {model.wall_s:.0f} s (CPU {model.cpu_s:.0f} s) at load "
            f"{load3:.1f}, goal {MODEL_GOAL_S:.0f} s"
        )
    headline = (
        headline_row(
            "#37 make test, wall (2 workers, mypy beside)",
            f"{make_wall:.0f} s",
            f"{serial.wall_s:.0f} s (serial pytest alone)",
            f"{speedup:.2f}",
            goal=f"<= {SUITE_GOAL_S:.0f} s idle",
        ),
        headline_row(
            "#37 tests/model, wall", f"{model.wall_s:.1f} s", goal=f"<= {MODEL_GOAL_S:.0f} s"
        ),
        headline_row(
            f"#37 {peer_args[0]}, CPU with 1 OpenBLAS thread",
            f"{peer_one.cpu_s:.1f} s",
            f"{peer_two.cpu_s:.1f} s (2 threads)",
            f"{ratio:.2f}",
        ),
    )
    return Section("The test suite", "\n".join(md), (), tuple(shortfalls), headline)
