"""The implant's shells and bone walls compiled (issue 37): suggest's shell terms, the exact
walls, ``suggest`` and ``plan_path`` with the demo's implant, each beside its NumPy path and a
tight-loop floor reading the same samples, in one run."""

from __future__ import annotations

import contextlib
import math
import os
import threading
import time
from collections.abc import Callable
from dataclasses import replace

import numpy as np

from bench.bench_path import in_loops
from bench.report import Section, headline_row, table, time_round
from bench.shell_floor import RAY_FLOOR, SHELL_FLOOR
from bench.suggest_floor import search_floor
from ctdrill import jit
from ctdrill.app.search.candidates import SearchSpace, make_candidates
from ctdrill.app.search.shell import (
    N_ANGLES,
    SHELL_MM,
    axis_frames,
    body_profile,
    sample_shells,
)
from ctdrill.app.search.shell_kernel import SHELL_KERNEL
from ctdrill.app.search.suggest import Suggestion, suggest
from ctdrill.app.search.warmup import search_kernels
from ctdrill.engine.path import plan_path
from ctdrill.engine.plans import plan_calibration
from ctdrill.imaging.dicom.series import load_series
from ctdrill.imaging.plan.implants import implant_placement
from ctdrill.imaging.plan.load import load_plan
from ctdrill.imaging.plan.types import Plan
from ctdrill.imaging.sampling.envelope import ENVELOPE_GAP_MM
from ctdrill.imaging.sampling.envelope_kernel import ENVELOPE_KERNEL
from ctdrill.imaging.sampling.envelope_march import full_march
from ctdrill.imaging.sampling.kernel_args import volume_args
from ctdrill.imaging.sampling.walls import (
    DEPTH_STEP_MM,
    MAX_WALL_MM,
    plan_bone_walls,
    ray_step_mm,
)
from ctdrill.imaging.sampling.walls import (
    N_ANGLES as WALL_ANGLES,
)
from ctdrill.imaging.volume import CTVolume
from ctdrill.resources import asset

#: Goals of issue 37: suggest with the demo's implant, ms a candidate (1000 candidates) ...
SUGGEST_GOAL_MS = 0.5
#: ... the shell terms, and the whole search, within this many times a tight loop reading the
#: same samples ...
FLOOR_GOAL = 2.0
#: ... and plan_path with the implant (full-grid walls), ms.
PATH_GOAL_MS = 5.0

NEW_KERNELS = (ENVELOPE_KERNEL, SHELL_KERNEL)


def _off(fn: Callable[[], object]) -> Callable[[], object]:
    """``fn`` with the shell and wall kernels switched off (their NumPy paths)."""

    def run() -> object:
        with jit.switched_off(NEW_KERNELS):
            return fn()

    return run


def _load() -> str:
    one, five, _ = os.getloadavg()
    return f"{one:.1f} (5-min {five:.1f})"


def fresh_volume(volume: CTVolume) -> CTVolume:
    """The same CT as a new volume object (nothing cached with it)."""
    return CTVolume(
        volume.hu,
        volume.affine_lps,
        volume.valid,
        volume.info,
        slice_positions_mm=volume.slice_positions_mm,
    )


def _pool_cpu_s() -> float:
    """CPU time of ctdrill's worker threads (``ctdrill/jit.py``'s pool) so far, s."""
    total = 0.0
    for t in threading.enumerate():
        if t.name.startswith("ctdrill-jit") and t.ident is not None:
            with contextlib.suppress(OSError, ProcessLookupError):
                total += time.clock_gettime(time.pthread_getcpuclockid(t.ident))
    return total


def cpu_loops(
    fns: dict[str, Callable[[], object]], calls: dict[str, int], loops: int
) -> tuple[dict[str, float], dict[str, float], dict[str, float]]:
    """CPU time a call of each peer, as :func:`bench.bench_path.in_loops` times wall time: the
    process's (every thread), the calling thread's and ctdrill's worker threads', ms."""
    samples: dict[str, list[tuple[float, float, float]]] = {name: [] for name in fns}
    for _ in range(loops):
        for name, fn in fns.items():
            p0, t0, w0 = time.process_time(), time.thread_time(), _pool_cpu_s()
            for _ in range(calls[name]):
                fn()
            p1, t1, w1 = time.process_time(), time.thread_time(), _pool_cpu_s()
            samples[name].append((p1 - p0, t1 - t0, w1 - w0))
    out: tuple[dict[str, float], dict[str, float], dict[str, float]] = ({}, {}, {})
    for name, v in samples.items():
        for i, got in enumerate(out):
            got[name] = float(np.median([x[i] for x in v])) / calls[name] * 1e3
    return out


