"""Force profiles of many trajectories at once (the batched form of :func:`build_profile`).

:func:`build_profiles` integrates the force law over the lip rings of ``N`` trajectories'
float32 ring samples (N, D, R, A) and returns per row what :func:`build_profile` returns for
that row's samples: ``S0``, ``Sk``, ``s_t``, the lip-mean HU and the count of extrapolated
samples, with the same gate and the same clipping of ``C'``. The power laws ``10**b0 C'**n``
come from cubic Hermite tables of the laws on the calibration's ``C'`` range
(:func:`law_tables`: within 5e-12 of the law, relative, for the bundled sets), which replaces
one log and three exps per lip sample (most of the kernel's time) by three polynomials; the
sums differ from NumPy's pairwise ones only in the last bits. A second set of ring weights
gives another weighted mean HU (e.g. by annulus area). The compiled kernel runs when its
cache is present; otherwise :func:`_profile_numpy` does the kernel's operations in the
kernel's order with NumPy, vectorised over rows and depths (the same bits: a row's profile does
not depend on whether its process loaded numba). :func:`build_profile` is the reference both
are tested against.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ctdrill.hu import AIR_HU
from ctdrill.jit import Kernel, row_spans, run_spans
from ctdrill.model.calibration import Calibration, Harmonic, PowerLaw

_LN10 = math.log(10.0)


@dataclass(frozen=True, eq=False)
class ProfileBatch:
    """Per-row profile arrays; columns past a row's ``n_depths`` are NaN.

    Attributes
    ----------
    s0_n, s_t, hu_mean, hu_mean_alt : (N, D).
    sk_n : (N, K, D).
    n_clipped, n_samples : (N,) int64.
    """

    s0_n: np.ndarray
    sk_n: np.ndarray
    s_t: np.ndarray
    hu_mean: np.ndarray
    hu_mean_alt: np.ndarray
    n_clipped: np.ndarray
    n_samples: np.ndarray


#: Nodes per ``lo`` of C' in the power-law tables: the cubic Hermite interpolant of
#: ``C'**n`` on steps ``h <= lo / 512`` is within ``|n (n-1) (n-2) (n-3)| / 384 (h / C')**4``
#: (relative; 3e-12 for the bundled sets' exponents) of the law itself.
TABLE_STEPS_PER_LO = 512


def law_tables(calibration: Calibration) -> tuple[float, float, np.ndarray]:
    """Cubic Hermite tables of the calibration's power laws on C' in its range.

    Returns
    -------
    lo : the range's lower end.
    inv_step : 1 / node step.
    coefs : (M - 1, n_laws, 4) polynomial coefficients in the local coordinate ``u`` in
        [0, 1] of each interval (``a0 + u (a1 + u (a2 + u a3))``), laws in the order A0, then
        each harmonic; values and slopes at the nodes from the law itself (NumPy's exp/log10).
        Built once per set of laws in a process (cached: do not write into it).
    """
    lo, hi = (float(v) for v in calibration.c_prime_range)
    return _tables(lo, hi, (calibration.a0, *calibration.harmonics))


@functools.lru_cache(maxsize=16)
def _tables(
    lo: float, hi: float, laws: tuple[PowerLaw | Harmonic, ...]
) -> tuple[float, float, np.ndarray]:
    n_nodes = math.ceil((hi - lo) / (lo / TABLE_STEPS_PER_LO)) + 1
    nodes = np.linspace(lo, hi, n_nodes)
    step = (hi - lo) / (n_nodes - 1)
    coefs = np.empty((n_nodes - 1, len(laws), 4))
    for k, law in enumerate(laws):
        f = np.exp(_LN10 * (law.b0 + law.n * np.log10(nodes)))
        m = step * law.n * f / nodes  # h * df/dC'
        f0, f1, m0, m1 = f[:-1], f[1:], m[:-1], m[1:]
        coefs[:, k, 0] = f0
        coefs[:, k, 1] = m0
        coefs[:, k, 2] = 3.0 * (f1 - f0) - 2.0 * m0 - m1
        coefs[:, k, 3] = 2.0 * (f0 - f1) + m0 + m1
    return lo, 1.0 / step, coefs


def _profile_kernel(
    hu: np.ndarray,
    n_depth: np.ndarray,
    ring_w: np.ndarray,
    alt_w: np.ndarray,
    gate_lo: float,
    gate_w: float,
    cp_lo: float,
    cp_hi: float,
    air_hu: float,
    inv_step: float,
    coefs: np.ndarray,
    sums: np.ndarray,
    alt: np.ndarray,
    clipped: np.ndarray,
    row_lo: int,
    row_hi: int,
) -> None:  # pragma: no cover - compiled by numba; tested against build_profile
    n_r = hu.shape[2]
    n_a = hu.shape[3]
    n_law = coefs.shape[1]
    last = coefs.shape[0] - 1
    ring = np.empty(n_law + 2)
    acc = np.empty(n_law + 2)
    for n in range(row_lo, row_hi):
        count = 0
        for d in range(n_depth[n]):
            for q in range(n_law + 2):
                acc[q] = 0.0
            acc_alt = 0.0
            for r in range(n_r):
                for q in range(n_law + 2):
                    ring[q] = 0.0
                for a in range(n_a):
                    h = float(hu[n, d, r, a])
                    g = (h - gate_lo) / gate_w
                    g = min(max(g, 0.0), 1.0)
                    ring[0] += g
                    ring[1] += h
                    if g > 0.0:  # g = 0 adds exactly 0 to every law's sum
                        if h < cp_lo + air_hu or h > cp_hi + air_hu:
                            count += 1
                        cp = min(max(h - air_hu, cp_lo), cp_hi)
                        pos = (cp - cp_lo) * inv_step
                        j = min(int(pos), last)
                        u = pos - j
                        for k in range(n_law):
                            val = coefs[j, k, 0] + u * (
                                coefs[j, k, 1] + u * (coefs[j, k, 2] + u * coefs[j, k, 3])
                            )
                            ring[2 + k] += val * g
                for q in range(n_law + 2):
                    acc[q] += ring[q] * ring_w[r]
                acc_alt += ring[1] * alt_w[r]
            for q in range(n_law + 2):
                sums[n, q, d] = acc[q]
            alt[n, d] = acc_alt
        clipped[n] = count


def _profile_numpy(
    rows: np.ndarray,
    hu: np.ndarray,
    n_depth: np.ndarray,
    ring_w: np.ndarray,
    alt_w: np.ndarray,
    gate_lo: float,
    gate_w: float,
    cp_lo: float,
    cp_hi: float,
    air_hu: float,
    inv_step: float,
    coefs: np.ndarray,
    sums: np.ndarray,
    alt: np.ndarray,
    clipped: np.ndarray,
) -> None:
    """:func:`_profile_kernel` for ``rows`` with NumPy: every sum is taken in the kernel's order
    (angles, then rings, one addition at a time), every product and polynomial the same, so
    the results are the kernel's bits. Vectorised over the rows and their depths."""
    n_law = coefs.shape[1]
    last = coefs.shape[0] - 1
    with np.errstate(invalid="ignore"):  # past a row's depths the buffer holds anything
        h_all = hu[rows].astype(np.float64)  # (T, D, R, A): float32 to float64 is exact
    t, d_max, n_r, n_a = h_all.shape
    valid = np.arange(d_max)[None, :] < n_depth[rows][:, None]
    acc = np.zeros((n_law + 2, t, d_max))
    acc_alt = np.zeros((t, d_max))
    count = np.zeros(t, dtype=np.int64)
    for r in range(n_r):
        ring = np.zeros((n_law + 2, t, d_max))
        for a in range(n_a):
            h = h_all[:, :, r, a]
            g = np.minimum(np.maximum((h - gate_lo) / gate_w, 0.0), 1.0)
            ring[0] += g
            ring[1] += h
            cut = g > 0.0  # where g = 0 the kernel adds nothing (it would add exactly 0)
            out = cut & valid & ((h < cp_lo + air_hu) | (h > cp_hi + air_hu))
            count += out.sum(axis=1)
            pos = (np.minimum(np.maximum(h - air_hu, cp_lo), cp_hi) - cp_lo) * inv_step
            pos[~cut] = 0.0  # not read (NaN HU there: an index of its own)
            j = np.minimum(pos.astype(np.int64), last)
            u = pos - j
            for k in range(n_law):
                c = coefs[j, k]
                val = c[..., 0] + u * (c[..., 1] + u * (c[..., 2] + u * c[..., 3]))
                np.add(ring[2 + k], val * g, out=ring[2 + k], where=cut)
        acc += ring * ring_w[r]
        acc_alt += ring[1] * alt_w[r]
    for i, n in enumerate(rows.tolist()):
        m = int(n_depth[n])
        sums[n, :, :m] = acc[:, i, :m]
        alt[n, :m] = acc_alt[i, :m]
        clipped[n] = count[i]


_SIG = (
    "void(float32[:, :, :, ::1], int64[::1], float64[::1], float64[::1], float64, float64, "
    "float64, float64, float64, float64, float64[:, :, ::1], float64[:, :, ::1], "
    "float64[:, ::1], int64[::1], int64, int64)"
)
PROFILE_KERNEL = Kernel(_profile_kernel, [_SIG])


def build_profiles(
    hu: np.ndarray,
    depth_mm: np.ndarray,
    n_depths: np.ndarray,
    ring_weights: np.ndarray,
    calibration: Calibration,
    *,
    blades: int,
    rpm: float,
    alt_weights: np.ndarray | None = None,
    rows: np.ndarray | None = None,
) -> ProfileBatch:
    """Profiles of ``N`` trajectories from their float32 ring samples.

    Parameters
    ----------
    hu : (N, D, R, A) float32 ring samples (row ``n`` valid up to ``n_depths[n]``).
    depth_mm : (N, D) tip depths, mm (uniform per row).
    n_depths : (N,) depths per row.
    ring_weights : (R,) quadrature weights of the force integral (sum 1).
    calibration, blades, rpm : as for :func:`build_profile`.
    alt_weights : (R,) weights of :attr:`ProfileBatch.hu_mean_alt` (default ``ring_weights``).
    rows : the rows to compute (default all); the others stay NaN.

    Returns
    -------
    ProfileBatch
        Row ``n`` equal (to rounding) to ``build_profile`` on that row's samples.
    """
    n, d_max, n_r, n_a = hu.shape
    w = np.asarray(ring_weights, dtype=np.float64)
    alt_w = w if alt_weights is None else np.asarray(alt_weights, dtype=np.float64)
    laws = [calibration.a0, *calibration.harmonics]
    sums = np.full((n, len(laws) + 2, d_max), np.nan)
    alt = np.full((n, d_max), np.nan)
    clipped = np.zeros(n, dtype=np.int64)
    todo = np.arange(n) if rows is None else np.asarray(rows, dtype=np.int64)
    nd = np.ascontiguousarray(n_depths, dtype=np.int64)
    if todo.size:
        gate_w = float(calibration.gate_width_hu)
        gate_lo = float(calibration.gate_hu) - 0.5 * gate_w
        lo, hi = (float(v) for v in calibration.c_prime_range)
        _, inv_step, coefs = law_tables(calibration)
        args: tuple[Any, ...] = (np.ascontiguousarray(hu, dtype=np.float32), nd, w / n_a)
        args += (alt_w / n_a, gate_lo, gate_w, lo, hi, float(AIR_HU), inv_step, coefs)
        args += (sums, alt, clipped)
        if PROFILE_KERNEL.ready():
            run_spans(PROFILE_KERNEL, row_spans(todo), *args)
        else:
            _profile_numpy(todo, *args)
    # layout of ``sums``: s_t, lip-mean HU, S0, then each harmonic's Sk
    return ProfileBatch(
        s0_n=sums[:, 2],
        sk_n=sums[:, 3:],
        s_t=sums[:, 0],
        hu_mean=sums[:, 1],
        hu_mean_alt=alt,
        n_clipped=clipped,
        n_samples=nd * (n_r * n_a),
    )
