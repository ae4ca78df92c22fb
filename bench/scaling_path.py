"""Force-path scaling for ``bench_scaling``: trajectories on the demo, one path vs volume size.

Not a benchmark module of its own (no ``bench_`` prefix): ``bench/bench_scaling.py`` calls it.
The peer does ``plan_path``'s work with ``scipy.ndimage.map_coordinates(order=1,
mode="constant", cval=-1000)`` for the lip and the same profile and clearance code, so the
difference between the two is the sampling path (and ``plan_path``'s checks of the volume).
"""

from __future__ import annotations

import tempfile
from collections.abc import Callable
from functools import partial
from pathlib import Path

import numpy as np
from scipy import ndimage

from bench.bench_export import candidates as export_candidates
from bench.report import Timing, figure_path, profile_top, time_it, time_pair
from ctdrill.app.export import write_exports
from ctdrill.engine.case import ExportJob
from ctdrill.engine.grid import DEFAULT_DEPTH_STEP_MM, depth_grid_mm
from ctdrill.engine.path import plan_path
from ctdrill.engine.settings import DEFAULTS
from ctdrill.engine.summarize import CaseContext
from ctdrill.imaging import load_series
from ctdrill.imaging.plan.landmarks import CanalLandmark
from ctdrill.imaging.plan.load import load_plan
from ctdrill.imaging.plan.safety import clearance_profile_mm, max_safe_depth_mm
from ctdrill.imaging.plan.types import DrillSpec, Plan
from ctdrill.imaging.sampling.lip import (
    DEFAULT_N_ANGLES,
    DEFAULT_N_RINGS,
    lip_ring_points,
    sample_lip_rings,
)
from ctdrill.imaging.volume import CTVolume
from ctdrill.model.calibration import Calibration, load_calibration
from ctdrill.model.profile import build_profile

ROOT = Path(__file__).resolve().parents[1]
DEMO = ROOT / "assets" / "demo"
PATH_FIGURE = "path_scaling.png"
#: Per-trajectory timings against volume size, in table order.
VOLUME_SERIES = ("plan_path", "peer", "lip sampling", "peer lip sampling")
PathFn = Callable[[CTVolume, Plan, Calibration], object]


def peer_lip_hu(volume: CTVolume, plan: Plan, depth_mm: np.ndarray) -> np.ndarray:
    """(D, R, A) lip HU by ``map_coordinates(order=1, mode="constant", cval=-1000)``."""
    pts = lip_ring_points(
        plan.entry_lps,
        plan.target_lps,
        depth_mm,
        drill=DrillSpec(diameter_mm=plan.drill.diameter_mm, tip_length_mm=plan.drill.tip_length_mm),
        n_rings=DEFAULT_N_RINGS,
        n_angles=DEFAULT_N_ANGLES,
    )
    ijk = volume.lps_to_index(pts.reshape(-1, 3))
    hu = ndimage.map_coordinates(volume.hu, ijk[:, ::-1].T, order=1, mode="constant", cval=-1000.0)
    return np.asarray(hu).reshape(pts.shape[:3])


def peer_path(volume: CTVolume, plan: Plan, calibration: Calibration) -> float:
    """``plan_path``'s work with ``map_coordinates`` for the lip; returns the max safe depth."""
    depth = depth_grid_mm(plan.planned_depth_mm, DEFAULT_DEPTH_STEP_MM)
    hu = peer_lip_hu(volume, plan, depth)
    weights = np.full(DEFAULT_N_RINGS, 1.0 / DEFAULT_N_RINGS)
    build_profile(hu, weights, depth, calibration, blades=plan.drill.blades, rpm=plan.drill.rpm)
    clearance_profile_mm(plan, plan.landmarks, depth)
    return max_safe_depth_mm(plan)


def candidates(plan: Plan, n: int) -> list[Plan]:
    """``n`` trajectories around ``plan`` (:func:`bench.bench_export.candidates`, seed 1)."""
    return export_candidates(plan, n, seed=1)


def _batch(volume: CTVolume, plans: list[Plan], cal: Calibration, fn: PathFn) -> None:
    for plan in plans:
        fn(volume, plan, cal)


