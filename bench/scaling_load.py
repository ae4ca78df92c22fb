"""Loading scaling for ``bench_scaling``: readers, series, peak memory, the figure.

Not a benchmark module of its own (no ``bench_`` prefix): ``bench/bench_scaling.py`` calls it.
``python -m bench.scaling_load READER FOLDER SIDE`` is the child process that measures one
reader's peak memory with nothing else loaded.
"""

from __future__ import annotations

import gc
import os
import subprocess
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bench.report import (
    Timing,
    figure_path,
    loglog_slope,
    peak_rss_mib,
    reset_peak_rss,
    rss_mib,
    time_round,
)
from ctdrill.imaging import load_series
from ctdrill.imaging.phantom.writer import write_series

ROOT = Path(__file__).resolve().parents[1]
LOAD_FIGURE = "load_scaling.png"
READERS = ("load_series", "SimpleITK", "raw")
SPACING_MM = (0.4, 0.4, 0.5)  # (col, row, slice)


def can_drop_caches() -> bool:
    """Whether this process may drop the page cache (root, writable ``/proc/sys/vm``)."""
    return os.access("/proc/sys/vm/drop_caches", os.W_OK)


def drop_caches() -> bool:
    """Write back dirty pages and drop the page cache; False when not permitted."""
    try:
        os.sync()
        with open("/proc/sys/vm/drop_caches", "w", encoding="ascii") as fh:
            fh.write("3\n")
    except OSError:
        return False
    return True


def sitk_read(folder: Path) -> tuple[np.ndarray, object]:
    """SimpleITK (GDCM) series read as int16: (slices, rows, cols) view and the image it needs."""
    import SimpleITK as sitk

    reader = sitk.ImageSeriesReader()
    reader.SetFileNames(sitk.ImageSeriesReader.GetGDCMSeriesFileNames(str(folder)))
    reader.SetOutputPixelType(sitk.sitkInt16)
    image = reader.Execute()
    return sitk.GetArrayViewFromImage(image), image  # the view needs the image alive


def raw_read(paths: list[Path], shape: tuple[int, int, int]) -> np.ndarray:
    """The last ``rows * cols * 2`` bytes of each file, in order, into one int16 array."""
    out = np.empty(shape, dtype=np.int16)
    nbytes = shape[1] * shape[2] * 2
    for k, path in enumerate(paths):
        with path.open("rb") as fh:
            fh.seek(-nbytes, os.SEEK_END)
            fh.readinto(out[k].data.cast("B"))
    return out


def reader(name: str, folder: Path, side: int) -> Callable[[], object]:
    """A no-argument loader of ``folder`` (``side`` x ``side`` slices) for reader ``name``."""
    paths = sorted(folder.iterdir())
    shape = (len(paths), side, side)
    if name == "load_series":
        return lambda: load_series(folder)
    if name == "SimpleITK":
        return lambda: sitk_read(folder)
    return lambda: raw_read(paths, shape)


def measure_peak_mib(name: str, folder: Path, side: int) -> float:
    """Peak RSS rise (MiB) over the RSS before one load, in this process."""
    fn = reader(name, folder, side)
    gc.collect()
    reset_peak_rss()
    base = rss_mib()
    kept = fn()
    peak = peak_rss_mib() - base
    del kept
    return peak


def peak_mib(jobs: list[tuple[str, Path, int]], *, fresh: bool = True) -> list[float]:
    """Peak RSS rise (MiB) of each (reader, folder, side) load.

    ``fresh``: each in its own new process (two at a time; memory does not depend on timing),
    so no allocator state is shared; else one after the other in this process (quick mode).
    """
    if not fresh:
        return [measure_peak_mib(name, folder, side) for name, folder, side in jobs]
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    results: list[float] = []
    for start in range(0, len(jobs), 2):
        procs = [
            subprocess.Popen(
                [sys.executable, "-m", "bench.scaling_load", name, str(folder), str(side)],
                stdout=subprocess.PIPE,
                text=True,
                env=env,
                cwd=ROOT,
            )
            for name, folder, side in jobs[start : start + 2]
        ]
        for proc in procs:
            out, _ = proc.communicate()
            if proc.returncode != 0:
                raise RuntimeError(f"peak-memory child failed ({proc.args!r})")
            results.append(float(out.strip().splitlines()[-1]))
    return results


