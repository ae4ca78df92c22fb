"""Order-1 ``map_coordinates`` (``mode="nearest"``) at index points, compiled (numba).

:meth:`ctdrill.imaging.volume.CTVolume.sample` on an unpadded volume builds the continuous
``(k, j, i)`` index of every point and interpolates the voxels there. This kernel does the
interpolation as ``scipy.ndimage.map_coordinates(order=1, mode="nearest", prefilter=False)``
does (:func:`~ctdrill.imaging.sampling.trilinear.at_index`: the weights ``1 - t`` and
``1 - (1 - t)``, the corners in the same order, each term ``value * wk * wj * wi``, indices
beyond an edge on the edge), so the two give the same bits.
It needs no SciPy import (0.3-0.6 s of a fresh process's start: SciPy's array-API layer) and
runs over the points in one compiled loop (split between threads from :data:`THREAD_POINTS`
points: each point is independent, so the bits do not depend on the split). Without the
kernel (not in numba's disk cache, or a small job: :mod:`ctdrill.jit`)
:func:`sample_index_points_numpy` does the same operations in NumPy, in blocks of
:data:`NUMPY_BLOCK_POINTS` points: the same bits, and still no SciPy import.
"""

from __future__ import annotations

import itertools

import numpy as np

from ctdrill import jit
from ctdrill.imaging.sampling.trilinear import at_index
from ctdrill.jit import Kernel


def _points_kernel(
    vol: np.ndarray, coords_kji: np.ndarray, out: np.ndarray, lo: int, hi: int
) -> None:  # pragma: no cover - compiled; tested against map_coordinates
    for n in range(lo, hi):
        out[n] = at_index(vol, coords_kji[0, n], coords_kji[1, n], coords_kji[2, n])


_SIG = "void({vol}[:, :, ::1], float64[:, ::1], float64[::1], int64, int64)"
#: Points below which one thread samples them all (a thread costs more than it saves).
THREAD_POINTS = 1 << 16
POINTS_KERNEL = Kernel(
    _points_kernel, [_SIG.format(vol="int16"), _SIG.format(vol="float32")], readonly=(0,)
)


def sample_index_points(vol: np.ndarray, coords_kji: np.ndarray, out: np.ndarray) -> bool:
    """Fill ``out`` (N,) float64 with the order-1 interpolation of ``vol`` (K, J, I), int16 or
    float32, C order) at the index points ``coords_kji`` (3, N) float64, C order, each within
    ``[-1e-6, n - 1 + 1e-6]`` per axis. False (``out`` untouched) when the kernel is not in the
    cache or the arrays are not of those types."""
    if not (
        vol.dtype in (np.int16, np.float32)
        and vol.ndim == 3
        and vol.flags.c_contiguous
        and coords_kji.dtype == np.float64
        and coords_kji.flags.c_contiguous
        and out.dtype == np.float64
        and out.flags.c_contiguous
        and POINTS_KERNEL.ready()
    ):
        return False
    n = out.shape[0]
    parts = max(1, min(jit.cpus(), 8, n // THREAD_POINTS))
    edges = [n * p // parts for p in range(parts + 1)]
    jit.run_spans(POINTS_KERNEL, list(itertools.pairwise(edges)), vol, coords_kji, out)
    return True


#: Points per block of :func:`sample_index_points_numpy`: its temporaries (~1.3 MB) stay in
#: the CPU's cache; 227 000 points (a one-plan export's walls) took 16 ms of CPU in blocks of
#: 2**14 against 24 ms in one block of 2**18 (each point's bits do not depend on the blocks).
NUMPY_BLOCK_POINTS = 1 << 14


def sample_index_points_numpy(vol: np.ndarray, coords_kji: np.ndarray, out: np.ndarray) -> None:
    """:func:`sample_index_points` in NumPy: the kernel's weights, corner order and sums
    (``value * wk * wj * wi``, added one corner after another), hence its bits. ``vol``
    (K, J, I) of any real dtype, ``coords_kji`` (3, N) float64, ``out`` (N,) float64."""
    n_kji = vol.shape
    flat = vol.reshape(-1)
    strides = (n_kji[1] * n_kji[2], n_kji[2], 1)
    for lo in range(0, out.shape[0], NUMPY_BLOCK_POINTS):
        c = coords_kji[:, lo : lo + NUMPY_BLOCK_POINTS]
        s = np.floor(c)
        w0 = 1.0 - (c - s)  # scipy's weights: 1 - t, then 1 minus that (not t)
        w1 = 1.0 - w0
        top = np.array(n_kji, dtype=np.float64)[:, None] - 1.0
        i0 = np.clip(s, 0.0, top).astype(np.int64)
        i1 = np.clip(s + 1.0, 0.0, top).astype(np.int64)
        total = np.zeros(c.shape[1])
        for k, wk in ((i0[0], w0[0]), (i1[0], w1[0])):
            for j, wj in ((i0[1], w0[1]), (i1[1], w1[1])):
                for i, wi in ((i0[2], w0[2]), (i1[2], w1[2])):
                    at = k * strides[0] + j * strides[1] + i
                    total += flat[at].astype(np.float64) * wk * wj * wi
        out[lo : lo + c.shape[1]] = total
