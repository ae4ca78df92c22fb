"""Timing helpers and the Markdown report shared by every benchmark module."""

from __future__ import annotations

import gc
import os
import platform
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from importlib import metadata

import numpy as np


@dataclass(frozen=True)
class Timing:
    """Wall-clock timing of repeated runs, seconds."""

    median_s: float
    p25_s: float
    p75_s: float
    min_s: float
    repeats: int

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
    arr = np.asarray(samples)
    return Timing(
        median_s=float(np.median(arr)),
        p25_s=float(np.percentile(arr, 25)),
        p75_s=float(np.percentile(arr, 75)),
        min_s=float(arr.min()),
        repeats=repeats,
    )


@dataclass(frozen=True)
class Section:
    """One benchmark's part of ``docs/benchmarks.md``."""

    title: str
    markdown: str
    figures: tuple[str, ...] = field(default=())


def table(header: Sequence[str], rows: Sequence[Sequence[object]]) -> str:
    """A Markdown table."""
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


def machine_info() -> str:
    """Machine, allocator settings and library versions, as a Markdown list."""
    libs = []
    for dist in ("numpy", "scipy", "pydicom", "SimpleITK", "vtk", "pyvista", "PySide6_Essentials"):
        try:
            libs.append(f"{dist} {metadata.version(dist)}")
        except metadata.PackageNotFoundError:
            continue
    return "\n".join(
        [
            f"- Machine: {platform.machine()}, {os.cpu_count()} cores, {platform.platform()}",
            f"- Python {platform.python_version()}; {', '.join(libs)}",
            "- Allocator: MALLOC_TRIM_THRESHOLD_="
            f"{os.environ.get('MALLOC_TRIM_THRESHOLD_', '(glibc default)')}",
        ]
    )
