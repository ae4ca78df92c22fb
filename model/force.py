"""The force law of DESIGN.md section 1 on CT numbers: pure functions on scalars and arrays.

``C' = HU + 1000``; ``A0 = 10**b0 C'**n (1 + Ke v)``; ``Bk = 10**b0k C'**nk``; every power law is
evaluated at ``C'`` clipped to the calibration's ``c_prime_range``; the gate
``g = clip((HU - (gate_hu - w/2)) / w, 0, 1)`` says what is cut. Nothing here returns NaN or
inf for any finite HU and any finite feed.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from ctdrill.hu import AIR_HU
from ctdrill.model.calibration import Calibration

#: Feed (mm/s) above which the feed factor ``1 + Ke v`` stops growing. The paper calibrated
#: 0.1-0.5 mm/s; implant drilling feeds stay below a few mm/s. The cap only keeps the law
#: finite and bounded for absurd feeds (a hand flick in the simulator, a corrupt file).
MAX_FEED_MM_S: float = 50.0


def feed_outside_model(feed_mm_s: float, calibration: Calibration) -> str | None:
    """Why ``feed_mm_s`` is beyond what the model knows, or None when it is not.

    Beyond the set's ``feed_range_mm_s`` Eq. 19 is extrapolated; beyond
    :data:`MAX_FEED_MM_S` the feed factor is held at the cap (it keeps the law bounded for the
    device), so the forces are those at the cap: both are stated, never silent.
    """
    v = float(feed_mm_s)
    notes = []
    rng = calibration.feed_range_mm_s
    if rng is not None and not rng[0] <= v <= rng[1]:
        notes.append(
            f"feed {v:g} mm/s lies outside the feeds calibration {calibration.name!r} was "
            f"measured at ({rng[0]:g}..{rng[1]:g} mm/s): Eq. 19 is extrapolated there"
        )
    if v > MAX_FEED_MM_S:
        ke = calibration.ke_per_mm_s
        ratio = (1.0 + ke * v) / (1.0 + ke * MAX_FEED_MM_S)
        notes.append(
            f"the feed factor 1 + Ke v is capped at {MAX_FEED_MM_S:g} mm/s (it keeps the force "
            f"law bounded on the device): forces are those at {MAX_FEED_MM_S:g} mm/s, Eq. 19 "
            f"at {v:g} mm/s gives {ratio:.3g} x the DC force"
        )
    return "; ".join(notes) if notes else None


def c_prime(hu: ArrayLike) -> np.ndarray:
    """``C' = HU - AIR_HU = HU + 1000`` (attenuation relative to air; DESIGN.md 1.1), float64."""
    return np.asarray(hu, dtype=np.float64) - AIR_HU


def c_prime_clipped(hu: ArrayLike, calibration: Calibration) -> np.ndarray:
    """``C'`` clipped to ``calibration.c_prime_range``, float64, same shape as ``hu``."""
    lo, hi = calibration.c_prime_range
    return np.clip(c_prime(hu), lo, hi)


def gate(hu: ArrayLike, calibration: Calibration) -> np.ndarray:
    """Cut fraction of material at ``hu``: 0 below the ramp, 1 above, linear across it.

    ``clip((HU - (gate_hu - gate_width_hu / 2)) / gate_width_hu, 0, 1)``, float64 in [0, 1].
    """
    w = calibration.gate_width_hu
    lo = calibration.gate_hu - 0.5 * w
    return np.clip((np.asarray(hu, dtype=np.float64) - lo) / w, 0.0, 1.0)


def out_of_range(hu: ArrayLike, calibration: Calibration) -> np.ndarray:
    """Bool mask of samples that are cut (gate > 0) and whose ``C'`` lies outside the range."""
    cp = c_prime(hu)
    lo, hi = calibration.c_prime_range
    return (gate(hu, calibration) > 0.0) & ((cp < lo) | (cp > hi))


def clip_count(hu: ArrayLike, calibration: Calibration) -> int:
    """Number of samples the law extrapolates: cut (gate > 0) and ``C'`` outside the range."""
    return int(np.count_nonzero(out_of_range(hu, calibration)))


def feed_factor(feed_mm_s: ArrayLike, *, ke_per_mm_s: float) -> np.ndarray:
    """``1 + Ke v`` with ``v`` clipped to ``[0, MAX_FEED_MM_S]``, float64.

    The one owner of the feed factor of Eq. 19 (:func:`feed_factor_scalar` is the same rule on
    one float, :func:`feed_at_factor_mm_s` its inverse). Retraction (``v < 0``) cuts nothing
    new, so it neither lowers nor raises the force: the factor is 1, never below (a negative
    factor would push the hand). A NaN feed counts as no feed.
    """
    v = np.clip(np.nan_to_num(np.asarray(feed_mm_s, dtype=np.float64), nan=0.0), 0.0, MAX_FEED_MM_S)
    return 1.0 + ke_per_mm_s * v


def feed_factor_scalar(feed_mm_s: float, ke_per_mm_s: float) -> float:
    """:func:`feed_factor` on one float, without NumPy (the O(1) per-tick path of ``force_n``)."""
    v = feed_mm_s if feed_mm_s > 0.0 else 0.0  # retraction and NaN: no feed
    if v > MAX_FEED_MM_S:
        v = MAX_FEED_MM_S
    return 1.0 + ke_per_mm_s * v


