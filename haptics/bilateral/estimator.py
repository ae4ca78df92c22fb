"""The CT number from the slave's force (Eq. 25 reconstructed) and the automatic stop on it.

Per tick of the slave's loop (:meth:`HuEstimator.update`):

1. **Low-pass**: the slave's environment force estimate (RFOB) and its feed are averaged over
   one period of the lowest vibration harmonic, ``60 / (blades rpm)`` s: every term of Eq. 19's
   vibration averages to exactly 0 over it (docs/model.md, "What the paper leaves open").
2. **Gate**: the estimate starts ``l_t`` mm after the force first rose above
   :data:`CONTACT_N` (Eq. 2's contact state: the lip is only partly engaged) and holds while
   the drill does not cut (feed below :data:`MIN_FEED_MM_S`: a resting drill's force is any
   value below ``S0``).
3. **Inverse of Eq. 20 with the adapted gain** (Eq. 25):
   ``log10 C' = (log10(F / (1 + Ke v)) - log10 gamma - b0) / n``, clipped to the set's range;
   below the gate's upper edge the gate ramp is inverted linearly (0 N: its lower edge).
4. **The force gain** ``log10 gamma``, learnt against the plan's CT as prior: once per
   profile step of new depth, where the plan's CT is uniform within :data:`PRIOR_WINDOW_MM`
   and the lip fully engaged, the residual ``z = log10(F / (1 + Ke v)) - b0 - n log10 C'_plan``
   is one vote; the gain is the median of the votes and of one vote for the model's own gain
   (``z = 0``). A Kalman filter on the same residual (the joint filter on gain and CT number
   marginalised over the CT number) was tried first: under a misregistration its first votes
   come from the wrong layer, it locks onto them and rejects the right ones after; the median
   follows the majority of the path, where plan and slave agree. The CT number reported is the
   force's own with this gain (the prior's weight on it is 0), so a misregistered plan cannot
   pull it except through the gain.
5. **Stop** (:attr:`HuEstimator.stop_reason`): ``cortex_exit`` when the estimate, after
   :data:`IN_BONE_MM` in bone, falls below the gate's upper edge (the lip leaves the bone);
   ``density_rise`` when it exceeds the plan's CT anywhere within :data:`PRIOR_WINDOW_MM` by
   :data:`RISE_MARGIN_HU`. Force and feed only for the first; the second asks the plan.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass

import numpy as np

from ctdrill.model.calibration import Calibration
from ctdrill.model.profile import Profile

#: The force above which the drill touches material, N.
CONTACT_N = 0.2
#: Below this feed the drill does not cut and the force says nothing of the material, mm/s.
MIN_FEED_MM_S = 0.05
#: The plan's CT must be uniform within this many HU ...
PRIOR_UNIFORM_HU = 100.0
#: ... over this far either side of the drill, mm, for the gain to learn there.
PRIOR_WINDOW_MM = 0.15
#: A density rise counts where the plan's CT shows none within this far either side, mm
#: (the registration error it tolerates).
RISE_WINDOW_MM = 3.0
#: Depth in bone before an exit counts, mm.
IN_BONE_MM = 0.5
#: The exit level: this fraction of the way from the gate's upper edge up to the softest bone
#: the plan's CT shows along the whole path.
EXIT_LEVEL_FRACTION = 0.5
#: A density rise the plan does not expect: this much above its CT's maximum nearby, HU.
RISE_MARGIN_HU = 500.0


@dataclass(frozen=True, eq=False)
class Prior:
    """The plan's CT along the path, as the slave's loop reads it (plain lists).

    Built by :func:`plan_prior`; ``origin_mm`` is the slave depth of the plan's depth 0.
    """

    origin_mm: float
    step_mm: float
    log10_c: list[float]
    usable: list[bool]
    window_max_hu: list[float]
    exit_hu: float


def _window(values: np.ndarray, half: int, pad: float) -> np.ndarray:
    padded = np.concatenate([np.full(half, pad), values, np.full(half, pad)])
    return np.lib.stride_tricks.sliding_window_view(padded, 2 * half + 1)


def plan_prior(profile: Profile, calibration: Calibration, origin_mm: float = 0.0) -> Prior:
    """The plan's profile as the estimator's prior: its CT number, where the gain may learn
    from it (uniform within :data:`PRIOR_WINDOW_MM`, lip fully engaged), its maximum within
    :data:`RISE_WINDOW_MM`, and the exit level (module docstring)."""
    hu = np.asarray(profile.hu_mean, dtype=np.float64)
    step = profile.step_mm
    w = max(1, round(PRIOR_WINDOW_MM / step))
    win = _window(hu, w, math.nan)
    usable = (np.nanmax(win, axis=1) - np.nanmin(win, axis=1) <= PRIOR_UNIFORM_HU) & (
        _window(np.asarray(profile.s_t), w, 0.0).min(axis=1) >= 0.999
    )
    hi = _window(hu, max(1, round(RISE_WINDOW_MM / step)), -math.inf).max(axis=1)
    gate_hi = calibration.gate_hu + 0.5 * calibration.gate_width_hu
    bone = hu[(np.asarray(profile.s_t) >= 0.999) & (hu >= gate_hi)]
    softest = float(bone.min()) if bone.size else gate_hi
    c = np.log10(np.maximum(hu + 1000.0, 1.0))
    return Prior(
        origin_mm=origin_mm + float(profile.depth_mm[0]),
        step_mm=step,
        log10_c=[float(v) for v in c],
        usable=[bool(v) for v in usable],
        window_max_hu=[float(v) for v in hi],
        exit_hu=gate_hi + EXIT_LEVEL_FRACTION * (softest - gate_hi),
    )


class HuEstimator:
    """Eq. 25 with an adapted force gain, and the force-based stop (module docstring).

    Parameters
    ----------
    calibration : Calibration
        The force law the estimator assumes.
    prior : Prior
        The plan's CT along the path.
    tip_length_mm : float
        The drill's lip length ``l_t``, mm.
    window_ticks : int
        Ticks in one period of the lowest harmonic.
    tick_s : float

    Attributes
    ----------
    hu : float
        The estimate, HU (NaN while gated before the first valid tick; then held).
    valid : bool
        This tick's estimate is new (not held).
    log10_gain : float
        The force gain's estimate.
    stop_reason : str or None
        ``cortex_exit`` or ``density_rise`` once the stop fired.
    force_lp_n, feed_lp_mm_s : float
        The low-passed force and feed.
    """

    def __init__(
        self,
        calibration: Calibration,
        prior: Prior,
        *,
        tip_length_mm: float,
        window_ticks: int,
        tick_s: float,
    ) -> None:
        self.b0 = calibration.a0.b0
        self.n = calibration.a0.n
        self.ke = calibration.ke_per_mm_s
        self.c_lo = math.log10(calibration.c_prime_range[0])
        self.c_hi = math.log10(calibration.c_prime_range[1])
        self.gate_lo = calibration.gate_hu - 0.5 * calibration.gate_width_hu
        self.gate_hi = calibration.gate_hu + 0.5 * calibration.gate_width_hu
        cp_hi = min(
            max(self.gate_hi + 1000.0, calibration.c_prime_range[0]), calibration.c_prime_range[1]
        )
        self.log10_a0_gate = self.b0 + self.n * math.log10(cp_hi)
        self.prior = prior
        self.tip = tip_length_mm
        self.n_win = max(1, window_ticks)
        self._f = [0.0] * self.n_win
        self._v = [0.0] * self.n_win
        self._i = 0
        self._fsum = 0.0
        self._vsum = 0.0
        self._z: list[float] = [0.0]  # the prior: the model's gain, one vote
        self.contact_mm = math.nan
        self.log10_gain = 0.0
        self._next_update_mm = -math.inf
        self.hu = math.nan
        self.valid = False
        self.bone_since_mm = math.nan
        self.stop_reason: str | None = None
        self.force_lp_n = 0.0
        self.feed_lp_mm_s = 0.0
        self.gain_updates = 0

    def _prior_index(self, depth_mm: float) -> int:
        pos = (depth_mm - self.prior.origin_mm) / self.prior.step_mm
        if not 0.0 <= pos < len(self.prior.log10_c) - 0.5:
            return -1
        return round(pos)

    def update(self, slave_mm: float, force_n: float, feed_mm_s: float) -> None:
        """One tick: the slave's depth, its environment force estimate (+ against the
        advance) and feed."""
        i = self._i
        self._fsum += force_n - self._f[i]
        self._vsum += feed_mm_s - self._v[i]
        self._f[i] = force_n
        self._v[i] = feed_mm_s
        i += 1
        if i == self.n_win:  # re-sum once a window: no drift of the running sums
            i = 0
            self._fsum = math.fsum(self._f)
            self._vsum = math.fsum(self._v)
        self._i = i
        f = self._fsum / self.n_win
        v = self._vsum / self.n_win
        self.force_lp_n = f
        self.feed_lp_mm_s = v
        self.valid = False
        if math.isnan(self.contact_mm):
            if f > CONTACT_N:
                self.contact_mm = slave_mm
            return
        if slave_mm < self.contact_mm + self.tip or v < MIN_FEED_MM_S or self.stop_reason:
            return
        factor = 1.0 + self.ke * (v if v < 50.0 else 50.0)
        y = math.log10(f / factor) if f > 0.0 else -math.inf
        self._adapt(slave_mm, y)
        y_gain = y - self.log10_gain
        if y_gain >= self.log10_a0_gate:
            c = (y_gain - self.b0) / self.n
            c = self.c_lo if c < self.c_lo else (self.c_hi if c > self.c_hi else c)
            hu = 10.0**c - 1000.0
        else:  # the gate ramp: the share of the gate's upper-edge force
            share = 10.0 ** (y_gain - self.log10_a0_gate) if y > -math.inf else 0.0
            hu = self.gate_lo + (self.gate_hi - self.gate_lo) * share
        self.hu = hu
        self.valid = True
        self._check_stop(slave_mm, hu)

    def _adapt(self, slave_mm: float, y: float) -> None:
        if slave_mm < self._next_update_mm or not math.isfinite(y):
            return
        k = self._prior_index(slave_mm)
        if k < 0 or not self.prior.usable[k]:
            return
        self._next_update_mm = slave_mm + self.prior.step_mm
        z = y - self.b0 - self.n * self.prior.log10_c[k]
        bisect.insort(self._z, z)
        m = len(self._z)
        mid = m // 2
        self.log10_gain = self._z[mid] if m % 2 else 0.5 * (self._z[mid - 1] + self._z[mid])
        self.gain_updates += 1

    def _check_stop(self, slave_mm: float, hu: float) -> None:
        if hu >= self.prior.exit_hu:
            if math.isnan(self.bone_since_mm):
                self.bone_since_mm = slave_mm
        elif not math.isnan(self.bone_since_mm):
            if slave_mm - self.bone_since_mm >= IN_BONE_MM:
                self.stop_reason = "cortex_exit"
                return
            self.bone_since_mm = math.nan
        k = self._prior_index(slave_mm)
        if k >= 0 and hu > self.prior.window_max_hu[k] + RISE_MARGIN_HU:
            self.stop_reason = "density_rise"
