"""Trajectory search (issue 17): ``evaluate_batch`` on 1000 candidates against a batched NumPy
``map_coordinates`` peer and against 1000 calls of ``plan_path``, in one run."""

from __future__ import annotations

import subprocess
import sys
import time
from dataclasses import replace

import numpy as np

from bench import search_peer
from bench.report import ROOT, Section, Timing, headline_row, table, time_it, time_round
from ctdrill import jit
from ctdrill.app.search.warmup import search_kernels
from ctdrill.engine.batch import BatchResult, evaluate_batch
from ctdrill.engine.path import plan_path
from ctdrill.engine.plans import plan_calibration
from ctdrill.imaging.dicom.series import load_series
from ctdrill.imaging.plan.load import load_plan
from ctdrill.imaging.plan.types import Plan
from ctdrill.resources import asset

#: Goal of issue 17: 1000 candidates of the demo plan in at most this, seconds.
GOAL_S = 0.5
#: ... and at least this many times faster than the batched NumPy peer.
GOAL_RATIO = 10.0


def candidates(plan: Plan, n: int, seed: int = 17) -> tuple[np.ndarray, np.ndarray]:
    """Entries within +-3 mm (in the crest plane) of the planned one, axes tilted 0-15 degrees,
    the planned depth: what ``ctdrill suggest`` explores."""
    rng = np.random.default_rng(seed)
    entries = plan.entry_lps + rng.uniform(-3.0, 3.0, (n, 3)) * np.array([1.0, 1.0, 0.0])
    tilt = np.deg2rad(rng.uniform(0.0, 15.0, n))
    az = rng.uniform(0.0, 2.0 * np.pi, n)
    u = plan.direction
    e1 = np.cross(u, [1.0, 0.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(u, e1)
    dirs = np.cos(tilt)[:, None] * u + np.sin(tilt)[:, None] * (
        np.cos(az)[:, None] * e1 + np.sin(az)[:, None] * e2
    )
    return entries, entries + plan.planned_depth_mm * dirs


def _load_seconds() -> float:
    """A fresh process's import of evaluate_batch plus loading its kernels from the cache."""
    code = (
        "import time; t=time.perf_counter(); from ctdrill.app.search.warmup import "
        "search_kernels; ok=all(k.ready() for k in search_kernels()); "
        "print(time.perf_counter()-t if ok else -1)"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True
    )
    return float(out.stdout.strip())


def _agreement(got: BatchResult, plan: Plan, volume: object, cal: object, rows: int) -> float:
    """Largest |difference| between evaluate_batch and plan_path over ``rows`` rows: every
    profile array, clearance per depth, max safe depth, stop depth."""
    worst = 0.0
    for i in range(rows):
        row = replace(plan, entry_lps=got.entries_lps[i], target_lps=got.targets_lps[i])
        want = plan_path(volume, row, cal)  # type: ignore[arg-type]
        m = want.depth_mm.size
        pairs = [
            (got.s0_n[i, :m], want.profile.s0_n),
            (got.sk_n[i, :, :m], want.profile.sk_n),
            (got.s_t[i, :m], want.profile.s_t),
            (got.hu_mean[i, :m], want.profile.hu_mean),
            (got.clearance_mm[i, :m], want.clearance_mm),
            (got.max_safe_depth_mm[i], want.max_safe_depth_mm),
            (got.stop_depth_mm[i], want.stop_depth_mm),
        ]
        for a, b in pairs:
            worst = max(worst, float(np.max(np.abs(np.asarray(a) - np.asarray(b)))))
    return worst


def run(quick: bool) -> Section:
    """The search benchmark's section (with headline rows)."""
    demo = asset("demo")
    volume = load_series(demo / "ct")
    plan = load_plan(demo / "plan.json")
    cal = plan_calibration(plan)
    n = 8 if quick else 1000
    n_path = 1 if quick else 100
    repeats = 1 if quick else 3
    entries, targets = candidates(plan, n)
    t0 = time.perf_counter()
    was_ready = all(k.ready() for k in search_kernels())
    jit.warm_up(search_kernels())
    warm_s = time.perf_counter() - t0
    load_s = float("nan") if quick else _load_seconds()
    result = evaluate_batch(volume, plan, entries, targets, cal)
    peer = search_peer.evaluate(volume, plan, entries, targets, cal, result.depth_mm)
    peer_diff = max(
        float(np.max(np.abs(peer["s0"] - result.s0_n))),
        float(np.max(np.abs(peer["clearance"] - result.clearance_mm[:, :, 0]))),
        float(np.max(np.abs(peer["max_safe"] - result.max_safe_depth_mm))),
    )
    times = time_round(
        {
            "batch": lambda: evaluate_batch(volume, plan, entries, targets, cal),
            "peer": lambda: search_peer.evaluate(
                volume, plan, entries, targets, cal, result.depth_mm
            ),
        },
        repeats=repeats,
        warmup=0,
    )
    sub = [
        replace(plan, entry_lps=e, target_lps=t)
        for e, t in zip(entries[:n_path], targets[:n_path], strict=True)
    ]
    t_path = time_it(
        lambda: [plan_path(volume, p, cal) for p in sub], repeats=1 if quick else 3, warmup=0
    )
    scale = n / n_path
    path_s = Timing(
        t_path.median_s * scale,
        t_path.p25_s * scale,
        t_path.p75_s * scale,
        t_path.min_s * scale,
        t_path.repeats,
    )
    n_agree = 1 if quick else 20
    agree = _agreement(result, plan, volume, cal, n_agree)
    batch, peer_t = times["batch"], times["peer"]
    ratio_peer = peer_t.median_s / batch.median_s
    ratio_path = path_s.median_s / batch.median_s
    rows = [
        [
            f"evaluate_batch, {n} candidates",
            batch.fmt("s"),
            f"{batch.median_s / n * 1e3:.3g} ms",
            "1",
        ],
        [
            "batched NumPy peer (map_coordinates, same clearance)",
            peer_t.fmt("s"),
            f"{peer_t.median_s / n * 1e3:.3g} ms",
            f"{ratio_peer:.1f}",
        ],
        [
            f"{n} x plan_path (timed on {n_path}, x {scale:g})",
            path_s.fmt("s"),
            f"{path_s.median_s / n * 1e3:.3g} ms",
            f"{ratio_path:.1f}",
        ],
    ]
    cached = "already cached" if was_ready else "compiled by this run"
    md = f"""Case: the bundled demo phantom (``assets/demo``, 80 x 100 x 80 voxels of 0.4 mm) and
its plan (12 mm, an 83-segment canal, margin 2 mm); {n} candidate axes (entries within 3 mm of the
planned one in the crest plane, tilted 0-15 degrees, the planned depth), default lip (6 x 12)
and depth step (0.05 mm): 241 depths, 17,352 trilinear samples per trajectory.
``evaluate_batch`` runs its compiled kernels (numba, loaded from the disk cache, on
{jit.cpus()} threads); the peer is ``bench/search_peer.py``: every trajectory's lip points
through ``map_coordinates(order=1)``, the force law on all samples, and the same closed-form
clearance (signed distance and its derivative, secant steps) vectorised over (trajectory,
depth, segment) pairs in chunks of {search_peer.CHUNK} trajectories, the max safe depth by the
same bracket and 65-point passes. Medians of {repeats} round-robin repeats [IQR].

{table(["work", "time", "per trajectory", "/ evaluate_batch"], rows)}

Same answers: over the first {n_agree} candidates evaluate_batch and plan_path differ by at
most {agree:.2g} (profile arrays in N or HU, clearance and depths in mm); the peer differs from
evaluate_batch by at most {peer_diff:.2g}. Kernels: {cached}
(warm-up {warm_s:.1f} s); a fresh process imports ``evaluate_batch`` and loads the kernels from
the cache in {load_s:.2f} s.
"""
    shortfalls = []
    if batch.median_s > GOAL_S:
        shortfalls.append(
            f"{n} candidates took {batch.median_s:.2f} s (goal <= {GOAL_S} s) on this "
            "shared machine"
        )
    if ratio_peer < GOAL_RATIO:
        shortfalls.append(
            f"evaluate_batch is {ratio_peer:.1f} x the NumPy peer (goal >= {GOAL_RATIO:g} x)"
        )
    headline = (
        headline_row(
            f"#17 evaluate {n} candidate trajectories (demo plan)",
            batch.fmt("s"),
            f"NumPy batch {peer_t.fmt('s')}",
            f"{ratio_peer:.1f}",
            f"<= {GOAL_S} s, >= {GOAL_RATIO:g} x",
        ),
        headline_row(
            f"#17 the same, against {n} x plan_path",
            batch.fmt("s"),
            f"{path_s.median_s:.3g} s",
            f"{ratio_path:.1f}",
            "same answers (1e-9)",
        ),
    )
    return Section(
        "Trajectory search: many candidates at once",
        md,
        shortfalls=tuple(shortfalls),
        headline=headline,
    )