@dataclass(frozen=True)
class LoadRow:
    """One series size: timings per reader (warm; cold or None) and peak RSS rise, MiB."""

    slices: int
    mib: float
    warm: dict[str, Timing]
    cold: dict[str, Timing] | None
    peak_mib: dict[str, float]


def write_folders(tmp: Path, side: int, slices: tuple[int, ...]) -> dict[int, Path]:
    """Folders ``<side>x<n>`` holding the first n slices of one written series (hard links)."""
    rng = np.random.default_rng(0)
    hu = rng.integers(-1000, 2000, size=(max(slices), side, side), dtype=np.int16)
    affine = np.diag([*SPACING_MM, 1.0])
    affine[:3, 3] = (-0.2 * side, -0.2 * side, 0.0)
    written = write_series(tmp / "all", hu, affine)
    del hu
    folders = {}
    for n in slices:
        folder = tmp / f"{side}x{n}"
        folder.mkdir()
        for path in written.paths[:n]:
            os.link(path, folder / path.name)
        folders[n] = folder
    return folders


def load_rows(
    folders: dict[int, Path], side: int, *, repeats: int, cold_repeats: int, fresh: bool
) -> list[LoadRow]:
    """Warm and (``cold_repeats`` > 0) cold timings and peak memory of every reader and size.

    ``fresh``: peak memory of each load in a new process (see :func:`peak_mib`).
    """
    jobs = [(name, folder, side) for folder in folders.values() for name in READERS]
    peaks = iter(peak_mib(jobs, fresh=fresh))
    rows = []
    for n, folder in folders.items():
        fns = {name: reader(name, folder, side) for name in READERS}
        warm = time_round(fns, repeats=repeats)
        cold = (
            time_round(fns, repeats=cold_repeats, warmup=0, before_each=drop_caches)
            if cold_repeats
            else None
        )
        peak = {name: next(peaks) for name in READERS}
        rows.append(LoadRow(n, n * side**2 * 2 / 2**20, warm, cold, peak))
    return rows


def same_values(folder: Path, side: int) -> bool:
    """load_series, SimpleITK and the raw bytes give identical voxels."""
    ours = load_series(folder).hu
    view, _image = sitk_read(folder)
    raw = raw_read(sorted(folder.iterdir()), (ours.shape[0], side, side))
    return bool(np.array_equal(ours, view) and np.array_equal(ours, raw))


# ------------------------------------------------------------------------------ growth


def growth(slope: float) -> str:
    """A log-log slope in words: flat, falling, linear, sublinear or superlinear."""
    if abs(slope) < 0.15:
        return "flat"
    if slope < 0.0:
        return "falling"
    if 0.85 <= slope <= 1.15:
        return "linear"
    return "sublinear" if slope < 0.85 else "superlinear"


def slopes(x: list[float], named: dict[str, list[float]]) -> str:
    """``name slope (growth)`` for every series of ``named`` measured at every ``x``."""
    return ", ".join(
        f"{name} {loglog_slope(x, y):.2f} ({growth(loglog_slope(x, y))})"
        for name, y in named.items()
        if len(y) == len(x) and len(x) >= 2
    )


def _series_of(rows: list[LoadRow], name: str) -> dict[str, list[float]]:
    """Warm and cold times (s) and peak memory (MiB) of reader ``name``, per size."""
    out = {
        "warm": [r.warm[name].median_s for r in rows],
        "cold": [r.cold[name].median_s for r in rows if r.cold],
        "memory": [r.peak_mib[name] for r in rows],
    }
    return {key: values for key, values in out.items() if len(values) == len(rows)}


