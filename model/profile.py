"""Force profiles along a trajectory: the lip integral precomputed per depth (DESIGN.md 1.4).

``F(x, v, t) = S0(x) (1 + Ke v) + sum_k Sk(x) sin(2 pi fk t)`` with

``S0(x) = sum_r w_r mean_a g(HU) A0(C', v=0)``, ``Sk(x)`` likewise with ``Bk``, and
``s_t(x) = sum_r w_r mean_a g(HU)``, from the HU sampled on the cutting lip's rings.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from ctdrill.hu import AIR_HU
from ctdrill.model.calibration import Calibration, Harmonic, PowerLaw, harmonic_freqs_hz
from ctdrill.model.errors import ModelInputError
from ctdrill.model.force import (
    feed_factor,
    feed_factor_scalar,
    gate,
    phase_rad,
)

_LN10 = math.log(10.0)
#: Relative tolerance on the uniformity of a profile's depth step.
_STEP_RTOL = 1e-6


class ProfileInputError(ModelInputError):
    """Lip samples or depths passed to a profile builder are malformed."""


@dataclass(frozen=True, eq=False)
class Profile:
    """Per-depth force coefficients along one trajectory.

    Attributes
    ----------
    depth_mm : ndarray, shape (N,)
        Tip depth from the entry point, uniform step (N >= 2), mm.
    s0_n : ndarray, shape (N,)
        DC cutting force at zero feed, N.
    sk_n : ndarray, shape (K, N)
        Harmonic amplitudes, N.
    freqs_hz : ndarray, shape (K,)
        Harmonic frequencies, Hz.
    s_t : ndarray, shape (N,)
        Cut fraction of the lip, 0..1.
    hu_mean : ndarray, shape (N,)
        Lip-mean HU (same quadrature as the forces).
    ke_per_mm_s : float
        Feed sensitivity ``Ke``, per (mm/s).
    n_clipped, n_samples : int
        Samples the law extrapolated (cut and ``C'`` outside the range) and samples in all.
    calibration : str
        Name of the calibration set.
    """

    depth_mm: np.ndarray
    s0_n: np.ndarray
    sk_n: np.ndarray
    freqs_hz: np.ndarray
    s_t: np.ndarray
    hu_mean: np.ndarray
    ke_per_mm_s: float
    n_clipped: int
    n_samples: int
    calibration: str
    # Plain-Python copies for the O(1) per-tick evaluation in force_n.
    _d0: float = field(init=False, repr=False)
    _inv_step: float = field(init=False, repr=False)
    _last: int = field(init=False, repr=False)
    _s0: list[float] = field(init=False, repr=False)
    _sk: list[list[float]] = field(init=False, repr=False)
    _freqs: list[float] = field(init=False, repr=False)
    _periods: list[float] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        depth = np.asarray(self.depth_mm, dtype=np.float64)
        n = depth.shape[0]
        if depth.ndim != 1 or n < 2:
            raise ProfileInputError(f"profile depth_mm must be 1-D with >= 2 depths, got {n}")
        step = float(depth[1] - depth[0])
        if not (math.isfinite(step) and step > 0.0):
            raise ProfileInputError("profile depth_mm must increase with a finite step")
        for name in ("s0_n", "s_t", "hu_mean"):
            if np.shape(getattr(self, name)) != (n,):
                raise ProfileInputError(f"profile {name} must have shape ({n},)")
        k = len(np.asarray(self.freqs_hz))
        if np.shape(self.sk_n) != (k, n):
            raise ProfileInputError(f"profile sk_n must have shape ({k}, {n})")
        arrays = {
            "depth_mm": depth,
            "s0_n": np.asarray(self.s0_n, dtype=np.float64),
            "sk_n": np.asarray(self.sk_n, dtype=np.float64),
            "freqs_hz": np.asarray(self.freqs_hz, dtype=np.float64),
            "s_t": np.asarray(self.s_t, dtype=np.float64),
            "hu_mean": np.asarray(self.hu_mean, dtype=np.float64),
        }
        for name, arr in arrays.items():
            arr = arr.copy()
            arr.flags.writeable = False
            object.__setattr__(self, name, arr)
        set_ = object.__setattr__
        set_(self, "_d0", float(depth[0]))
        set_(self, "_inv_step", 1.0 / step)
        set_(self, "_last", n - 1)
        set_(self, "_s0", [float(v) for v in arrays["s0_n"]])
        set_(self, "_sk", [[float(v) for v in row] for row in arrays["sk_n"]])
        set_(self, "_freqs", [float(f) for f in arrays["freqs_hz"]])
        set_(self, "_periods", [1.0 / float(f) for f in arrays["freqs_hz"]])

    @property
    def step_mm(self) -> float:
        """Depth step, mm."""
        return 1.0 / self._inv_step

    def mean_force_n(self, feed_mm_s: float) -> np.ndarray:
        """``S0(x) (1 + Ke v)`` at every profile depth, N: the force without vibration at feed v."""
        return np.asarray(self.s0_n * feed_factor(feed_mm_s, ke_per_mm_s=self.ke_per_mm_s))


def check_depths(depth_mm: ArrayLike) -> np.ndarray:
    depth = np.asarray(depth_mm, dtype=np.float64)
    if depth.ndim != 1 or depth.shape[0] < 2:
        raise ProfileInputError(
            f"depth_mm must be a 1-D array of >= 2 depths, got shape {depth.shape}"
        )
    if not np.all(np.isfinite(depth)):
        raise ProfileInputError("depth_mm contains NaN or inf; pass finite depths (mm)")
    steps = np.diff(depth)
    step = (depth[-1] - depth[0]) / (depth.shape[0] - 1)
    if step <= 0.0 or np.max(np.abs(steps - step)) > _STEP_RTOL * max(step, abs(depth[-1])):
        raise ProfileInputError(
            "depth_mm must increase with a uniform step (force_n interpolates by index); "
            "resample the lip on a uniform depth grid"
        )
    return depth


def build_profile(
    lip_hu: ArrayLike,
    ring_weights: ArrayLike,
    depth_mm: ArrayLike,
    calibration: Calibration,
    *,
    blades: int,
    rpm: float,
) -> Profile:
    """Integrate the force law over the lip rings at every depth.

    Parameters
    ----------
    lip_hu : array_like, shape (D, R, A)
        HU at ring ``r``, angle ``a`` of the lip when the tip is at ``depth_mm[d]``.
    ring_weights : array_like, shape (R,) or (D, R)
        Quadrature weights of ``(1/R) integral dr``; non-negative, sum to 1. Per depth (D, R)
        for a drill following narrower ones (rings on the lip outside their holes): each
        depth's weights sum to the cut share of the lip, in (0, 1]; forces and ``s_t`` then
        count only the cut part, ``hu_mean`` is the mean HU over it.
    depth_mm : array_like, shape (D,)
        Tip depths, uniform step, mm.
    calibration : Calibration
    blades : int
        Cutting blades of the drill.
    rpm : float
        Drill speed, rev/min.

    Returns
    -------
    Profile
        ``n_clipped`` counts samples that are cut and whose ``C'`` was clipped.
    """
    hu = np.asarray(lip_hu)
    if hu.ndim != 3 or min(hu.shape) < 1:
        raise ProfileInputError(f"lip_hu must have shape (D, R, A), got {hu.shape}")
    depth = check_depths(depth_mm)
    if hu.shape[0] != depth.shape[0]:
        raise ProfileInputError(
            f"lip_hu has {hu.shape[0]} depths but depth_mm has {depth.shape[0]}; they must match"
        )
    w = np.asarray(ring_weights, dtype=np.float64)
    per_depth = w.ndim == 2
    if w.shape != (hu.shape[1],) and w.shape != hu.shape[:2]:
        raise ProfileInputError(
            f"ring_weights must have shape ({hu.shape[1]},) or {hu.shape[:2]} to match lip_hu "
            f"rings, got {w.shape}"
        )
    if not np.all(np.isfinite(w)) or np.any(w < 0.0):
        raise ProfileInputError("ring_weights must be finite and >= 0")
    if not per_depth and abs(float(w.sum()) - 1.0) > 1e-6:
        raise ProfileInputError("ring_weights must sum to 1")
    share = w.sum(axis=-1) if per_depth else None
    if share is not None and not (np.all(share > 0.0) and np.all(share <= 1.0 + 1e-9)):
        raise ProfileInputError(
            "per-depth ring_weights must sum to the cut share of the lip, in (0, 1], at each depth"
        )
    hu = hu.astype(np.float64, copy=False)
    if not np.all(np.isfinite(hu)):
        raise ProfileInputError(
            f"lip_hu contains NaN or inf; sample outside the volume as a finite HU ({AIR_HU:g})"
        )
    freqs = harmonic_freqs_hz(calibration, blades=blades, rpm=rpm)
    n_angles = hu.shape[2]

    ring_w = w / n_angles

    def lip_mean(values: np.ndarray) -> np.ndarray:
        """(D, R, A) -> (D,): weighted over rings, mean over angles."""
        if per_depth:
            return np.asarray(np.einsum("dr,dr->d", values.sum(axis=2), ring_w))
        return np.asarray(values.sum(axis=2) @ ring_w)

    # One pass per quantity with reused buffers (a trajectory is ~1e5-1e6 samples): the gate,
    # log10 of the clipped C', then each power law as exp(ln 10 (b0 + n log10 C')).
    g = gate(hu, calibration)
    lo, hi = calibration.c_prime_range
    log_cp = np.subtract(hu, AIR_HU)  # C'
    np.clip(log_cp, lo, hi, out=log_cp)
    np.log10(log_cp, out=log_cp)
    buf = np.empty_like(log_cp)
    laws: list[PowerLaw | Harmonic] = [calibration.a0, *calibration.harmonics]
    sums = []
    for law in laws:
        np.multiply(log_cp, law.n * _LN10, out=buf)
        buf += law.b0 * _LN10
        np.exp(buf, out=buf)
        buf *= g
        sums.append(lip_mean(buf))
    n_clipped = int(np.count_nonzero((g > 0.0) & ((hu < lo + AIR_HU) | (hu > hi + AIR_HU))))
    return Profile(
        depth_mm=depth,
        s0_n=sums[0],
        sk_n=np.array(sums[1:]).reshape(len(freqs), depth.shape[0]),
        freqs_hz=freqs,
        s_t=lip_mean(g),
        hu_mean=lip_mean(hu) if share is None else lip_mean(hu) / share,
        ke_per_mm_s=calibration.ke_per_mm_s,
        n_clipped=n_clipped,
        n_samples=int(hu.size),
        calibration=calibration.name,
    )


def force_n(profile: Profile, depth_mm: float, feed_mm_s: float, t_s: float) -> float:
    """Cutting force (N) at tip depth ``depth_mm``, feed ``feed_mm_s``, time ``t_s``. O(1).

    ``S0(x) (1 + Ke v) + sum_k Sk(x) sin(2 pi fk t)``, ``S0`` and ``Sk`` linear in depth between
    profile samples, 0 outside ``[depth_mm[0], depth_mm[-1]]``. ``v`` is clipped to
    ``[0, MAX_FEED_MM_S]`` (retraction cuts nothing new); a non-finite ``t`` drops the vibration.
    """
    pos = (depth_mm - profile._d0) * profile._inv_step
    if not 0.0 <= pos <= profile._last:  # also rejects NaN
        return 0.0
    i = int(pos)
    if i == profile._last:
        i -= 1
    frac = pos - i
    s0 = profile._s0
    out = (s0[i] + frac * (s0[i + 1] - s0[i])) * feed_factor_scalar(feed_mm_s, profile.ke_per_mm_s)
    if math.isfinite(t_s):
        for sk, f, period in zip(profile._sk, profile._freqs, profile._periods, strict=True):
            amp = sk[i] + frac * (sk[i + 1] - sk[i])
            out += amp * math.sin(2.0 * math.pi * f * math.fmod(t_s, period))
    return out


def force_series_n(
    profile: Profile, depth_mm: ArrayLike, feed_mm_s: ArrayLike, t_s: ArrayLike
) -> np.ndarray:
    """Vectorised :func:`force_n` over a time series.

    Parameters
    ----------
    depth_mm : array_like, shape (T,)
    feed_mm_s : array_like, shape (T,) or scalar
    t_s : array_like, shape (T,)

    Returns
    -------
    ndarray, shape (T,)
        Force, N; 0 where the depth is outside the profile or not finite.
    """
    x = np.asarray(depth_mm, dtype=np.float64)
    t = np.broadcast_to(np.asarray(t_s, dtype=np.float64), x.shape)
    feed = np.nan_to_num(np.asarray(feed_mm_s, dtype=np.float64), nan=0.0)
    s0 = np.interp(x, profile.depth_mm, profile.s0_n, left=0.0, right=0.0)
    out = s0 * feed_factor(feed, ke_per_mm_s=profile.ke_per_mm_s)
    finite_t = np.isfinite(t)
    t0 = np.where(finite_t, t, 0.0)
    for k in range(profile.freqs_hz.shape[0]):
        amp = np.interp(x, profile.depth_mm, profile.sk_n[k], left=0.0, right=0.0)
        vib = amp * np.sin(phase_rad(profile.freqs_hz[k : k + 1], t0)[0])
        out = out + np.where(finite_t, vib, 0.0)
    return np.where(np.isfinite(x), out, 0.0)
