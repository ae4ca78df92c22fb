"""Timing, memory and profiling helpers and the Markdown pieces shared by every benchmark module.

A benchmark module ``bench/bench_<area>.py`` exposes ``run(quick: bool) -> Section``; ``python -m
bench`` collects the sections into ``docs/benchmarks.md``. Figures are written where
:func:`figure_path` says (``docs/benchmarks/`` for ``make bench``, beside the report otherwise).
"""

from __future__ import annotations

import cProfile
import gc
import io
import os
import platform
import pstats
import subprocess
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
FIGURE_DIR_ENV = "CTDRILL_BENCH_FIGURES"
DEFAULT_FIGURE_DIR = ROOT / "docs" / "benchmarks"
LIBRARIES = (
    "numpy",
    "scipy",
    "pydicom",
    "pylibjpeg",
    "pylibjpeg-libjpeg",
    "pylibjpeg-openjpeg",
    "SimpleITK",
    "vtk",
    "pyvista",
    "PySide6_Essentials",
    "matplotlib",
    "pyserial",
)


@dataclass(frozen=True)
class Timing:
    """Wall-clock timing of repeated runs, seconds."""

    median_s: float
    p25_s: float
    p75_s: float
    min_s: float
    repeats: int

    @classmethod
    def from_samples(cls, samples_s: Sequence[float]) -> Timing:
        """Median, quartiles and minimum of ``samples_s`` (seconds, at least one)."""
        arr = np.asarray(samples_s, dtype=np.float64)
        return cls(
            median_s=float(np.median(arr)),
            p25_s=float(np.percentile(arr, 25)),
            p75_s=float(np.percentile(arr, 75)),
            min_s=float(arr.min()),
            repeats=int(arr.size),
        )

    def fmt(self, unit: str = "ms") -> str:
        """Median with its inter-quartile range, e.g. ``12.3 ms [11.9-12.8]``."""
        scale = {"s": 1.0, "ms": 1e3, "us": 1e6}[unit]
        return (
            f"{self.median_s * scale:.3g} {unit} "
            f"[{self.p25_s * scale:.3g}-{self.p75_s * scale:.3g}]"
        )


def time_it(fn: Callable[[], object], *, repeats: int = 7, warmup: int = 1) -> Timing:
    """Run ``fn`` ``warmup`` times, then time ``repeats`` runs with a monotonic clock."""
    for _ in range(warmup):
        fn()
    samples = []
    for _ in range(repeats):
        gc.collect()
        t0 = time.perf_counter()
        fn()
        samples.append(time.perf_counter() - t0)
    return Timing.from_samples(samples)


def time_round(
    fns: Mapping[str, Callable[[], object]],
    *,
    repeats: int = 7,
    warmup: int = 1,
    before_each: Callable[[], object] | None = None,
) -> dict[str, Timing]:
    """Time peers round-robin (a, b, c, a, b, c, ...), so that drifting load hits all alike.

    ``before_each`` runs untimed before every timed call (e.g. dropping the page cache).
    """
    for _ in range(warmup):
        for fn in fns.values():
            fn()
    samples: dict[str, list[float]] = {name: [] for name in fns}
    for _ in range(repeats):
        for name, fn in fns.items():
            if before_each is not None:
                before_each()
            gc.collect()
            t0 = time.perf_counter()
            fn()
            samples[name].append(time.perf_counter() - t0)
    return {name: Timing.from_samples(values) for name, values in samples.items()}


def time_pair(
    fn_a: Callable[[], object],
    fn_b: Callable[[], object],
    *,
    repeats: int = 7,
    warmup: int = 1,
) -> tuple[Timing, Timing]:
    """Time two peers alternately (a, b, a, b, ...); see :func:`time_round`."""
    got = time_round({"a": fn_a, "b": fn_b}, repeats=repeats, warmup=warmup)
    return got["a"], got["b"]


@dataclass(frozen=True)
class Section:
    """One benchmark's part of ``docs/benchmarks.md``.

    ``figures`` are paths of written figures (absolute, or relative to the repository root);
    ``shortfalls`` are one-line statements of where ctdrill is slower than a peer or misses a
    goal, repeated in the report's summary. ``headline`` rows go into the report's headline
    table, each :data:`HEADLINE_COLUMNS` long (use :func:`headline_row`).
    """

    title: str
    markdown: str
    figures: tuple[str, ...] = field(default=())
    shortfalls: tuple[str, ...] = field(default=())
    headline: tuple[tuple[str, ...], ...] = field(default=())


#: Columns of the report's headline table (one row per headline figure of any module).
HEADLINE_COLUMNS = ("work", "ctdrill", "peer", "peer / ctdrill", "goal")


def headline_row(
    work: str, ours: str, peer: str = "", ratio: str = "", goal: str = ""
) -> tuple[str, ...]:
    """One row of the headline table: what was measured, our figure, the peer's, their
    ratio and the goal it answers (empty cells allowed)."""
    return (work, ours, peer, ratio, goal)