def fit_rows(rows: list[LoadRow]) -> list[list[object]]:
    """Least-squares ``y = fixed + per_slice * n`` per reader, for time and peak memory."""
    n = np.array([r.slices for r in rows], dtype=np.float64)
    out: list[list[object]] = []
    for name in READERS:
        cells: list[object] = [name]
        series = _series_of(rows, name)
        for key, scale in (("warm", 1e3), ("cold", 1e3), ("memory", 1.0)):
            if key in series and len(n) >= 2:
                per, fixed = np.polyfit(n, np.asarray(series[key]), 1)
                cells += [f"{fixed * scale:.3g}", f"{per * scale:.3g}"]
            else:
                cells += ["n/a", "n/a"]
        out.append(cells)
    return out


def why_not_linear(rows: list[LoadRow]) -> list[str]:
    """One line per reader and measure whose growth is not linear, with the fit that says why."""
    n = np.array([r.slices for r in rows], dtype=np.float64)
    lines = []
    units = {"warm": ("ms", 1e3), "cold": ("ms", 1e3), "memory": ("MiB", 1.0)}
    for name in READERS:
        for key, values in _series_of(rows, name).items():
            y = np.maximum(np.asarray(values), 1e-9)
            slope = loglog_slope(list(n), list(y))
            if growth(slope) == "linear" or len(n) < 2:
                continue
            _, fixed = np.polyfit(n, y, 1)
            unit, scale = units[key]
            if fixed > 0 and slope < 1.0:
                lines.append(
                    f"- {name}, {key}: slope {slope:.2f}; a fixed {fixed * scale:.3g} {unit} "
                    f"({fixed / y[0]:.0%} of the total at {int(n[0])} slices), whatever the "
                    "number of slices, weighs less as the series grows."
                )
            else:
                lines.append(
                    f"- {name}, {key}: slope {slope:.2f}; per slice "
                    f"{y[0] / n[0] * scale:.3g} {unit} at {int(n[0])} slices and "
                    f"{y[-1] / n[-1] * scale:.3g} {unit} at {int(n[-1])}: the cost per slice "
                    "itself changes with the series size (read it against the spread in the "
                    "table above)."
                )
    return lines or ["- Every reader grows linearly in time and memory here."]


# ------------------------------------------------------------------------------ figures


def plot_load(rows: list[LoadRow]) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = [r.slices for r in rows]
    fig, (ax_t, ax_m) = plt.subplots(1, 2, figsize=(10.0, 4.2))
    for k, name in enumerate(READERS):
        color = f"C{k}"
        med = [r.warm[name].median_s for r in rows]
        err = [
            [m - r.warm[name].p25_s for m, r in zip(med, rows, strict=True)],
            [r.warm[name].p75_s - m for m, r in zip(med, rows, strict=True)],
        ]
        ax_t.errorbar(n, med, yerr=err, fmt="o-", color=color, label=f"{name}, warm", ms=4)
        if rows[0].cold is not None:
            cold = [r.cold[name].median_s for r in rows if r.cold is not None]
            ax_t.plot(n, cold, "s--", color=color, label=f"{name}, cold", ms=4)
        ax_m.plot(n, [r.peak_mib[name] for r in rows], "o-", color=color, label=name, ms=4)
    ax_m.plot(n, [r.mib for r in rows], "k:", label="volume (int16)")
    for ax in (ax_t, ax_m):
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel(f"slices ({rows[0].mib / rows[0].slices * 1024:.0f} KiB each)")
        ax.legend(fontsize=7)
        ax.grid(True, which="both", alpha=0.3)
    ax_t.set_ylabel("load time (s), median and IQR")
    ax_m.set_ylabel("peak RSS rise (MiB)")
    ax_t.set_title("Loading time vs slices")
    ax_m.set_title("Peak memory vs slices")
    fig.tight_layout()
    out = figure_path(LOAD_FIGURE)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


if __name__ == "__main__":
    # Child of peak_mib: python -m bench.scaling_load READER FOLDER SIDE -> peak MiB on stdout.
    print(measure_peak_mib(sys.argv[1], Path(sys.argv[2]), int(sys.argv[3])))
