"""Tight-loop floors for ``bench_shells``: compiled loops that read the same trilinear samples as
the shell and wall kernels and only sum them (no rule, no flags, no bisection)."""

from __future__ import annotations

import numpy as np

from ctdrill.imaging.sampling.trilinear import VOLUME_SIG, trilinear
from ctdrill.jit import Kernel


def _shell_floor(
    vol: np.ndarray,
    inv_lin: np.ndarray,
    inv_off: np.ndarray,
    top: np.ndarray,
    k_nominal: np.ndarray,
    remap: bool,
    entries: np.ndarray,
    dirs: np.ndarray,
    e1: np.ndarray,
    e2: np.ndarray,
    depth: np.ndarray,
    radial: np.ndarray,
    cos_t: np.ndarray,
    sin_t: np.ndarray,
    out: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """Every shell, surface and wall point of every candidate (sample_shells' points)."""
    for n in range(entries.shape[0]):
        acc = 0.0
        for d in range(depth.shape[0]):
            c0 = entries[n, 0] + depth[d] * dirs[n, 0]
            c1 = entries[n, 1] + depth[d] * dirs[n, 1]
            c2 = entries[n, 2] + depth[d] * dirs[n, 2]
            for a in range(cos_t.shape[0]):
                r0 = cos_t[a] * e1[n, 0] + sin_t[a] * e2[n, 0]
                r1 = cos_t[a] * e1[n, 1] + sin_t[a] * e2[n, 1]
                r2 = cos_t[a] * e1[n, 2] + sin_t[a] * e2[n, 2]
                for k in range(radial.shape[1]):
                    r = radial[d, k]
                    h = trilinear(
                        vol, inv_lin, inv_off, top, k_nominal, remap,
                        c0 + r * r0, c1 + r * r1, c2 + r * r2,
                    )  # fmt: skip
                    if not np.isnan(h):
                        acc += h
        out[n] = acc


def _ray_floor(
    vol: np.ndarray,
    inv_lin: np.ndarray,
    inv_off: np.ndarray,
    top: np.ndarray,
    k_nominal: np.ndarray,
    remap: bool,
    origins: np.ndarray,
    dirs: np.ndarray,
    step: float,
    n_steps: np.ndarray,
    out: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """``n_steps[n]`` samples ``step`` apart along each ray."""
    for n in range(origins.shape[0]):
        acc = 0.0
        for k in range(n_steps[n]):
            t = k * step
            h = trilinear(
                vol, inv_lin, inv_off, top, k_nominal, remap,
                origins[n, 0] + t * dirs[n, 0],
                origins[n, 1] + t * dirs[n, 1],
                origins[n, 2] + t * dirs[n, 2],
            )  # fmt: skip
            if not np.isnan(h):
                acc += h
        out[n] = acc


_SHELL_SIG = (
    "void(" + VOLUME_SIG + ", float64[:, ::1], float64[:, ::1], float64[:, ::1], "
    "float64[:, ::1], float64[::1], float64[:, ::1], float64[::1], float64[::1], float64[::1])"
)
_RAY_SIG = (
    "void(" + VOLUME_SIG + ", float64[:, ::1], float64[:, ::1], float64, int64[::1], float64[::1])"
)
SHELL_FLOOR = Kernel(
    _shell_floor,
    [_SHELL_SIG.format(vol="int16"), _SHELL_SIG.format(vol="float32")],
    readonly=(0, 4),
)
RAY_FLOOR = Kernel(
    _ray_floor, [_RAY_SIG.format(vol="int16"), _RAY_SIG.format(vol="float32")], readonly=(0, 4)
)
