"""Force model: profile build time and per-tick force cost against the error each buys.

Test field (drill frame, ``bone-illustrative`` calibration, drill 2 mm, tip 0.6 mm): planar
layers tilted 25 degrees to the drill axis - air, 2 mm soft tissue (40 HU, below the gate),
a 2 mm cortical plate (1500 HU), trabecular bone (450 HU), a 1.5 mm canal-like gap (0 HU), and
trabecular bone again. A lip point at depth ``xi``, radius ``r`` and angle ``theta`` lies at
``s = xi cos(a) + r sin(a) cos(theta)`` across the layers.

Reference: the lip integral of DESIGN.md 1.4 with the angle mean in closed form (the fraction
of a ring beyond a plane is ``arccos(c) / pi``) and 2048 midpoint rings (converged: 1024 rings
differ by < 1e-4 N). Each (rings, angles) configuration point-samples the same continuous field
and builds its profile with :func:`ctdrill.model.build_profile`; its error is the RMS (and max) of
``S0`` against the reference over 401 depths (0..20 mm, 0.05 mm). The depth step is measured
separately on the exact layered profile (:func:`ctdrill.model.layered.layered_profile`),
interpolated linearly as :func:`ctdrill.model.force_n` does, against the exact profile every 0.001
mm.
"""

from __future__ import annotations

import math
from functools import partial

import numpy as np

from bench.report import Section, figure_path, table, time_it
from ctdrill.imaging.sampling.lip import DEFAULT_N_ANGLES, DEFAULT_N_RINGS
from ctdrill.model import build_profile, force_n, force_series_n, load_calibration
from ctdrill.model.calibration import harmonic_freqs_hz
from ctdrill.model.force import a0_n, force_density_n, gate
from ctdrill.model.layered import layered_profile

FIGURE_NAME = "model_pareto.png"

CAL = load_calibration("bone-illustrative")
RADIUS_MM = 1.0
TIP_MM = 0.6
TILT = math.radians(25.0)
#: Layer boundaries across the tilted planes (s, mm) and the HU between them.
#: Off the depth grids on purpose (S0 of layers is piecewise linear with kinks at b and b + l_t).
BOUNDS = np.array([2.013, 4.037, 6.021, 12.0071, 13.533])
HU_LAYERS = np.array([40.0, 1500.0, 450.0, 0.0])
HU_BEFORE, HU_AFTER = -1000.0, 450.0


def field_hu(s: np.ndarray) -> np.ndarray:
    """HU at plane coordinate ``s`` (mm), any shape."""
    hu_all = np.concatenate(([HU_BEFORE], HU_LAYERS, [HU_AFTER]))
    return np.asarray(hu_all[np.searchsorted(BOUNDS, s, side="right")])


def lip_hu(depth_mm: np.ndarray, n_rings: int, n_angles: int) -> tuple[np.ndarray, np.ndarray]:
    """Point samples of the field on the lip rings: (D, R, A) HU and (R,) weights."""
    frac = (np.arange(n_rings) + 0.5) / n_rings
    xi = depth_mm[:, None] - TIP_MM * frac[None, :]
    r = RADIUS_MM * frac
    theta = 2.0 * np.pi * np.arange(n_angles) / n_angles
    s = xi[:, :, None] * math.cos(TILT) + (r[:, None] * math.sin(TILT) * np.cos(theta))[None]
    return field_hu(s), np.full(n_rings, 1.0 / n_rings)


def reference_s0(depth_mm: np.ndarray, *, n_rings: int = 2048) -> np.ndarray:
    """``S0`` with the exact angle mean on each ring and ``n_rings`` midpoint rings, N."""
    hu_all = np.concatenate(([HU_BEFORE], HU_LAYERS, [HU_AFTER]))
    f_all = gate(hu_all, CAL) * a0_n(hu_all, 0.0, CAL)  # (L + 2,)
    frac = (np.arange(n_rings) + 0.5) / n_rings
    xi = depth_mm[:, None] - TIP_MM * frac[None, :]  # (D, R)
    amp = (RADIUS_MM * frac * math.sin(TILT))[None, :, None]  # (1, R, 1)
    c = (BOUNDS[None, None, :] - xi[:, :, None] * math.cos(TILT)) / amp
    beyond = np.arccos(np.clip(c, -1.0, 1.0)) / np.pi  # (D, R, L + 1): fraction with s >= b
    ones = np.ones((*beyond.shape[:2], 1))
    zeros = np.zeros_like(ones)
    cum = np.concatenate([ones, beyond, zeros], axis=2)  # fraction beyond each edge
    share = cum[:, :, :-1] - cum[:, :, 1:]  # (D, R, L + 2) per layer
    return np.asarray((share @ f_all).mean(axis=1))


