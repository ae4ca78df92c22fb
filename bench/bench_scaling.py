"""Scaling: loading against slices, the force path against trajectories and volume size.

Loading. Series of 100, 300 and 600 slices of 512 x 512 (int16, 0.4 x 0.4 x 0.5 mm, one
Explicit VR Little Endian file per slice, 50-300 MiB) are written with
:func:`ctdrill.imaging.phantom.writer.write_series` into a temporary folder (removed afterwards).
Three readers load each: ``ctdrill.imaging.load_series``; SimpleITK's ``ImageSeriesReader`` (GDCM
file discovery and ordering included, ``SetOutputPixelType(sitkInt16)``, array view); and a raw read
of the same pixel bytes (the last ``rows * cols * 2`` bytes of every file, in a known order, into
one preallocated array: the floor, no parsing). The readers run round-robin, one run each in
turn. Warm runs repeat on a hot page cache; cold runs drop it before every run
(``sync; echo 3 > /proc/sys/vm/drop_caches``). Peak memory is the rise of the peak resident set
(``VmHWM``) over the resident set after imports, in a fresh process per reader and size, so no
allocator state is shared between them (quick mode: in this process). Goals (issue 8):
load_series at most 0.5 x SimpleITK's time, and within 1.5 x the raw read cold.

Force path. ``ctdrill.engine.path.plan_path`` (lip sampling at the default depth step and rings x
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
    fit_rows,
    load_rows,
    plot_load,
    same_values,
    slopes,
    why_not_linear,
    write_folders,
)
from bench.scaling_path import (
    export_profile,
    lip_profile,
    path_profile,
    plot_path,
    trajectory_scaling,
    volume_scaling,
)
from ctdrill.imaging import load_series

ROOT = Path(__file__).resolve().parents[1]
DEMO = ROOT / "assets" / "demo"
GOAL_VS_SITK = 0.5
GOAL_VS_RAW_COLD = 1.5
#: Slower than a peer means beyond this factor; closer is a tie on this shared machine.
TIE = 1.1


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


FULL = Sizes(512, (100, 300, 600), (1, 10, 100, 1000), (1, 10, 100), 12.0, 7, 3)
QUICK = Sizes(128, (16, 32), (1, 2), (1,), 4.0, 1, 0)


# ------------------------------------------------------------------------------ report


def goal_rows(rows: list[LoadRow]) -> tuple[list[list[object]], list[str]]:
    """Goal table rows per size and one line per missed goal (issue 8's loading goals)."""
    out: list[list[object]] = []
    misses: list[str] = []
    for r in rows:
        vs_sitk = r.warm["load_series"].median_s / r.warm["SimpleITK"].median_s
        cells: list[object] = [r.slices, f"{vs_sitk:.2f}"]
        checks = [("warm vs SimpleITK", vs_sitk, GOAL_VS_SITK)]
        floor = ""
        if r.cold is not None:
            c_sitk = r.cold["load_series"].median_s / r.cold["SimpleITK"].median_s
            c_raw = r.cold["load_series"].median_s / r.cold["raw"].median_s
            raw_sitk = r.cold["raw"].median_s / r.cold["SimpleITK"].median_s
            cells += [f"{c_sitk:.2f}", f"{c_raw:.2f}", f"{raw_sitk:.2f}"]
            checks += [("cold vs SimpleITK", c_sitk, GOAL_VS_SITK)]
            checks += [("cold vs raw", c_raw, GOAL_VS_RAW_COLD)]
            if raw_sitk > GOAL_VS_SITK:
                floor = (
                    f" (even the raw read of the bytes takes {raw_sitk:.2f} x SimpleITK's cold "
                    "time here: the disk, not the parser, sets this floor)"
                )
        else:
            cells += ["n/a", "n/a", "n/a"]
        missed = [
            f"{what} {ratio:.2f} x (goal <= {goal} x)"
            + (floor if what == "cold vs SimpleITK" else "")
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


def _load_text(
    sizes: Sizes, rows: list[LoadRow], cold_ok: bool, same: bool, t_write: float
) -> tuple[list[str], list[str]]:
    goal_table, misses = goal_rows(rows)
    n = [float(r.slices) for r in rows]
    warm = {name: [r.warm[name].median_s for r in rows] for name in READERS}
    cold = {name: [r.cold[name].median_s for r in rows if r.cold] for name in READERS}
    peak = {name: [max(r.peak_mib[name], 1e-3) for r in rows] for name in READERS}
    ratio = ", ".join(f"{name} {rows[-1].peak_mib[name] / rows[-1].mib:.2f}" for name in READERS)
    if cold_ok:
        cache = "Cold: page cache dropped before every run."
    elif sizes.cold_repeats == 0:
        cache = "Cold runs skipped in quick mode: warm only."
    else:
        cache = "Cold runs not permitted here (no write access to drop_caches): warm only."
    md = [
        "### Loading time against slices",
        "",
        f"Series written in {t_write:.1f} s; the three readers return identical voxels: "
        f"{same}. {cache}",
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
                "raw / SimpleITK cold",
                "goals (<= 0.5 x SimpleITK, <= 1.5 x raw cold)",
                *(f"peak MiB {n}" for n in READERS),
                "volume MiB",
            ],
            goal_table,
        ),
        "",
        "### How loading grows",
        "",
        f"Log-log slopes against slices (1 is linear): warm {slopes(n, warm)}; "
        f"cold {slopes(n, cold) or 'n/a'}; peak memory {slopes(n, peak)}. "
        f"Peak memory over the volume's size at {rows[-1].slices} slices: {ratio}.",
        "",
        "A straight-line fit `y = fixed + per_slice x n` separates a one-off cost per call "
        "(folder listing, series discovery, setup, buffers of fixed size) from the cost per "
        "slice (open, parse, read, copy); a positive fixed cost bends the log-log line below "
        "slope 1, a negative one means the cost per slice rises with the series size.",
        "",
        table(
            [
                "reader",
                "warm fixed ms",
                "warm ms / slice",
                "cold fixed ms",
                "cold ms / slice",
                "memory fixed MiB",
                "memory MiB / slice",
            ],
            fit_rows(rows),
        ),
        "",
        "Where growth is not linear, and why:",
        "",
        *why_not_linear(rows),
        "",
    ]
    return md, [f"loading, {m}" for m in misses]


