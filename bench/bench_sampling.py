"""Lip sampling: accuracy versus cost of interpolation order, depth step and rings x angles.

An analytic test object (LPS mm) is voxelised at 0.3 mm with partial-volume averaging
(4 x 4 x 4 sub-samples per voxel, as a CT detector integrates): a soft-tissue layer, a 2 mm
cortical plate tilted 10 degrees to the drill, smooth trabecular bone
(600 HU +- 250 HU of sinusoids), and a 1.2 mm-radius canal the drill breaks into. The drill
(2 mm, 0.6 mm tip) runs 16 mm along an axis tilted off the grid axes.

Truth: the lip integrals of DESIGN.md 1.4 on the *continuous* object (160 rings x 256 angles,
depth step 0.01 mm): the lip-mean HU and the cut fraction ``s_t`` (gate of the
``bone-illustrative`` calibration). Each configuration samples the voxelised volume at its depth
step; its profile, linearly interpolated in depth as the force renderer does, is compared with
the truth at every 0.01 mm. Errors are RMS over the trajectory; times are per trajectory
(median of repeats), for :func:`ctdrill.imaging.sampling.lip.sample_lip_rings` (orders 0 and 1) and
for ``scipy.ndimage.map_coordinates`` on pre-filtered spline coefficients (order 3; the one-off
pre-filter is reported apart).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from functools import partial
from pathlib import Path

import numpy as np
from scipy import ndimage

from bench.report import Section, figure_path, table, time_it
from ctdrill.imaging.plan.types import DrillSpec
from ctdrill.imaging.sampling.lip import (
    DEFAULT_N_ANGLES,
    DEFAULT_N_RINGS,
    lip_ring_points,
    sample_lip_rings,
)
from ctdrill.imaging.volume import CTVolume, SeriesInfo
from ctdrill.model import a0_n, gate, load_calibration

ROOT = Path(__file__).resolve().parents[1]
#: The force law the errors in N are stated in (DESIGN.md: the set for patient CT).
_CAL = load_calibration("bone-illustrative")
FIGURE_NAME = "sampling_pareto.png"

SPACING_MM = 0.3
DIAMETER_MM = 2.0
TIP_MM = 0.6
LENGTH_MM = 16.0
_TILT = np.deg2rad(10.0)
_PLATE_NORMAL = np.array([np.sin(_TILT), 0.0, np.cos(_TILT)])
_AXIS = np.array([0.08, -0.05, -1.0]) / np.linalg.norm([0.08, -0.05, -1.0])
ENTRY = np.array([0.11, -0.07, 2.0])
TARGET = ENTRY + LENGTH_MM * _AXIS
# Canal along (0, 1, 0.1), its centre 0.4 mm beside the axis at 14 mm depth.
_CANAL_DIR = np.array([0.0, 1.0, 0.1]) / np.linalg.norm([0.0, 1.0, 0.1])
_CANAL_P = ENTRY + 14.0 * _AXIS + np.array([0.4, 0.0, 0.0])
CANAL_R = 1.2
ORDER_NAMES = {0: "nearest", 1: "trilinear", 3: "cubic"}
# fmt: off
TABLE_HEADER = ["order", "step mm", "rings x angles", "samples", "time ms", "disc RMS s_t",
                "disc RMS HU", "disc RMS S0 N (%)", "object RMS s_t", "object max s_t err",
                "object RMS HU", "object RMS S0 N (%)"]
# fmt: on


def field_hu(p: np.ndarray) -> np.ndarray:
    """Continuous HU of the test object at LPS points (..., 3)."""
    s = p @ _PLATE_NORMAL  # > 0 above the plate's outer surface
    smooth = (
        600.0
        + 150.0 * np.sin(2 * np.pi * p[..., 0] / 7.0) * np.cos(2 * np.pi * p[..., 1] / 9.0)
        + 100.0 * np.sin(2 * np.pi * p[..., 2] / 5.0)
    )
    hu = np.where(s > 3.0, -1000.0, np.where(s > 0.0, 40.0, np.where(s > -2.0, 1700.0, smooth)))
    rel = p - _CANAL_P
    d_canal = np.linalg.norm(rel - (rel @ _CANAL_DIR)[..., None] * _CANAL_DIR, axis=-1)
    return np.asarray(np.where((d_canal < CANAL_R) & (s <= -2.0), 30.0, hu))


def make_volume(*, sub: int) -> CTVolume:
    """The object voxelised on a 0.3 mm grid around the path, ``sub``^3 sub-samples per voxel."""
    lo = np.minimum(ENTRY, TARGET) - np.array([3.0, 3.0, 2.0])
    hi = np.maximum(ENTRY, TARGET) + np.array([3.0, 3.0, 2.0])
    n = np.ceil((hi - lo) / SPACING_MM).astype(int) + 1  # (cols, rows, slices)
    offs = (np.arange(sub) + 0.5) / sub - 0.5
    hu = np.zeros((n[2], n[1], n[0]))
    k, j, i = np.meshgrid(np.arange(n[2]), np.arange(n[1]), np.arange(n[0]), indexing="ij")
    centres = lo + SPACING_MM * np.stack([i, j, k], -1).astype(np.float64)
    for dz in offs:
        for dy in offs:
            for dx in offs:
                hu += field_hu(centres + SPACING_MM * np.array([dx, dy, dz]))
    hu /= sub**3
    affine = np.diag([SPACING_MM, SPACING_MM, SPACING_MM, 1.0])
    affine[:3, 3] = lo
    return CTVolume(
        hu=np.rint(hu).astype(np.int16),
        affine_lps=affine,
        valid=None,
        info=SeriesInfo(series_uid="bench"),
    )


@dataclass(frozen=True)
class Truth:
    depth_mm: np.ndarray
    hu_mean: np.ndarray
    s_t: np.ndarray
    s0_n: np.ndarray


def _lip_stats(hu: np.ndarray, gate_fn: object) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(D,) lip-mean HU, cut fraction s_t and DC force S0 (N, zero feed) of lip samples (D, R, A).

    Rings are equal-width bins (midpoint rule), so the lip integral is the plain mean.
    """
    g = gate_fn(hu)  # type: ignore[operator]
    s0 = g * a0_n(hu, 0.0, _CAL)
    return hu.mean(axis=(1, 2), dtype=np.float64), g.mean(axis=(1, 2)), s0.mean(axis=(1, 2))