def _pareto(points: list[tuple[float, float]]) -> list[bool]:
    """True where no other point is both faster and more accurate."""
    out = []
    for i, (t, e) in enumerate(points):
        dominated = any(
            (t2 <= t and e2 <= e) and (t2 < t or e2 < e)
            for j, (t2, e2) in enumerate(points)
            if j != i
        )
        out.append(not dominated)
    return out


def _rings_angles(quick: bool) -> tuple[str, list[tuple[int, int, float, float, float]]]:
    """Rows (rings, angles, median build s, S0 RMS error N, S0 max error N) and the table."""
    depth = np.linspace(0.0, 20.0, 81 if quick else 401)
    ref = reference_s0(depth, n_rings=256 if quick else 2048)
    ref_half = reference_s0(depth, n_rings=128 if quick else 1024)
    rings = [1, 2, 4, 8, 16] if quick else [1, 2, 4, 6, 8, 12, 16, 32]
    angles = [1, 4, 12] if quick else [1, 4, 8, 12, 16, 32]
    rows: list[tuple[int, int, float, float, float]] = []
    iqr: list[str] = []
    for n_r in rings:
        for n_a in angles:
            hu, w = lip_hu(depth, n_r, n_a)
            timing = time_it(
                partial(build_profile, hu, w, depth, CAL, blades=2, rpm=900),
                repeats=3 if quick else 15,
            )
            iqr.append(f"{timing.p25_s * 1e3:.3g}-{timing.p75_s * 1e3:.3g}")
            p = build_profile(hu, w, depth, CAL, blades=2, rpm=900)
            err = p.s0_n - ref
            rows.append(
                (
                    n_r,
                    n_a,
                    timing.median_s,
                    float(np.sqrt(np.mean(err**2))),
                    float(np.max(np.abs(err))),
                )
            )
    front = _pareto([(r[2], r[3]) for r in rows])
    front_samples = _pareto([(float(r[0] * r[1]), r[3]) for r in rows])
    body = table(
        [
            "rings",
            "angles",
            "samples/depth",
            "build (ms)",
            "IQR (ms)",
            "S0 RMS error (N)",
            "S0 max error (N)",
            "front (samples)",
            "front (time)",
        ],
        [
            (
                r[0],
                r[1],
                r[0] * r[1],
                f"{r[2] * 1e3:.3g}",
                q,
                f"{r[3]:.3g}",
                f"{r[4]:.3g}",
                "yes" if fs else "",
                "yes" if f else "",
            )
            for r, q, f, fs in zip(rows, iqr, front, front_samples, strict=True)
        ],
    )
    conv = float(np.max(np.abs(ref - ref_half)))
    head = (
        f"Profile build for {depth.shape[0]} depths (rings x angles, point samples of the tilted "
        f"layered field). Reference converged to {conv:.2g} N (max difference at half the rings); "
        f"peak S0 {ref.max():.3g} N.\n\n"
    )
    _figure(rows, front, front_samples)
    return head + body, rows


def _figure(
    rows: list[tuple[int, int, float, float, float]],
    front: list[bool],
    front_samples: list[bool],
) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10.0, 4.2), sharey=True)
    panels = (
        (axes[0], [float(r[0] * r[1]) for r in rows], front_samples, "lip samples per depth"),
        (axes[1], [r[2] * 1e3 for r in rows], front, "profile build time, 401 depths (ms)"),
    )
    for ax, xs, on_front, label in panels:
        for (n_r, n_a, _, e, _), x, on in zip(rows, xs, on_front, strict=True):
            ax.loglog(x, max(e, 1e-6), "o", color="C1" if on else "C0", ms=5)
            ax.annotate(f"{n_r}x{n_a}", (x, max(e, 1e-6)), fontsize=6)
        ax.set_xlabel(label)
    axes[0].set_ylabel("S0 RMS error vs reference (N)")
    fig.suptitle("Lip quadrature, rings x angles (orange: Pareto front)")
    fig.tight_layout()
    fig.savefig(figure_path(FIGURE_NAME), dpi=110)
    plt.close(fig)


