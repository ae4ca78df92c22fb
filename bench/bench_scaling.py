"""Scaling: loading against slices, the force path against trajectories and volume size.

Loading. Series of 100, 300 and 600 slices of 512 x 512 (int16, 0.4 x 0.4 x 0.5 mm, one
Explicit VR Little Endian file per slice, 50-300 MiB) are written with
:func:`imaging.dicom_writer.write_series` into a temporary folder (removed afterwards). Three
readers load each: ``imaging.load_series``; SimpleITK's ``ImageSeriesReader`` (GDCM file
discovery and ordering included, ``SetOutputPixelType(sitkInt16)``, array view); and a raw read
of the same pixel bytes (the last ``rows * cols * 2`` bytes of every file, in a known order, into
one preallocated array: the floor, no parsing). Warm runs repeat on a hot page cache; cold runs
drop it before every run (``sync; echo 3 > /proc/sys/vm/drop_caches``). Peak memory is the rise
of the peak resident set (``VmHWM``) over the resident set after imports, in a fresh process
per reader and size, so no allocator state is shared between them (quick mode: in this
process). Goals (issue 8): load_series at most 0.5 x SimpleITK's time, and within 1.5 x the
raw read cold.

Force path. ``app.pipeline.plan_path`` (lip sampling at the default depth step and rings x
angles, profile, clearance to the canal, exact max safe depth) on the demo case for 1 to 1000
candidate trajectories (entries within +-3 mm, axes tilted up to 15 degrees), against a plain
peer doing the same work with ``scipy.ndimage.map_coordinates(order=1, mode="constant",
cval=-1000)`` on the same lip points and the same profile and clearance code. The export
(``write_exports``: two CSV files, the summary and the plot per trajectory) for 1 to 100. Then
one trajectory of the same length on volumes from the demo's 0.6 Mvoxel to 157 Mvoxel.
"""

from __future__ import annotations

import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from bench.report import Section, loglog_slope, profile_top, table
from bench.scaling_load import (
    READERS,
    LoadRow,
    can_drop_caches,
    drop_caches,
    load_rows,
    plot_load,
    same_values,
    write_folders,
)
from bench.scaling_path import plot_path, trajectory_scaling, volume_scaling
from imaging import load_series

ROOT = Path(__file__).resolve().parents[1]
DEMO = ROOT / "assets" / "demo"
GOAL_VS_SITK = 0.5
GOAL_VS_RAW_COLD = 1.5


@dataclass(frozen=True)
class Sizes:
    """What one mode measures."""

    side: int
    slices: tuple[int, ...]
    trajectories: tuple[int, ...]
    exports: tuple[int, ...]
    depth_mm: float
    repeats: int
    cold_repeats: int


FULL = Sizes(512, (100, 300, 600), (1, 10, 100, 1000), (1, 10, 100), 12.0, 5, 3)
QUICK = Sizes(128, (16, 32), (1, 2), (1,), 4.0, 1, 0)


# ------------------------------------------------------------------------------ report


def _growth(slope: float) -> str:
    if abs(slope) < 0.15:
        return "flat"
    if slope < 0.0:
        return "falling"
    if 0.85 <= slope <= 1.15:
        return "linear"
    return "sublinear" if slope < 0.85 else "superlinear"


def _goal_rows(rows: list[LoadRow]) -> tuple[list[list[object]], list[str]]:
    out: list[list[object]] = []
    misses: list[str] = []
    for r in rows:
        vs_sitk = r.warm["load_series"].median_s / r.warm["SimpleITK"].median_s
        cells: list[object] = [r.slices, f"{vs_sitk:.2f}"]
        checks = [("warm vs SimpleITK", vs_sitk, GOAL_VS_SITK)]
        if r.cold is not None:
            c_sitk = r.cold["load_series"].median_s / r.cold["SimpleITK"].median_s
            c_raw = r.cold["load_series"].median_s / r.cold["raw"].median_s
            cells += [f"{c_sitk:.2f}", f"{c_raw:.2f}"]
            checks += [("cold vs SimpleITK", c_sitk, GOAL_VS_SITK)]
            checks += [("cold vs raw", c_raw, GOAL_VS_RAW_COLD)]
        else:
            cells += ["n/a", "n/a"]
        missed = [
            f"{what} {ratio:.2f} x (goal <= {goal} x)"
            for what, ratio, goal in checks
            if ratio > goal
        ]
        misses += [f"{r.slices} slices: {m}" for m in missed]
        cells.append("met" if not missed else "**missed**: " + "; ".join(missed))
        cells += [f"{r.peak_mib[name]:.0f}" for name in READERS]
        cells.append(f"{r.mib:.3g}")
        out.append(cells)
    return out, misses


def _time_rows(rows: list[LoadRow]) -> list[list[object]]:
    out: list[list[object]] = []
    for r in rows:
        cells: list[object] = [r.slices, f"{r.mib:.3g}"]
        cells += [r.warm[name].fmt("s") for name in READERS]
        cells += [r.cold[name].fmt("s") if r.cold else "n/a" for name in READERS]
        out.append(cells)
    return out


def _slopes(x: list[float], named: dict[str, list[float]]) -> str:
    return ", ".join(
        f"{name} {loglog_slope(x, y):.2f} ({_growth(loglog_slope(x, y))})"
        for name, y in named.items()
        if len(y) == len(x) and len(x) >= 2
    )