def feed_at_factor_mm_s(factor: float, ke_per_mm_s: float) -> float:
    """The feed ``v`` at which ``1 + Ke v`` equals ``factor``: ``(factor - 1) / Ke``, mm/s.

    The inverse of :func:`feed_factor_scalar` for ``factor`` in ``[1, 1 + Ke MAX_FEED_MM_S]``
    and ``Ke > 0``; the yielding cut front (:mod:`ctdrill.model.cutting`) asks it how fast the
    material gives way under ``factor = F / S0``. Beyond the cap it keeps the same line (the
    front's speed is not capped; its step is bounded by the spring instead).
    """
    return (factor - 1.0) / ke_per_mm_s


def power_law_n(c_prime_value: np.ndarray, b0: float, n: float) -> np.ndarray:
    """``10**b0 * C'**n`` evaluated as ``10**(b0 + n log10 C')`` (no overflow of ``10**b0``).

    ``c_prime_value`` must be > 0 (clip it first); float64, same shape.
    """
    return np.asarray(np.power(10.0, b0 + n * np.log10(c_prime_value)))


def a0_n(hu: ArrayLike, feed_mm_s: ArrayLike, calibration: Calibration) -> np.ndarray:
    """DC term ``A0 = 10**b0 C'**n (1 + Ke v)`` (N), ungated, broadcast over ``hu`` and feed."""
    cp = c_prime_clipped(hu, calibration)
    law = calibration.a0
    return power_law_n(cp, law.b0, law.n) * feed_factor(
        feed_mm_s, ke_per_mm_s=calibration.ke_per_mm_s
    )


def bk_n(hu: ArrayLike, calibration: Calibration) -> np.ndarray:
    """Harmonic amplitudes ``Bk = 10**b0k C'**nk`` (N), ungated, shape ``(K, *hu.shape)``."""
    cp = c_prime_clipped(hu, calibration)
    if not calibration.harmonics:
        return np.zeros((0, *cp.shape))
    return np.stack([power_law_n(cp, h.b0, h.n) for h in calibration.harmonics])


def phase_rad(freqs_hz: ArrayLike, t_s: ArrayLike) -> np.ndarray:
    """``2 pi f t`` reduced modulo one period of each frequency, shape ``(K, *t.shape)``.

    The reduction keeps ``sin`` finite and accurate for any finite time.
    """
    f = np.asarray(freqs_hz, dtype=np.float64).reshape(-1, *([1] * np.ndim(t_s)))
    t = np.asarray(t_s, dtype=np.float64)
    return 2.0 * np.pi * f * np.fmod(t, 1.0 / f)


def force_density_n(
    hu: ArrayLike,
    feed_mm_s: ArrayLike,
    t_s: ArrayLike,
    calibration: Calibration,
    *,
    freqs_hz: ArrayLike,
) -> np.ndarray:
    """Force per unit lip fraction of material at ``hu``: ``g (A0 + sum_k Bk sin(2 pi fk t))``.

    This is ``f(HU)`` of DESIGN.md 1.4 (N). ``freqs_hz`` (K,) comes from
    :func:`ctdrill.model.calibration.harmonic_freqs_hz`. Broadcasts ``hu``, feed and ``t``.
    """
    hu_b, feed_b, t_b = np.broadcast_arrays(
        np.asarray(hu, dtype=np.float64),
        np.asarray(feed_mm_s, dtype=np.float64),
        np.asarray(t_s, dtype=np.float64),
    )
    g = gate(hu_b, calibration)
    dc = a0_n(hu_b, feed_b, calibration)
    bk = bk_n(hu_b, calibration)
    f = np.asarray(freqs_hz, dtype=np.float64)
    if f.shape != (bk.shape[0],):
        raise ValueError(f"freqs_hz must have shape ({bk.shape[0]},), one per harmonic")
    out = dc
    if bk.shape[0]:
        out = dc + np.sum(bk * np.sin(phase_rad(f, t_b)), axis=0)
    return np.asarray(g * out)


def slab_force_n(
    depth_mm: ArrayLike,
    hu: float,
    feed_mm_s: ArrayLike,
    t_s: ArrayLike,
    calibration: Calibration,
    *,
    thickness_mm: float,
    tip_length_mm: float,
    freqs_hz: ArrayLike,
) -> np.ndarray:
    """The paper's Eq. 2-4 x Eq. 19 for a homogeneous slab of ``thickness_mm`` at ``hu``.

    ``s_t = x / l_t`` (contact), 1 (cutting), ``1 - (x - d) / l_t`` (penetrating), 0 outside
    ``[0, d + l_t]``; valid for ``d >= l_t``. The reference the lip integral must reproduce.
    """
    x = np.asarray(depth_mm, dtype=np.float64)
    d = float(thickness_mm)
    lt = float(tip_length_mm)
    if not 0.0 < lt <= d:
        raise ValueError(f"slab_force_n needs 0 < tip_length_mm <= thickness_mm, got {lt}, {d}")
    # Eq. 2 (x / l_t), Eq. 3 (1), Eq. 4 (1 - (x - d) / l_t): their minimum, clipped to [0, 1].
    s_t = np.clip(np.minimum(np.minimum(x / lt, 1.0), 1.0 - (x - d) / lt), 0.0, 1.0)
    return s_t * force_density_n(hu, feed_mm_s, t_s, calibration, freqs_hz=freqs_hz)