def _points(depth_mm: np.ndarray, n_rings: int, n_angles: int) -> np.ndarray:
    return lip_ring_points(
        ENTRY,
        TARGET,
        depth_mm,
        drill=DrillSpec(diameter_mm=DIAMETER_MM, tip_length_mm=TIP_MM),
        n_rings=n_rings,
        n_angles=n_angles,
    )


def _lip_hu(
    vol: CTVolume, depth_mm: np.ndarray, n_rings: int, n_angles: int, order: int = 1
) -> np.ndarray:
    return sample_lip_rings(
        vol,
        ENTRY,
        TARGET,
        depth_mm,
        drill=DrillSpec(diameter_mm=DIAMETER_MM, tip_length_mm=TIP_MM),
        n_rings=n_rings,
        n_angles=n_angles,
        order=order,
    ).hu


def reference(
    vol: CTVolume | None, depth_mm: np.ndarray, *, n_rings: int, n_angles: int, gate_fn: object
) -> Truth:
    """Lip integrals with a fine lip: of the continuous object (``vol`` None) or of ``vol``."""
    hu_mean = np.empty(depth_mm.size)
    s_t = np.empty(depth_mm.size)
    s0_n = np.empty(depth_mm.size)
    for a in range(0, depth_mm.size, 64):
        sl = slice(a, a + 64)
        if vol is None:
            hu = field_hu(_points(depth_mm[sl], n_rings, n_angles))
        else:
            hu = _lip_hu(vol, depth_mm[sl], n_rings, n_angles)
        hu_mean[sl], s_t[sl], s0_n[sl] = _lip_stats(hu, gate_fn)
    return Truth(depth_mm, hu_mean, s_t, s0_n)


def _rms(err: np.ndarray) -> float:
    return float(np.sqrt(np.mean(err**2)))


