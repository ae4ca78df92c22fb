"""The first bone crossing of :mod:`ctdrill.imaging.sampling.surface`, compiled: arrays only.

The kernel reads the same points as :func:`~ctdrill.imaging.sampling.surface._crossings` on
its NumPy path (each ``origin + t * direction`` built with the same floating-point operations,
trilinear as :meth:`~ctdrill.imaging.volume.CTVolume.sample` through
:func:`~ctdrill.imaging.sampling.trilinear.trilinear`, NaN outside) and applies the same rules:
the first bone sample after a measured one below the threshold, then the bisection of every
line in lockstep until the widest bracket is within the tolerance (the NumPy loop's stopping
rule), in compiled code that releases the interpreter lock. Only an unpadded volume is read
here (:func:`~ctdrill.imaging.sampling.trilinear.fits`); the NumPy path is the reference (its
samples are ``CTVolume.sample``'s bits: trilinear with map_coordinates' weights).
"""

from __future__ import annotations

import numpy as np

from ctdrill.imaging.sampling.trilinear import VOLUME_SIG, trilinear
from ctdrill.jit import Kernel


def _surface_kernel(
    vol: np.ndarray,
    inv_lin: np.ndarray,
    inv_off: np.ndarray,
    top: np.ndarray,
    k_nominal: np.ndarray,
    remap: bool,
    origins: np.ndarray,
    dirs: np.ndarray,
    ts: np.ndarray,
    bone_hu: float,
    tol: float,
    out: np.ndarray,
) -> None:  # pragma: no cover - compiled by numba; tested against the NumPy path
    n = origins.shape[0]
    lo = np.empty(n)
    hi = np.empty(n)
    ok = np.zeros(n, dtype=np.bool_)
    for r in range(n):
        out[r] = np.nan
        prev = np.nan
        for j in range(ts.shape[0]):
            t = ts[j]
            h = trilinear(
                vol, inv_lin, inv_off, top, k_nominal, remap,
                origins[r, 0] + t * dirs[r, 0],
                origins[r, 1] + t * dirs[r, 1],
                origins[r, 2] + t * dirs[r, 2],
            )  # fmt: skip
            if h >= bone_hu:  # NaN compares False
                if j >= 1 and not np.isnan(prev):
                    ok[r] = True
                    lo[r] = ts[j - 1]
                    hi[r] = t
                break
            prev = h
    widest = 0.0
    any_ok = False
    for r in range(n):
        if ok[r]:
            any_ok = True
            widest = max(widest, hi[r] - lo[r])
    if not any_ok:
        return
    while widest > tol:
        widest = 0.0
        for r in range(n):
            if not ok[r]:
                continue
            mid = 0.5 * (lo[r] + hi[r])
            v = trilinear(
                vol, inv_lin, inv_off, top, k_nominal, remap,
                origins[r, 0] + mid * dirs[r, 0],
                origins[r, 1] + mid * dirs[r, 1],
                origins[r, 2] + mid * dirs[r, 2],
            )  # fmt: skip
            if v >= bone_hu:
                hi[r] = mid
            else:
                lo[r] = mid
            widest = max(widest, hi[r] - lo[r])
    for r in range(n):
        if ok[r]:
            out[r] = hi[r]


_SIG = (
    "void(" + VOLUME_SIG + ", float64[:, ::1], float64[:, ::1], float64[::1], float64, "
    "float64, float64[::1])"
)
SURFACE_KERNEL = Kernel(
    _surface_kernel, [_SIG.format(vol="int16"), _SIG.format(vol="float32")], readonly=(0, 4)
)