def _path_text(
    sizes: Sizes,
    traj_rows: list[list[object]],
    t_series: dict[str, list[float]],
    vol_rows: list[list[object]],
    voxels: list[float],
    v_series: dict[str, list[float]],
) -> tuple[list[str], list[str]]:
    n_traj = [float(n) for n in sizes.trajectories]
    exports = [float(n) for n in sizes.exports]
    labels = [str(row[0]) for row in vol_rows]
    checks = [
        ("plan_path", "peer", [f"{n} trajectories" for n in sizes.trajectories], t_series),
        ("plan_path", "peer", labels, v_series),
        ("lip sampling", "peer lip sampling", labels, v_series),
    ]
    shortfalls = []
    for ours_key, peer_key, names, series in checks:
        slow = [
            f"{name} ({ours / peer:.2f} x)"
            for name, ours, peer in zip(names, series[ours_key], series[peer_key], strict=True)
            if ours > TIE * peer
        ]
        if slow:
            shortfalls.append(
                f"{ours_key} is slower than its map_coordinates peer on " + ", ".join(slow)
            )
    export_slope = slopes(exports, {"export": t_series["export"]})
    md = [
        "### Force path against the number of trajectories (demo)",
        "",
        table(
            ["trajectories", "plan_path", "map_coordinates peer", "peer / ours", "export files"],
            traj_rows,
        ),
        "",
        f"Log-log slopes against trajectories: {slopes(n_traj, t_series)}"
        + (f"; {export_slope}." if export_slope else "."),
        "",
        "Ours and the peer run alternately (repeat by repeat; chunk by chunk of 10 "
        "trajectories for the larger batches), so that load from elsewhere hits both alike. "
        f"Ours counts as slower than a peer when its median is more than {TIE:g} x the "
        "peer's; closer is within run-to-run noise on this shared machine.",
        "",
        "### One trajectory against volume size",
        "",
        f"The same {sizes.depth_mm:g} mm trajectory down the middle of each volume.",
        "",
        table(
            [
                "volume",
                "Mvoxel",
                "plan_path",
                "peer path",
                "peer / ours",
                "lip: sample_lip_rings",
                "lip: map_coordinates",
                "peer / ours",
            ],
            vol_rows,
        ),
        "",
        f"Log-log slopes against voxels (0 is independent of the volume's size): "
        f"{slopes(voxels, v_series)}.",
        "",
    ]
    return md, shortfalls