def table(header: Sequence[str], rows: Sequence[Sequence[object]]) -> str:
    """A Markdown table."""
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


def figure_path(name: str) -> Path:
    """Where to write the figure ``name`` (e.g. ``"load_scaling.png"``); folder created.

    ``$CTDRILL_BENCH_FIGURES`` when set (``python -m bench`` sets it beside its ``--out``),
    else ``docs/benchmarks/``.
    """
    folder = Path(os.environ.get(FIGURE_DIR_ENV, str(DEFAULT_FIGURE_DIR)))
    folder.mkdir(parents=True, exist_ok=True)
    return folder / name


def loglog_slope(x: Sequence[float], y: Sequence[float]) -> float:
    """Least-squares slope of log(y) against log(x): 1.0 is linear growth."""
    lx = np.log(np.asarray(x, dtype=np.float64))
    ly = np.log(np.asarray(y, dtype=np.float64))
    return float(np.polyfit(lx, ly, 1)[0])


def profile_top(fn: Callable[[], object], *, n: int = 10) -> str:
    """Run ``fn`` once under cProfile; Markdown table of the ``n`` costliest functions.

    Sorted by own time (``tottime``), with cumulative time beside it, milliseconds.
    """
    prof = cProfile.Profile()
    prof.enable()
    fn()
    prof.disable()
    stats = pstats.Stats(prof, stream=io.StringIO())
    entries = []
    for (filename, line, func), (_, ncalls, tottime, cumtime, _) in stats.stats.items():  # type: ignore[attr-defined]
        short = filename
        for marker in ("site-packages/", str(ROOT) + "/"):
            if marker in filename:
                short = filename.split(marker, 1)[1]
        where = f"{short}:{line}({func})" if line else func
        entries.append((tottime, cumtime, ncalls, where))
    entries.sort(reverse=True)
    rows = [
        [f"`{where}`", ncalls, f"{tot * 1e3:.1f}", f"{cum * 1e3:.1f}"]
        for tot, cum, ncalls, where in entries[:n]
    ]
    return table(["function", "calls", "own ms", "cumulative ms"], rows)


# ------------------------------------------------------------------------------ memory


def _status_kib(key: str) -> int:
    with open("/proc/self/status", encoding="ascii") as fh:
        for line in fh:
            if line.startswith(key + ":"):
                return int(line.split()[1])
    raise KeyError(key)


def rss_mib() -> float:
    """Resident set size of this process now, MiB (``VmRSS``)."""
    return _status_kib("VmRSS") / 1024.0


def peak_rss_mib() -> float:
    """Peak resident set size of this process, MiB (``VmHWM``)."""
    return _status_kib("VmHWM") / 1024.0


def reset_peak_rss() -> bool:
    """Reset ``VmHWM`` to the current RSS (``echo 5 > /proc/self/clear_refs``); False if denied."""
    try:
        with open("/proc/self/clear_refs", "w", encoding="ascii") as fh:
            fh.write("5\n")
    except OSError:
        return False
    return True


# ------------------------------------------------------------------------------ machine


def _cpu_model() -> str:
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as fh:
            for line in fh:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def _memory_gib() -> str:
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            kib = int(fh.readline().split()[1])
    except (OSError, ValueError, IndexError):
        return "unknown"
    return f"{kib / 2**20:.1f} GiB"


def _git_revision() -> str:
    try:
        rev = subprocess.run(
            ["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"],
            capture_output=True,
            text=True,
            check=True,
            timeout=10,
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "-C", str(ROOT), "status", "--porcelain", "--untracked-files=no"],
            capture_output=True,
            text=True,
            check=True,
            timeout=10,
        ).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    return rev + (" with uncommitted changes" if dirty else "")


def machine_info() -> str:
    """Machine, date, revision, allocator settings and library versions, as a Markdown list."""
    libs = []
    for dist in LIBRARIES:
        try:
            libs.append(f"{dist} {metadata.version(dist)}")
        except metadata.PackageNotFoundError:
            continue
    known = ("MALLOC_TRIM_THRESHOLD_", "MALLOC_MMAP_THRESHOLD_")
    allocator = ", ".join(f"{key}={os.environ.get(key, '(glibc default)')}" for key in known)
    others = sorted(k for k in os.environ if k.startswith("MALLOC_") and k not in known)
    if others:
        allocator += ", " + ", ".join(f"{k}={os.environ[k]}" for k in others)
    threads = ", ".join(
        f"{k}={os.environ[k]}"
        for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")
        if k in os.environ
    )
    return "\n".join(
        [
            f"- Date: {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; "
            f"revision {_git_revision()}",
            f"- Machine: {_cpu_model()}, {os.cpu_count()} logical cores, {_memory_gib()} RAM, "
            f"{platform.platform()} ({platform.machine()})",
            f"- Python {platform.python_version()}; {', '.join(libs)}",
            f"- Allocator (glibc malloc): {allocator}",
            f"- Threads: {threads or 'library defaults'}; "
            f"display {os.environ.get('DISPLAY', '(none)')}",
        ]
    )