@dataclass(frozen=True)
class Result:
    order: int
    step_mm: float
    n_rings: int
    n_angles: int
    time_s: float
    rms_hu: float  # vs the continuous object
    rms_st: float
    max_st: float
    disc_hu: float  # vs the converged trilinear sampling of the same voxels
    disc_st: float
    rms_s0_n: float  # DC force S0 (bone-illustrative, zero feed) vs the continuous object
    disc_s0_n: float  # ... vs the converged sampling


def main_sweep(quick: bool) -> tuple[list[Result], dict[str, str]]:
    """Measure every configuration; also return notes (setup timings)."""
    cal = _CAL

    def gate_fn(hu: np.ndarray) -> np.ndarray:
        return gate(hu, cal)

    t0 = time.perf_counter()
    vol = make_volume(sub=2 if quick else 4)
    t_vox = time.perf_counter() - t0
    fine_step = 0.05 if quick else 0.01
    fine = np.arange(0.0, LENGTH_MM + 1e-9, fine_step)
    t0 = time.perf_counter()
    ref = reference(
        None, fine, n_rings=24 if quick else 160, n_angles=48 if quick else 256, gate_fn=gate_fn
    )
    t_truth = time.perf_counter() - t0
    t0 = time.perf_counter()
    conv = reference(
        vol, fine, n_rings=12 if quick else 48, n_angles=24 if quick else 96, gate_fn=gate_fn
    )
    t_conv = time.perf_counter() - t0
    t0 = time.perf_counter()
    coeffs = ndimage.spline_filter(vol.hu.astype(np.float64), order=3, mode="mirror")
    t_prefilter = time.perf_counter() - t0

    def sample(order: int, step: float, n_r: int, n_a: int) -> np.ndarray:
        depth = np.arange(0.0, LENGTH_MM + 1e-9, step)
        if order in (0, 1):
            return _lip_hu(vol, depth, n_r, n_a, order)
        pts = _points(depth, n_r, n_a)
        idx = vol.lps_to_index(pts.reshape(-1, 3))
        vals = ndimage.map_coordinates(
            coeffs, idx[:, ::-1].T, order=3, mode="mirror", prefilter=False
        )
        return vals.reshape(pts.shape[:3]).astype(np.float32)

    orders: tuple[int, ...]
    steps: tuple[float, ...]
    if quick:
        orders, steps = (1,), (0.1,)
        grids: tuple[tuple[int, int], ...] = ((2, 6), (DEFAULT_N_RINGS, DEFAULT_N_ANGLES))
    else:
        orders, steps = (0, 1, 3), (0.01, 0.02, 0.05, 0.1, 0.2, 0.5)
        grids = ((1, 4), (2, 6), (3, 8), (4, 8), (4, 12), (6, 12), (6, 18), (8, 24), (16, 48))
    results = []
    for order in orders:
        for step in steps:
            for n_r, n_a in grids:
                if step <= 0.02 and n_r * n_a > 100 and order != 1:
                    continue  # the slow corner adds nothing the order-1 sweep does not show
                depth = np.arange(0.0, LENGTH_MM + 1e-9, step)
                hu = sample(order, step, n_r, n_a)
                hu_mean, s_t, s0 = (np.interp(fine, depth, v) for v in _lip_stats(hu, gate_fn))
                errs = (
                    hu_mean - ref.hu_mean,
                    s_t - ref.s_t,
                    hu_mean - conv.hu_mean,
                    s_t - conv.s_t,
                    s0 - ref.s0_n,
                    s0 - conv.s0_n,
                )
                timing = time_it(partial(sample, order, step, n_r, n_a), repeats=1 if quick else 5)
                results.append(
                    Result(
                        order,
                        step,
                        n_r,
                        n_a,
                        timing.median_s,
                        _rms(errs[0]),
                        _rms(errs[1]),
                        float(np.max(np.abs(errs[1]))),
                        _rms(errs[2]),
                        _rms(errs[3]),
                        _rms(errs[4]),
                        _rms(errs[5]),
                    )
                )
    notes = {
        "volume": f"{vol.hu.shape[2]}x{vol.hu.shape[1]}x{vol.hu.shape[0]} voxels",
        "voxelise_s": f"{t_vox:.2f}",
        "truth_s": f"{t_truth:.2f}",
        "converged_s": f"{t_conv:.2f}",
        "converged": "12x24" if quick else "48x96",
        "prefilter_ms": f"{t_prefilter * 1e3:.1f}",
        "s0_peak_n": f"{float(np.max(ref.s0_n)):.2f}",
    }
    return results, notes