def run(quick: bool) -> Section:
    """Loading vs slices (time, memory, goals) and the force path vs trajectories and volume."""
    sizes = QUICK if quick else FULL
    cold_ok = sizes.cold_repeats > 0 and can_drop_caches()
    with tempfile.TemporaryDirectory(prefix="ctdrill-bench-scaling-") as tmp:
        t0 = time.perf_counter()
        folders = write_folders(Path(tmp), sizes.side, sizes.slices)
        t_write = time.perf_counter() - t0
        same = same_values(folders[min(folders)], sizes.side)
        rows = load_rows(
            folders,
            sizes.side,
            repeats=sizes.repeats,
            cold_repeats=sizes.cold_repeats if cold_ok else 0,
            fresh=not quick,
        )
        goal_rows, misses = _goal_rows(rows)
        biggest = folders[max(folders)]
        profile = ""
        if misses:
            if cold_ok:
                drop_caches()
            profile = profile_top(lambda: load_series(biggest))
        volumes = [("demo", load_series(DEMO / "ct"))]
        volumes += [(f"{sizes.side}x{sizes.side}x{n}", load_series(f)) for n, f in folders.items()]
        vol_rows, voxels, v_series = volume_scaling(
            volumes, depth_mm=sizes.depth_mm, repeats=sizes.repeats
        )
        del volumes
    traj_rows, t_series = trajectory_scaling(
        sizes.trajectories, sizes.exports, repeats=sizes.repeats
    )
    figures = (
        str(plot_load(rows)),
        str(plot_path(sizes.trajectories, t_series, sizes.exports, voxels, v_series)),
    )
    n_slices = [float(r.slices) for r in rows]
    warm = {name: [r.warm[name].median_s for r in rows] for name in READERS}
    cold = {name: [r.cold[name].median_s for r in rows if r.cold] for name in READERS}
    peak = {name: [max(r.peak_mib[name], 1e-3) for r in rows] for name in READERS}
    n_traj = [float(n) for n in sizes.trajectories]
    shortfalls = [f"loading, {m}" for m in misses]
    slower = [
        n
        for n, ours, peer in zip(
            sizes.trajectories, t_series["plan_path"], t_series["peer"], strict=True
        )
        if ours > peer
    ]
    if slower:
        shortfalls.append(
            f"plan_path is slower than the map_coordinates peer for {slower} trajectories on "
            "the demo (force-path table)"
        )
    slower_vol = [
        label
        for (label, *_), ours, peer in zip(
            vol_rows, v_series["plan_path"], v_series["peer"], strict=True
        )
        if ours > peer
    ]
    if slower_vol:
        shortfalls.append(
            f"plan_path is slower than the map_coordinates peer on volumes {slower_vol} "
            "(volume-size table)"
        )
    md = [
        __doc__.split("\n\n", 1)[1].strip() if __doc__ else "",
        "",
        "### Loading time against slices",
        "",
        f"Series written in {t_write:.1f} s; the three readers return identical voxels: {same}. "
        + (
            "Cold: page cache dropped before every run."
            if cold_ok
            else "Cold runs skipped (quick mode, or no write access to drop_caches): warm only."
            if not sizes.cold_repeats or not can_drop_caches()
            else ""
        ),
        "",
        table(
            ["slices", "MiB", *(f"{n} warm" for n in READERS), *(f"{n} cold" for n in READERS)],
            _time_rows(rows),
        ),
        "",
        "### Goals and peak memory",
        "",
        table(
            [
                "slices",
                "ours / SimpleITK warm",
                "ours / SimpleITK cold",
                "ours / raw cold",
                "goals (<= 0.5 x SimpleITK, <= 1.5 x raw cold)",
                *(f"peak MiB {n}" for n in READERS),
                "volume MiB",
            ],
            goal_rows,
        ),
        "",
        f"Growth with slices (log-log slope; 1 is linear): warm {_slopes(n_slices, warm)}; "
        f"cold {_slopes(n_slices, cold) or 'n/a'}; peak memory {_slopes(n_slices, peak)}.",
        "",
    ]
    if profile:
        md += [
            f"Where load_series spends its time ({max(folders)} slices"
            + (", cold" if cold_ok else ", warm")
            + "; cProfile, top 10 by own time):",
            "",
            profile,
            "",
        ]
    md += [
        "### Force path against the number of trajectories (demo)",
        "",
        table(
            ["trajectories", "plan_path", "map_coordinates peer", "peer / ours", "export files"],
            traj_rows,
        ),
        "",
        f"Growth with trajectories: {_slopes(n_traj, t_series)}"
        + (
            f"; {_slopes([float(n) for n in sizes.exports], {'export': t_series['export']})}."
            if len(sizes.exports) >= 2
            else "."
        ),
        "",
        "### One trajectory against volume size",
        "",
        table(["volume", "Mvoxel", "plan_path", "lip sampling", "peer", "peer / ours"], vol_rows),
        "",
        f"Growth with voxels: {_slopes(voxels, v_series)}.",
    ]
    return Section(
        title="Scaling", markdown="\n".join(md), figures=figures, shortfalls=tuple(shortfalls)
    )
