"""Exact profiles for layered material (HU varies only with depth along the drill axis).

The lip element at radius ``r`` sits at depth ``xi = x - l_t r / R``, so for such material the
lip integral ``(1/R) int_0^R f(HU(xi(r))) dr`` is the box filter
``(1/l_t) int_{x - l_t}^{x} f(HU(xi)) dxi``. With piecewise-constant layers it is a sum of
exact overlap lengths: no ring discretisation, no staircase. This is the reference that
:func:`ctdrill.model.profile.build_profile` converges to, and for one slab it is the paper's Eq.
2-4.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from ctdrill.hu import AIR_HU
from ctdrill.model.calibration import Calibration, harmonic_freqs_hz
from ctdrill.model.force import a0_n, bk_n, gate, out_of_range
from ctdrill.model.profile import Profile, ProfileInputError, check_depths


def layer_overlaps_mm(
    boundaries_mm: ArrayLike, depth_mm: ArrayLike, *, tip_length_mm: float
) -> np.ndarray:
    """Length of each layer inside the lip's depth window ``[x - l_t, x]``, mm.

    Parameters
    ----------
    boundaries_mm : array_like, shape (L + 1,)
        Increasing layer boundaries along the axis; layer ``i`` is ``[b_i, b_{i+1})``.
    depth_mm : array_like, shape (D,)
        Tip depths ``x``.
    tip_length_mm : float
        Lip length along the axis, ``l_t > 0``.

    Returns
    -------
    ndarray, shape (D, L + 2)
        Column 0: before ``b_0``; columns 1..L: the layers; column L + 1: after ``b_L``.
        Each row sums to ``l_t``.
    """
    b = np.asarray(boundaries_mm, dtype=np.float64)
    x = np.asarray(depth_mm, dtype=np.float64)[:, None]
    lt = float(tip_length_mm)
    edges = np.concatenate(([-np.inf], b, [np.inf]))
    lo = np.maximum(x - lt, edges[None, :-1])
    hi = np.minimum(x, edges[None, 1:])
    return np.asarray(np.clip(hi - lo, 0.0, None))


def layered_profile(
    boundaries_mm: ArrayLike,
    hu_layers: ArrayLike,
    depth_mm: ArrayLike,
    calibration: Calibration,
    *,
    tip_length_mm: float,
    blades: int,
    rpm: float,
    outside_hu: float = AIR_HU,
) -> Profile:
    """Exact profile for piecewise-constant layers along the axis.

    Parameters
    ----------
    boundaries_mm : array_like, shape (L + 1,)
        Strictly increasing depths (mm from the entry point) of the layer boundaries.
    hu_layers : array_like, shape (L,)
        HU of each layer.
    depth_mm : array_like, shape (D,)
        Tip depths, uniform step, mm.
    calibration : Calibration
    tip_length_mm : float
        Drill tip (lip) length along the axis, mm, >= 0 (0: a flat lip, the point value).
    blades, rpm
        Drill, for the harmonic frequencies.
    outside_hu : float
        HU before the first and after the last boundary (default air).

    Returns
    -------
    Profile
        ``n_samples`` counts (depth, layer) pairs the lip touches; ``n_clipped`` those that
        are cut with ``C'`` outside the calibration range.
    """
    b = np.asarray(boundaries_mm, dtype=np.float64)
    hu_l = np.asarray(hu_layers, dtype=np.float64)
    if b.ndim != 1 or b.shape[0] < 2 or not np.all(np.isfinite(b)) or np.any(np.diff(b) <= 0):
        raise ProfileInputError("boundaries_mm must be >= 2 finite, strictly increasing depths")
    if hu_l.shape != (b.shape[0] - 1,) or not np.all(np.isfinite(hu_l)):
        raise ProfileInputError(
            f"hu_layers must hold {b.shape[0] - 1} finite HU values, one per layer"
        )
    lt = float(tip_length_mm)
    if not np.isfinite(lt) or lt < 0.0:
        raise ProfileInputError(f"tip_length_mm must be finite and >= 0, got {tip_length_mm}")
    if not np.isfinite(outside_hu):
        raise ProfileInputError("outside_hu must be finite")
    depth = check_depths(depth_mm)
    freqs = harmonic_freqs_hz(calibration, blades=blades, rpm=rpm)

    hu_all = np.concatenate(([outside_hu], hu_l, [outside_hu]))  # (L + 2,)
    if lt > 0.0:
        frac = layer_overlaps_mm(b, depth, tip_length_mm=lt) / lt  # (D, L + 2)
    else:  # a flat lip: the whole edge sits at the tip depth, in layer [b_i, b_{i+1})
        frac = np.zeros((depth.shape[0], b.shape[0] + 1))
        frac[np.arange(depth.shape[0]), np.searchsorted(b, depth, side="right")] = 1.0
    g = gate(hu_all, calibration)
    s0 = frac @ (g * a0_n(hu_all, 0.0, calibration))
    sk = (frac @ (g[None, :] * bk_n(hu_all, calibration)).T).T
    touched = frac > 0.0
    return Profile(
        depth_mm=depth,
        s0_n=s0,
        sk_n=sk.reshape(len(freqs), depth.shape[0]),
        freqs_hz=freqs,
        s_t=frac @ g,
        hu_mean=frac @ hu_all,
        ke_per_mm_s=calibration.ke_per_mm_s,
        n_clipped=int(np.count_nonzero(touched & out_of_range(hu_all, calibration)[None, :])),
        n_samples=int(np.count_nonzero(touched)),
        calibration=calibration.name,
    )