def pareto(results: list[Result], key: str) -> list[Result]:
    """Configurations not beaten on both time and error ``key``."""
    front: list[Result] = []
    for r in sorted(results, key=lambda r: (r.time_s, getattr(r, key))):
        if not front or getattr(r, key) < getattr(front[-1], key):
            front.append(r)
    return front


def plot(results: list[Result], default: Result | None, out: Path) -> None:
    """Error vs time, one panel per error, markers by order, the Pareto front, defaults starred."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    fig, axs = plt.subplots(2, 2, figsize=(11, 8.5), constrained_layout=True)
    axes = axs.ravel()
    colours = {0: "tab:orange", 1: "tab:blue", 3: "tab:green"}
    markers = {0.01: "v", 0.02: "^", 0.05: "o", 0.1: "s", 0.2: "D", 0.5: "X"}
    for ax, key, label in (
        (axes[0], "disc_st", "RMS s_t error vs converged sampling"),
        (axes[1], "disc_hu", "RMS lip-mean HU error vs converged sampling"),
        (axes[2], "rms_st", "RMS s_t error vs the continuous object"),
        (axes[3], "rms_hu", "RMS lip-mean HU error vs the continuous object"),
    ):
        for r in results:
            ax.scatter(
                [r.time_s * 1e3],
                [getattr(r, key)],
                s=16,
                c=colours[r.order],
                marker=markers.get(r.step_mm, "o"),
                alpha=0.7,
            )
        front = pareto(results, key)
        ax.plot(
            [r.time_s * 1e3 for r in front],
            [getattr(r, key) for r in front],
            "k-",
            lw=0.8,
            label="Pareto front",
        )
        if default is not None:
            ax.scatter(
                [default.time_s * 1e3],
                [getattr(default, key)],
                marker="*",
                s=220,
                c="red",
                edgecolors="k",
                zorder=5,
                label=f"default ({default.n_rings}x{default.n_angles}, "
                f"{default.step_mm} mm, trilinear)",
            )
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("time per 16 mm trajectory (ms)")
        ax.set_ylabel(label)
        ax.grid(True, which="both", alpha=0.3)
    handles = [
        Line2D([], [], ls="", marker="o", c=colours[o], label=ORDER_NAMES[o])
        for o in sorted({r.order for r in results})
    ]
    handles += [
        Line2D([], [], ls="", marker=markers.get(h, "o"), c="grey", label=f"step {h} mm")
        for h in sorted({r.step_mm for r in results})
    ]
    axes[0].legend(handles=handles + axes[0].get_legend_handles_labels()[0], fontsize=7, ncol=2)
    fig.suptitle("Lip sampling: accuracy vs cost (0.3 mm voxels, 2 mm drill)")
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)


def _peer(quick: bool) -> tuple[str, float]:
    """sample_lip_rings vs a bare map_coordinates(order=1) on the same points (defaults)."""
    vol = make_volume(sub=1)
    depth = np.arange(0.0, LENGTH_MM + 1e-9, 0.05)
    hu32 = vol.hu.astype(np.float32)

    def ours() -> object:
        return sample_lip_rings(
            vol,
            ENTRY,
            TARGET,
            depth,
            drill=DrillSpec(diameter_mm=DIAMETER_MM, tip_length_mm=TIP_MM),
        )

    def peer() -> object:
        pts = lip_ring_points(
            ENTRY, TARGET, depth, drill=DrillSpec(diameter_mm=DIAMETER_MM, tip_length_mm=TIP_MM)
        )
        idx = vol.lps_to_index(pts.reshape(-1, 3))
        return ndimage.map_coordinates(hu32, idx[:, ::-1].T, order=1, mode="constant", cval=-1000.0)

    reps = 3 if quick else 15
    t_ours, t_peer = time_it(ours, repeats=reps), time_it(peer, repeats=reps)
    a = ours().hu.reshape(-1)  # type: ignore[attr-defined]
    b = np.asarray(peer())
    ratio_x = t_ours.median_s / t_peer.median_s
    ratio = f"{ratio_x:.2f}"
    rows = [["sample_lip_rings (trilinear, + outside counts, + axis)", t_ours.fmt("ms"), ratio],
            ["map_coordinates(order=1) on the same points", t_peer.fmt("ms"), "1.00"]]  # fmt: skip
    return (
        table(["implementation", "time per trajectory", "ratio"], rows)
        + f"\n\nSame {depth.size} x {DEFAULT_N_RINGS} x {DEFAULT_N_ANGLES} points; largest "
        f"difference between the two: {np.max(np.abs(a - b)):.2g} HU.",
        ratio_x,
    )


def _n_samples(r: Result) -> int:
    """Lip samples per trajectory: the machine-independent cost (times vary with load)."""
    return int(np.arange(0.0, LENGTH_MM + 1e-9, r.step_mm).size) * r.n_rings * r.n_angles


def run(quick: bool) -> Section:
    """Run the sweep, write the Pareto figure, return the report section."""
    results, notes = main_sweep(quick)
    key = (1, 0.1 if quick else 0.05, DEFAULT_N_RINGS, DEFAULT_N_ANGLES)
    default = next((r for r in results if (r.order, r.step_mm, r.n_rings, r.n_angles) == key), None)
    plot(results, default, figure_path(FIGURE_NAME))
    # fmt: off
    peak = float(notes["s0_peak_n"])
    rows = [
        [ORDER_NAMES[r.order], r.step_mm, f"{r.n_rings}x{r.n_angles}", _n_samples(r),
         f"{r.time_s * 1e3:.3g}", f"{r.disc_st:.4f}", f"{r.disc_hu:.1f}",
         f"{r.disc_s0_n:.3f} ({100 * r.disc_s0_n / peak:.2f} %)", f"{r.rms_st:.4f}",
         f"{r.max_st:.3f}", f"{r.rms_hu:.1f}",
         f"{r.rms_s0_n:.3f} ({100 * r.rms_s0_n / peak:.2f} %)"]
        for r in sorted(results, key=lambda r: (r.order, r.step_mm, r.n_rings * r.n_angles))
    ]
    # fmt: on
    front = pareto(results, "disc_st")
    peer_text, peer_ratio = _peer(quick)
    md = [
        __doc__.split("\n\n", 1)[1].strip() if __doc__ else "",
        "",
        f"Volume {notes['volume']}; voxelising took {notes['voxelise_s']} s, the truth "
        f"{notes['truth_s']} s, the cubic pre-filter {notes['prefilter_ms']} ms (once per "
        "volume, not in the times below).",
        "",
        f"Converged sampling: trilinear, {notes['converged']}, depth step of the truth "
        f"({notes['converged_s']} s). 'disc' columns compare with it (the discretisation error "
        "alone); 'object' columns with the continuous object (adds partial-volume error, "
        "which no sampling choice removes).",
        "",
        "Pareto front on the discretisation s_t error (time ms, RMS s_t): "
        + ", ".join(
            f"{ORDER_NAMES[r.order]} {r.step_mm} mm "
            f"{r.n_rings}x{r.n_angles} ({r.time_s * 1e3:.2g}, {r.disc_st:.4f})"
            for r in front
        ),
        "",
        table(TABLE_HEADER, rows),
        "",
        f"Force errors: the DC cutting force S0 of the ``bone-illustrative`` set at zero feed, "
        f"in N and in % of its peak along the path ({peak:.2f} N).",
        "",
        "### Peer: the same points through scipy",
        "",
        peer_text,
    ]
    shortfalls = (
        (
            f"lip sampling (`sample_lip_rings`) takes {peer_ratio:.2f} x the time of a bare "
            "`map_coordinates(order=1)` on the same points (it also counts outside/padding "
            "samples and returns the axis HU; the gap is in `CTVolume.sample`'s corner gather)",
        )
        if peer_ratio > 1.0
        else ()
    )
    return Section(
        title="Lip sampling",
        markdown="\n".join(md),
        figures=(str(figure_path(FIGURE_NAME)),),
        shortfalls=shortfalls,
    )
