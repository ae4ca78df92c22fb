"""The shells of :mod:`ctdrill.app.search.shell`, compiled: every candidate's ring samples.

For ``N`` candidate axes sharing one body, the kernel reads the same points
:func:`~ctdrill.app.search.shell.sample_shells` reads on its NumPy path (the same floating-point
construction of each point, trilinear as :meth:`~ctdrill.imaging.volume.CTVolume.sample` through
:func:`~ctdrill.imaging.sampling.trilinear.trilinear`) and applies the same rules to them (the
shell HU with outside as air and a tooth as water; the perforation and thin-wall flags), in
compiled code that releases the interpreter lock. The NumPy path stays the reference (tests
hold the two equal to float rounding; the samples are ``CTVolume.sample``'s bits, trilinear
with map_coordinates' weights).
"""

from __future__ import annotations

import numpy as np

from ctdrill.imaging.sampling.trilinear import VOLUME_SIG, trilinear
from ctdrill.jit import Kernel


def _shell_kernel(
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
    deep: np.ndarray,
    cos_t: np.ndarray,
    sin_t: np.ndarray,
    n_shell: int,
    params: np.ndarray,
    hu_out: np.ndarray,
    perforation: np.ndarray,
    thin: np.ndarray,
    row_lo: int,
    row_hi: int,
) -> None:  # pragma: no cover - compiled by numba; tested against the NumPy path
    bone_hu, tooth_hu, air_hu, tooth_score_hu = params[0], params[1], params[2], params[3]
    n_a = cos_t.shape[0]
    n_k = radial.shape[1]
    for n in range(row_lo, row_hi):
        perf = False
        thin_n = False
        for d in range(depth.shape[0]):
            c0 = entries[n, 0] + depth[d] * dirs[n, 0]
            c1 = entries[n, 1] + depth[d] * dirs[n, 1]
            c2 = entries[n, 2] + depth[d] * dirs[n, 2]
            for a in range(n_a):
                r0 = cos_t[a] * e1[n, 0] + sin_t[a] * e2[n, 0]
                r1 = cos_t[a] * e1[n, 1] + sin_t[a] * e2[n, 1]
                r2 = cos_t[a] * e1[n, 2] + sin_t[a] * e2[n, 2]
                for k in range(n_k):
                    if k == n_shell and (perf or not deep[d]):
                        continue  # the surface: read where it can still flag
                    if k == n_shell + 1 and thin_n:
                        continue
                    r = radial[d, k]
                    h = trilinear(
                        vol,
                        inv_lin,
                        inv_off,
                        top,
                        k_nominal,
                        remap,
                        c0 + r * r0,
                        c1 + r * r1,
                        c2 + r * r2,
                    )
                    if k < n_shell:
                        if np.isnan(h):
                            h = air_hu
                        elif h >= tooth_hu:
                            h = tooth_score_hu
                        hu_out[n, d, a * n_shell + k] = h
                    elif h < bone_hu or h >= tooth_hu:  # NaN (unknown): neither
                        if k == n_shell:
                            perf = True
                        else:
                            thin_n = True
        perforation[n] = perf
        thin[n] = thin_n


_SIG = (
    "void(" + VOLUME_SIG + ", float64[:, ::1], float64[:, ::1], float64[:, ::1], "
    "float64[:, ::1], float64[::1], float64[:, ::1], boolean[::1], float64[::1], float64[::1], "
    "int64, float64[::1], float64[:, :, ::1], boolean[::1], boolean[::1], int64, int64)"
)
SHELL_KERNEL = Kernel(
    _shell_kernel, [_SIG.format(vol="int16"), _SIG.format(vol="float32")], readonly=(0, 4)
)