def _same_walls(volume: CTVolume, plan: Plan) -> str:
    """Whether the skipping walls equal the full march's bit for bit, in words."""
    got = plan_bone_walls(volume, plan)
    with full_march():
        want = plan_bone_walls(volume, plan)
    assert got is not None and want is not None
    same = np.array_equal(got.wall_mm, want.wall_mm, equal_nan=True)
    return "equal" if same else "NOT equal"


def run(quick: bool) -> Section:
    """The section (with headline rows)."""
    jit.warm_up((*search_kernels(), SHELL_FLOOR, RAY_FLOOR))
    load_before = _load()
    demo = asset("demo")
    volume = load_series(demo / "ct")
    plan = load_plan(demo / "plan.json")
    cal = plan_calibration(plan)
    count = 40 if quick else 1000
    repeats = 2 if quick else 5
    drawn = plan.for_drill(len(plan.drills) - 1)
    space = SearchSpace(count=count)
    cands = make_candidates(volume, drawn, space)
    dirs = cands.targets_lps - cands.entries_lps
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    body = body_profile(drawn)
    n = cands.size

    # 1. the shell terms of every candidate, and their floor
    e1, e2 = axis_frames(dirs)
    theta = 2.0 * np.pi * np.arange(N_ANGLES) / N_ANGLES
    radial = np.ascontiguousarray(
        body.radius_mm[:, None] + np.array([*SHELL_MM, 0.0, plan.min_wall_mm])[None, :]
    )
    depth = np.ascontiguousarray(body.top_depth_mm + body.s_mm)
    floor_out = np.empty(n)
    vargs = volume_args(volume)

    def shells() -> object:
        return sample_shells(volume, body, cands.entries_lps, dirs, min_wall_mm=plan.min_wall_mm)

    def shell_floor() -> None:
        SHELL_FLOOR(
            *vargs, cands.entries_lps, dirs, e1, e2, depth, radial,
            np.cos(theta), np.sin(theta), floor_out,
        )  # fmt: skip

    one_thread = {"shells": shells, "floor": shell_floor}
    t_sh = time_round({**one_thread, "numpy": _off(shells)}, repeats=repeats * 2, warmup=1)
    # the kernel's own threads off: one thread each, as the floor
    saved = jit.cpus
    jit.cpus = lambda: 1
    try:
        t_sh1 = time_round({"shells": shells}, repeats=repeats * 2, warmup=1)["shells"]
    finally:
        jit.cpus = saved
    n_samples = n * len(depth) * N_ANGLES * radial.shape[1]

    # 2. the exact walls of one implant (what each exact check and plan_path compute)
    place = implant_placement(plan)
    assert place is not None
    step = ray_step_mm(volume)
    n_d = max(2, math.ceil(place.spec.length_mm / DEPTH_STEP_MM) + 1)
    n_rays = n_d * WALL_ANGLES
    walls = plan_bone_walls(volume, plan)
    assert walls is not None
    ray_o = np.repeat(place.platform_lps[None, :], n_rays, axis=0)
    ray_v = np.ascontiguousarray(np.tile(walls.directions_lps, (n_d, 1)))
    full = np.full(n_rays, math.ceil((MAX_WALL_MM + ENVELOPE_GAP_MM) / step) + 1, dtype=np.int64)
    ray_out = np.empty(n_rays)

    def ray_floor() -> None:
        RAY_FLOOR(*vargs, ray_o, ray_v, step, full, ray_out)

    def full_walls() -> object:
        with full_march():
            return plan_bone_walls(volume, plan)

    def fresh_walls() -> object:
        # a new volume object: its blocks classed on the way (the first call on a series)
        return plan_bone_walls(fresh_volume(volume), plan)

    t_w = time_round(
        {
            "walls": lambda: plan_bone_walls(volume, plan),
            "fresh": fresh_walls,
            "full": full_walls,
            "numpy": _off(lambda: plan_bone_walls(volume, plan)),
            "floor": ray_floor,
        },
        repeats=repeats * 4,
        warmup=1,
    )
    saved = jit.cpus
    jit.cpus = lambda: 1  # one thread, as the floor
    try:
        t_w1 = time_round(
            {"walls": lambda: plan_bone_walls(volume, plan), "full": full_walls},
            repeats=repeats * 4,
            warmup=1,
        )
    finally:
        jit.cpus = saved
    same = _same_walls(volume, plan)

    # 3. suggest with the implant, and 4. plan_path with it (in a loop, as the window)
    got: dict[str, Suggestion] = {"s": suggest(volume, plan, cal, space)}
    floor = search_floor(volume, got["s"])
    runs: list[Suggestion] = []

    def ours() -> None:
        got["s"] = suggest(volume, plan, cal, space)
        runs.append(got["s"])

    t_sg = time_round(
        {
            "ours": ours,
            "floor": floor.run,
            "numpy": _off(lambda: suggest(volume, plan, cal, space)),
        },
        repeats=1 if quick else 5,
        warmup=1,
    )
    # the split of the run whose own total is the median (not an outlier under load)
    s = sorted(runs, key=lambda r: r.total_s)[len(runs) // 2] if runs else got["s"]
    drill_only = replace(plan, implant=None)

    def path_full() -> object:
        with full_march():
            return plan_path(volume, plan, cal)

    path_fns: dict[str, Callable[[], object]] = {
        "implant": lambda: plan_path(volume, plan, cal),
        "full": path_full,
        "drill": lambda: plan_path(volume, drill_only, cal),
    }
    path_calls = {"implant": 10, "full": 10, "drill": 10}
    # the NumPy peer in loops of its own, after the others: its large arrays wake OpenBLAS's
    # worker thread, which then waits spinning for a while and would bill the next peer
    numpy_fns: dict[str, Callable[[], object]] = {
        "numpy": _off(lambda: plan_path(volume, plan, cal))
    }
    numpy_calls = {"numpy": 3}
    n_loops, n_cpu = (3, 3) if quick else (11, 7)
    loops = in_loops(path_fns, path_calls, n_loops)
    loops |= in_loops(numpy_fns, numpy_calls, n_loops)
    # the CPU time a call in the same kind of loops: the process's (every thread), the calling
    # thread's, ctdrill's worker threads' (the walls' rays); the rest is other threads'
    cpu, own, pool = cpu_loops(path_fns, path_calls, n_cpu)
    for part, more in zip((cpu, own, pool), cpu_loops(numpy_fns, numpy_calls, n_cpu), strict=True):
        part |= more
    load_after = _load()

    per_c = {k: v.median_s / n * 1e3 for k, v in t_sh.items()}
    per_c1 = t_sh1.median_s / n * 1e3
    sg_ms = t_sg["ours"].median_s / n * 1e3
    sg_np = t_sg["numpy"].median_s / n * 1e3
    sg_floor = t_sg["floor"].median_s / n * 1e3
    search_ratio = sg_ms / sg_floor
    cands_shells_s = s.total_s - s.evaluate_s - s.check_s
    floor_ratio = per_c1 / per_c["floor"]
    rows_shell = [
        ["shells, compiled (2 threads)", t_sh["shells"].fmt("ms"), f"{per_c['shells']:.4f}", ""],
        ["shells, compiled (1 thread)", t_sh1.fmt("ms"), f"{per_c1:.4f}", f"{floor_ratio:.2f}"],
        [
            "floor: the same samples read and summed (1 thread)",
            t_sh["floor"].fmt("ms"),
            f"{per_c['floor']:.4f}",
            "1",
        ],
        [
            "shells, NumPy path (the reference)",
            t_sh["numpy"].fmt("ms"),
            f"{per_c['numpy']:.4f}",
            f"{per_c['numpy'] / per_c['floor']:.1f}",
        ],
    ]
    w_ms = t_w["walls"].median_s
    rows_walls = [
        ["bone walls, compiled (blocks of one class stepped over)", t_w["walls"].fmt("ms"), "1"],
        [
            "the same, first call on a series (its blocks classed on the way)",
            t_w["fresh"].fmt("ms"),
            f"{t_w['fresh'].median_s / w_ms:.2f}",
        ],
        [
            "bone walls, compiled full march (every sample read)",
            t_w["full"].fmt("ms"),
            f"{t_w['full'].median_s / w_ms:.2f}",
        ],
        [
            "bone walls, compiled, 1 thread",
            t_w1["walls"].fmt("ms"),
            f"{t_w1['walls'].median_s / w_ms:.2f}",
        ],
        [
            "bone walls, compiled full march, 1 thread",
            t_w1["full"].fmt("ms"),
            f"{t_w1['full'].median_s / w_ms:.2f}",
        ],
        [
            "bone walls, NumPy path (the reference)",
            t_w["numpy"].fmt("ms"),
            f"{t_w['numpy'].median_s / t_w['walls'].median_s:.1f}",
        ],
        [
            "floor: every ray's full march read and summed (1 thread)",
            t_w["floor"].fmt("ms"),
            f"{t_w['floor'].median_s / t_w['walls'].median_s:.2f}",
        ],
    ]
    rows_sg = [
        [
            "suggest, compiled kernels",
            t_sg["ours"].fmt("s"),
            f"{sg_ms:.2f}",
            f"{s.evaluate_s:.2f} / {s.check_s:.2f}",
            f"{s.n_checked}",
        ],
        [
            "floor: the samples the search reads, read and summed (1 thread)",
            t_sg["floor"].fmt("s"),
            f"{sg_floor:.3f}",
            "",
            "",
        ],
        ["suggest, the NumPy shells and walls", t_sg["numpy"].fmt("s"), f"{sg_np:.2f}", "", ""],
    ]
    path_cols = ["work", "ms a call", "CPU ms a call", "calling thread", "ctdrill's workers"]
    path_cols += ["other threads", "/ compiled"]
    other = {k: max(cpu[k] - own[k] - pool[k], 0.0) for k in cpu}
    path_rows = (
        ("implant", "plan_path with the implant, compiled walls"),
        ("full", "plan_path with the implant, walls by the compiled full march"),
        ("numpy", "plan_path with the implant, NumPy walls"),
        ("drill", "plan_path without the implant (the drill only)"),
    )
    rows_path = [
        [
            label,
            f"{loops[key]:.2f}",
            f"{cpu[key]:.2f}",
            f"{own[key]:.2f}",
            f"{pool[key]:.2f}",
            f"{other[key]:.2f}",
            f"{loops[key] / loops['implant']:.2f}",
        ]
        for key, label in path_rows
    ]
    thread_note = (
        "under this load the second thread waits for a core"
        if t_w1["walls"].median_s < w_ms
        else "the second thread helps"
    )
    md = f"""Case: the bundled demo (``assets/demo``, 0.4 mm voxels) and its plan with its implant
(tapered 4.1 x 11.5 mm, apex 12 mm deep); {n} candidates of ``suggest``'s default space.
Load average {load_before} before and {load_after} after this module, on the 2 shared cores:
absolute times are inflated several-fold by the other processes; the ratios between peers
measured side by side (round-robin) are what count.

**Shell terms** (``sample_shells``: {len(depth)} depths x {N_ANGLES} directions x
{radial.shape[1]} offsets = {n_samples // max(n, 1)} trilinear samples a candidate, the score's
two shells, the surface and the thinnest wall to keep): the compiled kernel (threads across
the candidates; with one thread for the ratio to the floor), the tight-loop floor (a compiled
loop reading every one of the same samples and summing them: no rule, no flags) and the NumPy
path. Medians of {repeats * 2} round-robin repeats [IQR], ms a candidate in the third column.

{table(["work", "all candidates", "ms a candidate", "/ floor"], rows_shell)}

**Exact bone walls of one implant** (``plan_bone_walls``: {n_d} depths x {WALL_ANGLES}
directions = {n_rays} rays, step {step:.2f} mm; what each exact check of ``suggest``, each
``plan_path`` and the window compute): compiled (each ray marched only until the envelope
rule decides it, the exit crossing bisected to 1e-4 mm) against the NumPy path and a floor
that reads every ray's full march ({int(full[0])} samples, the NumPy path's samples) without
the rule. Medians of {repeats * 4} round-robin repeats.

{table(["work", "each call", "/ compiled"], rows_walls)}

**suggest** with the implant, {n} candidates: the whole command's search (the candidates'
bone surfaces, the batch of the final drill's stops, the shells, the exact check of the
best-ranked until 20 are feasible or 50 were checked: every drill's and the implant's
clearances, the full-grid walls), against a floor and the same search with the compiled
kernels of the shells and walls switched off (their NumPy paths). The **floor**
(``bench/suggest_floor.py``) is one compiled loop reading every CT sample the search reads and
summing it, no rule: the {floor.line_samples:,} samples of the candidates' entry-search lines,
the {floor.shell_samples:,} shell samples and, for the {s.n_checked} candidates checked, every
wall ray marched as far as the envelope rule needs to decide it (its wall plus the 3 mm gap of
non-bone, an unknown ray the whole march) and its exit's bisection: {floor.wall_samples:,}
samples (the rays' full marches would be {floor.wall_full_samples:,}); in all
{floor.samples / max(n, 1):,.0f} samples a candidate. The compiled walls step over uniform
blocks of the CT without reading each sample (``imaging/sampling/hu_blocks.py``), so they can
beat this floor. The
clearances to the canal are distances to its segments, not samples: not in the floor. Medians
of {1 if quick else 5} round-robin repeats [IQR].

{table(["work", "total", "ms a candidate", "batch / exact check (s)", "checked"], rows_sg)}

suggest / floor: **{search_ratio:.2f}** (goal <= {FLOOR_GOAL:g}). Of suggest's
{s.total_s:.2f} s in its median run: the batch of the final drill's stops (the clearance kernel,
the safe-depth search) {s.evaluate_s:.2f} s, the candidates' surfaces and the shells
{cands_shells_s:.2f} s, the exact check of {s.n_checked} candidates {s.check_s:.2f} s
({s.check_s / max(s.n_checked, 1) * 1e3:.1f} ms each, nearly all of it the walls).

**plan_path** with the implant, full-grid walls, time per call in loops of consecutive calls
(as the window calls it while a plan is edited), median of the loops, ms; beside it the
process's CPU time a call (all its threads) in the same kind of loops, which the other
processes on the 2 shared cores inflate less than the wall time, split by thread (medians of
each, so the parts need not add up exactly): the calling thread, ctdrill's worker threads
(``ctdrill/jit.py``'s pool: the walls' rays) and the other threads (OpenBLAS's worker, which
waits spinning for a while after a large matrix product: while ``CTVolume.sample`` built its
index coordinates by one, the NumPy walls woke it and its spinning billed the next peer, the
drill alone, with twice its wall time in CPU on the idle machine; the NumPy walls are timed
in loops of their own after the others).

{table(path_cols, rows_path)}

Where the time goes in ``plan_path`` with the implant: of its {cpu["implant"]:.2f} ms of CPU a
call, the drill's path takes {cpu["drill"]:.2f} ms, the walls' full march would add
{cpu["full"] - cpu["implant"]:.2f} ms more; the walls alone take {w_ms * 1e3:.1f} ms a call on
two threads, {t_w1["walls"].median_s * 1e3:.1f} ms on one ({thread_note}). The second thread is
the walls' own: ``plan_path`` starts the implant's rays on the worker thread
(``start_plan_bone_walls``), computes the drill's path on the calling thread meanwhile, then
both threads claim the rays still free, one walking them up and the other down until they meet
(``ctdrill/claims.py``), so the CPU time above the wall time is the rays' second thread
({pool["implant"]:.2f} ms a call; the other threads {other["implant"]:.2f} ms, the drill
alone's {other["drill"]:.2f} ms). Each exit crossing's
bisection reads its midpoints off the cell's cubic along the ray once its bracket lies inside
one cell (``imaging/sampling/cell_cubic.py``, under the same guard as the extrapolated
samples), and a ray that meets bone past the cap stops there.
The walls' rays step over the CT's blocks of 4 x 4 x 4 cells whose corners all lie inside one
class (soft, or bone-range), classed once per series as rays reach them
(``imaging/sampling/hu_blocks.py``), and read the rest at extrapolated index coordinates:
{t_w1["walls"].median_s / t_w["floor"].median_s:.2f} x (one thread) the floor that reads every
ray's full march, {t_w1["full"].median_s / t_w1["walls"].median_s:.1f} x faster than the same
kernel reading every sample. Same answers: the walls, unknown and open flags of every ray equal
the full march's bit for bit here ({same}), and on random small CTs with thin walls, values
exactly at the thresholds and rays grazing voxel faces
(``tests/imaging/test_walls_blocks.py``).
"""
    shortfalls = []
    if sg_ms > SUGGEST_GOAL_MS:
        shortfalls.append(
            f"suggest with the demo's implant took {sg_ms:.2f} ms a candidate ({n} candidates; "
            f"goal <= {SUGGEST_GOAL_MS} ms) at load {load_after}; batch {s.evaluate_s:.2f} s, "
            f"exact check {s.check_s:.2f} s of it ({s.n_checked} checked: nearly all the "
            "walls' kernel)"
        )
    if search_ratio > FLOOR_GOAL:
        shortfalls.append(
            f"suggest with the demo's implant took {search_ratio:.2f} x the tight loop reading "
            f"the same samples (goal <= {FLOOR_GOAL:g} x)"
        )
    if floor_ratio > FLOOR_GOAL:
        shortfalls.append(
            f"the compiled shells took {floor_ratio:.2f} x their tight-loop floor "
            f"(goal <= {FLOOR_GOAL:g} x)"
        )
    if loops["implant"] > PATH_GOAL_MS:
        shortfalls.append(
            f"plan_path with the implant took {loops['implant']:.2f} ms a call "
            f"(goal <= {PATH_GOAL_MS:g} ms; {cpu['implant']:.2f} ms of CPU) at load "
            f"{load_after}; the drill alone {loops['drill']:.2f} ms ({cpu['drill']:.2f} ms of "
            f"CPU), the walls {w_ms * 1e3:.2f} ms"
        )
    headline = (
        headline_row(
            f"#37 suggest with the demo's implant, {n} candidates (ms a candidate)",
            f"{sg_ms:.2f} ms",
            f"NumPy shells and walls {sg_np:.2f} ms",
            f"{sg_np / sg_ms:.1f}",
            f"<= {SUGGEST_GOAL_MS} ms",
        ),
        headline_row(
            "#37 suggest's whole search / a tight loop reading the same samples",
            f"{sg_ms:.3f} ms a candidate",
            f"floor {sg_floor:.3f} ms",
            f"{search_ratio:.2f} (ours / floor)",
            f"<= {FLOOR_GOAL:g} x",
        ),
        headline_row(
            "#37 suggest's shell terms / a tight loop reading the same samples",
            f"{per_c1:.4f} ms a candidate",
            f"floor {per_c['floor']:.4f} ms",
            f"{floor_ratio:.2f} (ours / floor)",
            f"<= {FLOOR_GOAL:g} x",
        ),
        headline_row(
            "#37 plan_path with the implant (full-grid walls, in a loop)",
            f"{loops['implant']:.2f} ms ({cpu['implant']:.2f} ms CPU)",
            f"walls by the full march {loops['full']:.2f} ms; drill only {loops['drill']:.2f} ms",
            f"{loops['full'] / loops['implant']:.2f}",
            f"<= {PATH_GOAL_MS:g} ms",
        ),
        headline_row(
            f"#37 the implant's bone walls ({n_rays} rays, 1 thread) / every ray's full march read",
            f"{t_w1['walls'].median_s * 1e3:.2f} ms",
            f"floor {t_w['floor'].median_s * 1e3:.2f} ms",
            f"{t_w1['walls'].median_s / t_w['floor'].median_s:.2f} (ours / floor)",
            "below the floor: the march shrinks",
        ),
    )
    return Section(
        "Search: the implant's shells and bone walls compiled",
        md,
        shortfalls=tuple(shortfalls),
        headline=headline,
    )