def run(quick: bool) -> Section:
    """Loading vs slices (time, memory, goals) and the force path vs trajectories and volume."""
    sizes = QUICK if quick else FULL
    cold_ok = sizes.cold_repeats > 0 and can_drop_caches()
    profiles: list[str] = []
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
        load_md, shortfalls = _load_text(sizes, rows, cold_ok, same, t_write)
        if shortfalls:
            biggest = folders[max(folders)]
            if cold_ok:
                drop_caches()
            profiles += [
                f"Where load_series spends its time ({max(folders)} slices, "
                + ("cold" if cold_ok else "warm")
                + "; cProfile, top 10 by own time):",
                "",
                profile_top(lambda: load_series(biggest)),
                "",
            ]
        volumes = [("demo", load_series(DEMO / "ct"))]
        volumes += [(f"{sizes.side}x{sizes.side}x{n}", load_series(f)) for n, f in folders.items()]
        vol_rows, voxels, v_series = volume_scaling(
            volumes, depth_mm=sizes.depth_mm, repeats=sizes.repeats
        )
        if loglog_slope(voxels, v_series["plan_path"]) > 0.15 or any(
            ours > TIE * peer
            for ours, peer in zip(v_series["plan_path"], v_series["peer"], strict=True)
        ):
            profiles += [
                f"Where plan_path spends its time on {volumes[-1][0]} (10 runs; cProfile, top "
                "10 by own time):",
                "",
                path_profile(volumes[-1][1], sizes.depth_mm, runs=10),
                "",
            ]
        slow_lip = [
            k
            for k, (ours, peer) in enumerate(
                zip(v_series["lip sampling"], v_series["peer lip sampling"], strict=True)
            )
            if ours > TIE * peer
        ]
        if slow_lip:
            label, volume = volumes[slow_lip[0]]
            profiles += [
                f"Where sample_lip_rings spends its time on {label} (50 runs; cProfile, top 10 "
                "by own time):",
                "",
                lip_profile(volume, sizes.depth_mm, runs=50),
                "",
            ]
        del volumes
    traj_rows, t_series = trajectory_scaling(
        sizes.trajectories, sizes.exports, repeats=sizes.repeats
    )
    if not quick:  # the export dominates the force path's cost; quick mode skips its profile
        profiles += [
            "Where the export of one trajectory spends its time (cProfile, top 10 by own time):",
            "",
            export_profile(),
            "",
        ]
    path_md, path_short = _path_text(sizes, traj_rows, t_series, vol_rows, voxels, v_series)
    figures = (
        str(plot_load(rows)),
        str(plot_path(sizes.trajectories, t_series, sizes.exports, voxels, v_series)),
    )
    md = [__doc__.split("\n\n", 1)[1].strip() if __doc__ else "", "", *load_md, *path_md]
    md += ["### Profiles", "", *profiles]
    return Section(
        title="Scaling",
        markdown="\n".join(md),
        figures=figures,
        shortfalls=tuple(shortfalls + path_short),
    )