def _depth_step(quick: bool) -> str:
    bounds = [*BOUNDS.tolist(), 40.0]
    hus = [40.0, 1500.0, 450.0, 0.0, 450.0]
    fine = np.arange(0.0, 20.0 + 1e-9, 0.001)
    exact = layered_profile(bounds, hus, fine, CAL, tip_length_mm=TIP_MM, blades=2, rpm=900)
    rows = []
    steps = [0.05, 0.2] if quick else [0.01, 0.02, 0.05, 0.1, 0.2]
    for step in steps:
        depth = np.arange(0.0, 20.0 + 1e-9, step)
        timing = time_it(
            partial(
                layered_profile, bounds, hus, depth, CAL, tip_length_mm=TIP_MM, blades=2, rpm=900
            ),
            repeats=3 if quick else 7,
        )
        p = layered_profile(bounds, hus, depth, CAL, tip_length_mm=TIP_MM, blades=2, rpm=900)
        err = force_series_n(p, fine, 0.0, np.full(fine.shape, np.nan)) - exact.s0_n
        rows.append(
            (
                f"{step:g}",
                depth.shape[0],
                f"{timing.median_s * 1e3:.3g}",
                f"{np.sqrt(np.mean(err**2)):.3g}",
                f"{np.max(np.abs(err)):.3g}",
            )
        )
    return (
        "Depth step of the profile table (exact layered profile, 0-20 mm, linear interpolation "
        "as `force_n`), error of S0 against the exact value every 0.001 mm:\n\n"
        + table(["step (mm)", "entries", "build (ms)", "RMS error (N)", "max error (N)"], rows)
    )


def _per_tick(quick: bool) -> str:
    depth = np.linspace(0.0, 20.0, 401)
    hu, w = lip_hu(depth, 6, 12)
    p = build_profile(hu, w, depth, CAL, blades=2, rpm=900)
    freqs = harmonic_freqs_hz(CAL, blades=2, rpm=900)
    n = 2_000 if quick else 20_000
    rng = np.random.default_rng(0)
    xs = rng.uniform(0.0, 20.0, n).tolist()
    ts = rng.uniform(0.0, 10.0, n).tolist()

    def scalar() -> None:
        for x, t in zip(xs, ts, strict=True):
            force_n(p, x, 0.4, t)

    x_arr = np.asarray(xs)
    t_arr = np.asarray(ts)

    def series() -> None:
        force_series_n(p, x_arr, 0.4, t_arr)

    rows_idx = np.clip((x_arr / 0.05).astype(int), 0, 400)[: n // 20]

    def direct() -> None:
        # Peer: evaluate the law over the lip's R x A samples every tick (no profile).
        for i, t in zip(rows_idx, ts, strict=False):
            s = force_density_n(hu[i], 0.4, t, CAL, freqs_hz=freqs)
            float(np.sum(w[:, None] * s) / s.shape[1])

    reps = 3 if quick else 7
    timings = [
        ("`force_n` (profile, scalar, O(1))", time_it(scalar, repeats=reps), n),
        ("`force_series_n` (profile, vectorised)", time_it(series, repeats=reps), n),
        (
            "lip law per tick (6 x 12 samples, no profile)",
            time_it(direct, repeats=reps),
            rows_idx.shape[0],
        ),
    ]
    base = timings[0][1].median_s / n
    rows = [
        (
            name,
            f"{tm.median_s / count * 1e6:.3g} [{tm.p25_s / count * 1e6:.3g}-"
            f"{tm.p75_s / count * 1e6:.3g}]",
            f"{tm.median_s / count / base:.3g}",
        )
        for name, tm, count in timings
    ]
    return (
        f"Force evaluation per tick ({n} random depths and times; budget at 10 kHz: 100 us):\n\n"
        + table(["method", "us per tick [IQR]", "ratio to force_n"], rows)
    )


def _default_shortfall(rows: list[tuple[int, int, float, float, float]]) -> tuple[str, ...]:
    """A shortfall line when imaging's default rings x angles is off the samples front."""
    by_config = {(r[0], r[1]): r for r in rows}
    default = by_config.get((DEFAULT_N_RINGS, DEFAULT_N_ANGLES))
    if default is None:
        return ()
    n_default = default[0] * default[1]
    better = [r for r in rows if r[0] * r[1] <= n_default and r[3] < default[3] and r != default]
    if not better:
        return ()
    best = min(better, key=lambda r: r[3])
    return (
        f"imaging's default lip sampling {DEFAULT_N_RINGS} x {DEFAULT_N_ANGLES} "
        f"({n_default} samples/depth) gives S0 RMS error {default[3]:.3g} N on the tilted "
        f"layered field; {best[0]} x {best[1]} ({best[0] * best[1]} samples) gives "
        f"{best[3]:.3g} N.",
    )


def run(quick: bool) -> Section:
    """Run the model benchmarks (``quick``: tiny sizes, few repeats)."""
    ra_text, rows = _rings_angles(quick)
    text = "\n\n".join([__doc__ or "", ra_text, _depth_step(quick), _per_tick(quick)])
    return Section(
        title="Force model",
        markdown=text,
        figures=(str(figure_path(FIGURE_NAME)),),
        shortfalls=() if quick else _default_shortfall(rows),
    )