def _paired_batch(
    volume: CTVolume, batch: list[Plan], cal: Calibration, *, repeats: int
) -> tuple[Timing, Timing]:
    """Total time of ``plan_path`` and of the peer over ``batch``, run alternately.

    Up to 10 trajectories: ``repeats`` alternating repeats. More: one pass, alternating ours
    and the peer chunk by chunk (10 trajectories each), the totals summed.
    """
    if len(batch) <= 10:
        return time_pair(
            partial(_batch, volume, batch, cal, plan_path),
            partial(_batch, volume, batch, cal, peer_path),
            repeats=repeats,
        )
    total_ours = total_peer = 0.0
    for start in range(0, len(batch), 10):
        chunk = batch[start : start + 10]
        ours, peer = time_pair(
            partial(_batch, volume, chunk, cal, plan_path),
            partial(_batch, volume, chunk, cal, peer_path),
            repeats=1,
            warmup=0,
        )
        total_ours += ours.median_s
        total_peer += peer.median_s
    return Timing.from_samples([total_ours]), Timing.from_samples([total_peer])


def _export(jobs: list[ExportJob], folder: Path, series_uid: str) -> None:
    n = sum(1 for _ in folder.iterdir()) if folder.exists() else 0
    write_exports(jobs, folder / f"run{n}", CaseContext(settings=DEFAULTS, series_uid=series_uid))


def _each(total_s: float, n: int) -> str:
    return f"{total_s / n * 1e3:.3g} ms each"


def trajectory_scaling(
    trajectories: tuple[int, ...], exports: tuple[int, ...], *, repeats: int
) -> tuple[list[list[object]], dict[str, list[float]]]:
    """Table rows and total times (s) per count: plan_path, peer, export (``exports`` only)."""
    volume = load_series(DEMO / "ct")
    plan = load_plan(DEMO / "plan.json")
    cal = load_calibration(plan.calibration)
    series: dict[str, list[float]] = {"plan_path": [], "peer": [], "export": []}
    rows: list[list[object]] = []
    for n in trajectories:
        batch = candidates(plan, n)
        ours, peer = _paired_batch(volume, batch, cal, repeats=repeats)
        series["plan_path"].append(ours.median_s)
        series["peer"].append(peer.median_s)
        export_cell = ""
        if n in exports:
            jobs = [ExportJob(plan_path(volume, p, cal), p.name) for p in batch]
            with tempfile.TemporaryDirectory(prefix="ctdrill-bench-export-") as tmp:
                fn = partial(_export, jobs, Path(tmp) / "out", volume.info.series_uid)
                t_exp = time_it(fn, repeats=1 if n > 10 else min(3, repeats))
            series["export"].append(t_exp.median_s)
            export_cell = f"{t_exp.fmt('s')} ({_each(t_exp.median_s, n)})"
        rows.append(
            [
                n,
                f"{ours.fmt('s')} ({_each(ours.median_s, n)})",
                f"{peer.fmt('s')} ({_each(peer.median_s, n)})",
                f"{peer.median_s / ours.median_s:.2f}",
                export_cell,
            ]
        )
    return rows, series


def volume_plan(volume: CTVolume, depth_mm: float) -> Plan:
    """A straight trajectory down the middle of ``volume`` with a canal 3 mm below its end."""
    cols, rows, slices = volume.dims
    top = volume.index_to_lps(np.array([(cols - 1) / 2, (rows - 1) / 2, slices - 1.0]))
    bottom = volume.index_to_lps(np.array([(cols - 1) / 2, (rows - 1) / 2, 0.0]))
    down = (bottom - top) / np.linalg.norm(bottom - top)
    entry = top + 1.0 * down
    target = entry + depth_mm * down
    across = np.cross(down, [1.0, 0.0, 0.0])
    canal_c = target + 3.0 * down + np.array([1.0, 0.0, 0.0])
    canal = CanalLandmark("canal", np.stack([canal_c - 10 * across, canal_c + 10 * across]), 1.2)
    return Plan(entry, target, calibration="bone-illustrative", landmarks=(canal,))


def _lip(volume: CTVolume, plan: Plan, depth_mm: np.ndarray) -> None:
    sample_lip_rings(
        volume,
        plan.entry_lps,
        plan.target_lps,
        depth_mm,
        drill=DrillSpec(diameter_mm=plan.drill.diameter_mm, tip_length_mm=plan.drill.tip_length_mm),
    )


