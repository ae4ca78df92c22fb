"""Trilinear sampling of a CT at one point, for compiled kernels (numba helpers).

:func:`trilinear` is :meth:`~ctdrill.imaging.volume.CTVolume.sample` (``order=1``) at one LPS
point of a volume without padding: the same index arithmetic, hull test (within 1e-6 voxel of
the voxel-centre hull) and true slice positions of an irregular stack, the weights (``1 - t``,
then 1 minus that, not ``t``) and summation order of
``scipy.ndimage.map_coordinates(order=1, mode="nearest")``, so its bits are
:meth:`~ctdrill.imaging.volume.CTVolume.sample`'s (an ulp apart, a sample exactly at a
threshold was classed differently by the walls' kernel and their NumPy path); NaN outside.
A kernel calling it must be recompiled when it changes (numba's disk cache of a kernel does not
see a change in another module): a change here goes with a touch of every kernel module that
imports it. The kernels
of the bone walls (:mod:`~ctdrill.imaging.sampling.envelope_kernel`), of the bone surface
(:mod:`~ctdrill.imaging.sampling.surface_kernel`), of suggest's shells
(:mod:`ctdrill.app.search.shell_kernel`), of the drill's lip rings
(:mod:`~ctdrill.imaging.sampling.lip_batch`) and of
:meth:`~ctdrill.imaging.volume.CTVolume.sample`'s points
(:mod:`~ctdrill.imaging.sampling.points_kernel`) read the CT through it; each cell's eight-term
sum is :func:`cell_sum`'s. What a kernel passes for a volume is
:mod:`~ctdrill.imaging.sampling.kernel_args`' (this module imports no volume: the volume's own
points kernel reads through it).
"""

from __future__ import annotations

import math

import numpy as np

from ctdrill.jit import helper

#: The numba type string of :func:`~ctdrill.imaging.sampling.kernel_args.volume_args`
#: for voxels of type ``{vol}``.
VOLUME_SIG = "{vol}[:, :, ::1], float64[:, ::1], float64[::1], float64[::1], float64[::1], boolean"


@helper
def cell_sum(
    vol: np.ndarray,
    k0: int,
    k1: int,
    j0: int,
    j1: int,
    i0: int,
    i1: int,
    wk0: float,
    wj0: float,
    wi0: float,
) -> float:  # pragma: no cover - compiled; tested through trilinear and the points kernel
    """The eight-term sum of one cell: corners ``(k0|k1, j0|j1, i0|i1)`` with the near
    weights ``wk0, wj0, wi0`` (the far ones 1 minus them), each term ``value * wk * wj * wi``,
    added in ``map_coordinates(order=1)``'s corner order: the one place every compiled
    trilinear read sums a cell."""
    wk1 = 1.0 - wk0
    wj1 = 1.0 - wj0
    wi1 = 1.0 - wi0
    total = 0.0
    total += float(vol[k0, j0, i0]) * wk0 * wj0 * wi0
    total += float(vol[k0, j0, i1]) * wk0 * wj0 * wi1
    total += float(vol[k0, j1, i0]) * wk0 * wj1 * wi0
    total += float(vol[k0, j1, i1]) * wk0 * wj1 * wi1
    total += float(vol[k1, j0, i0]) * wk1 * wj0 * wi0
    total += float(vol[k1, j0, i1]) * wk1 * wj0 * wi1
    total += float(vol[k1, j1, i0]) * wk1 * wj1 * wi0
    total += float(vol[k1, j1, i1]) * wk1 * wj1 * wi1
    return total


@helper
def at_index(
    vol: np.ndarray, ck: float, cj: float, ci: float
) -> float:  # pragma: no cover - compiled; tested through trilinear
    """The trilinear sample at index coordinates (k, j, i) inside the hull (within its
    tolerance): ``map_coordinates(order=1, mode="nearest")``'s weights and summation order
    (:func:`cell_sum`), indices beyond an edge on the edge."""
    n_k, n_j, n_i = vol.shape
    sk = math.floor(ck)
    sj = math.floor(cj)
    si = math.floor(ci)
    wk0 = 1.0 - (ck - sk)  # scipy's weights: 1 - t, then 1 minus that (not t)
    wj0 = 1.0 - (cj - sj)
    wi0 = 1.0 - (ci - si)
    return cell_sum(
        vol,
        min(max(sk, 0), n_k - 1),
        min(max(sk + 1, 0), n_k - 1),
        min(max(sj, 0), n_j - 1),
        min(max(sj + 1, 0), n_j - 1),
        min(max(si, 0), n_i - 1),
        min(max(si + 1, 0), n_i - 1),
        wk0,
        wj0,
        wi0,
    )


@helper
def at_index_inside(
    vol: np.ndarray, ck: float, cj: float, ci: float
) -> float:  # pragma: no cover - compiled; tested through the walls' kernel
    """:func:`at_index` at index coordinates strictly inside the hull (each ``>= 0`` and
    below its axis's last index, so the cell's far corners exist): the same weights and
    :func:`cell_sum` without the clamps, which do nothing there."""
    sk = math.floor(ck)
    sj = math.floor(cj)
    si = math.floor(ci)
    wk0 = 1.0 - (ck - sk)  # scipy's weights: 1 - t, then 1 minus that (not t)
    wj0 = 1.0 - (cj - sj)
    wi0 = 1.0 - (ci - si)
    return cell_sum(vol, sk, sk + 1, sj, sj + 1, si, si + 1, wk0, wj0, wi0)


@helper
def trilinear(
    vol: np.ndarray,
    inv_lin: np.ndarray,
    inv_off: np.ndarray,
    top: np.ndarray,
    k_nominal: np.ndarray,
    remap: bool,
    p0: float,
    p1: float,
    p2: float,
) -> float:  # pragma: no cover - compiled; tested against CTVolume.sample
    """CTVolume.sample(order=1) at one LPS point of an unpadded volume; NaN outside the hull."""
    n_s = k_nominal.shape[0]
    tol = 1e-6
    ck = inv_lin[2, 0] * p0 + inv_lin[2, 1] * p1 + inv_lin[2, 2] * p2
    ck += inv_off[2]
    cj = inv_lin[1, 0] * p0 + inv_lin[1, 1] * p1 + inv_lin[1, 2] * p2
    cj += inv_off[1]
    ci = inv_lin[0, 0] * p0 + inv_lin[0, 1] * p1 + inv_lin[0, 2] * p2
    ci += inv_off[0]
    if remap:  # np.interp on the true slice positions, linear beyond the ends
        if ck < k_nominal[0]:
            slope = 1.0 / (k_nominal[1] - k_nominal[0])
            ck = 0.0 + (ck - k_nominal[0]) * slope
        elif ck > k_nominal[n_s - 1]:
            slope = 1.0 / (k_nominal[n_s - 1] - k_nominal[n_s - 2])
            ck = (n_s - 1.0) + (ck - k_nominal[n_s - 1]) * slope
        elif ck == k_nominal[n_s - 1]:
            ck = n_s - 1.0
        else:
            j = np.searchsorted(k_nominal, ck, side="right") - 1
            if k_nominal[j] == ck:
                ck = float(j)
            else:
                slope = 1.0 / (k_nominal[j + 1] - k_nominal[j])
                ck = slope * (ck - k_nominal[j]) + float(j)
    if not (
        ck >= -tol
        and cj >= -tol
        and ci >= -tol
        and ck <= top[2] + tol
        and cj <= top[1] + tol
        and ci <= top[0] + tol
    ):
        return np.nan
    return at_index(vol, ck, cj, ci)