def volume_scaling(
    volumes: list[tuple[str, CTVolume]], *, depth_mm: float, repeats: int
) -> tuple[list[list[object]], list[float], dict[str, list[float]]]:
    """One ``depth_mm`` trajectory per volume: table rows, voxel counts, times (s) per volume."""
    cal = load_calibration("bone-illustrative")
    rows: list[list[object]] = []
    voxels: list[float] = []
    series: dict[str, list[float]] = {key: [] for key in VOLUME_SERIES}
    for label, volume in volumes:
        plan = volume_plan(volume, depth_mm)
        depth = depth_grid_mm(plan.planned_depth_mm, DEFAULT_DEPTH_STEP_MM)
        ours, peer = time_pair(
            partial(plan_path, volume, plan, cal),
            partial(peer_path, volume, plan, cal),
            repeats=repeats,
        )
        lip, peer_lip = time_pair(
            partial(_lip, volume, plan, depth),
            partial(peer_lip_hu, volume, plan, depth),
            repeats=repeats,
        )
        voxels.append(float(volume.hu.size))
        for key, t in zip(VOLUME_SERIES, (ours, peer, lip, peer_lip), strict=True):
            series[key].append(t.median_s)
        rows.append(
            [
                label,
                f"{volume.hu.size / 1e6:.3g}",
                ours.fmt(),
                peer.fmt(),
                f"{peer.median_s / ours.median_s:.2f}",
                lip.fmt(),
                peer_lip.fmt(),
                f"{peer_lip.median_s / lip.median_s:.2f}",
            ]
        )
    return rows, voxels, series


def plot_path(
    traj: tuple[int, ...],
    t_series: dict[str, list[float]],
    exports: tuple[int, ...],
    voxels: list[float],
    v_series: dict[str, list[float]],
) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax_n, ax_v) = plt.subplots(1, 2, figsize=(10.0, 4.2))
    ax_n.plot(traj, t_series["plan_path"], "o-", label="plan_path")
    ax_n.plot(traj, t_series["peer"], "s--", label="map_coordinates peer")
    ax_n.plot(exports, t_series["export"], "^-", label="write_exports (files)")
    ref = np.asarray(traj, dtype=float)
    ax_n.plot(ref, t_series["plan_path"][0] * ref, "k:", label="linear")
    ax_n.set_xlabel("trajectories")
    ax_n.set_ylabel("total time (s)")
    ax_n.set_title("Force path vs number of trajectories (demo)")
    for key, fmt in zip(VOLUME_SERIES, ("o-", "s--", "^-", "v--"), strict=True):
        ax_v.plot(voxels, [t * 1e3 for t in v_series[key]], fmt, label=key)
    ax_v.set_xlabel("volume size (voxels)")
    ax_v.set_ylabel("time per trajectory (ms)")
    ax_v.set_title("One trajectory vs volume size")
    for ax in (ax_n, ax_v):
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.legend(fontsize=7)
        ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    out = figure_path(PATH_FIGURE)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def export_profile() -> str:
    """cProfile top 10 of ``write_exports`` for one demo trajectory (Markdown table)."""
    volume = load_series(DEMO / "ct")
    plan = load_plan(DEMO / "plan.json")
    job = ExportJob(plan_path(volume, plan, load_calibration(plan.calibration)), plan.name)
    with tempfile.TemporaryDirectory(prefix="ctdrill-bench-export-") as tmp:
        _export([job], Path(tmp) / "warm", volume.info.series_uid)  # imports, font cache
        return profile_top(partial(_export, [job], Path(tmp) / "out", volume.info.series_uid))


def path_profile(volume: CTVolume, depth_mm: float, *, runs: int) -> str:
    """cProfile top 10 of ``runs`` calls of ``plan_path`` on ``volume`` (Markdown table)."""
    plan = volume_plan(volume, depth_mm)
    cal = load_calibration(plan.calibration)
    plan_path(volume, plan, cal)
    return profile_top(partial(_batch, volume, [plan] * runs, cal, plan_path))


def lip_profile(volume: CTVolume, depth_mm: float, *, runs: int) -> str:
    """cProfile top 10 of ``runs`` calls of ``sample_lip_rings`` on ``volume`` (Markdown)."""
    plan = volume_plan(volume, depth_mm)
    depth = depth_grid_mm(plan.planned_depth_mm, DEFAULT_DEPTH_STEP_MM)
    _lip(volume, plan, depth)
    return profile_top(partial(_repeat, partial(_lip, volume, plan, depth), runs))


def _repeat(fn: Callable[[], object], runs: int) -> None:
    for _ in range(runs):
        fn()
