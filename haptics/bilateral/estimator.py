"""The CT number from the slave's force (Eq. 25 reconstructed) and the automatic stop on it.

Per tick of the slave's loop (:meth:`HuEstimator.update`):

1. **Low-pass**: the slave's environment force estimate (RFOB) is averaged over one period of
   the lowest vibration harmonic, ``60 / (blades rpm)`` s: every term of Eq. 19's vibration
   averages to exactly 0 over it (docs/model.md, "What the paper leaves open"). The feed is
   the cut front's mean feed over the same window (the front: the slave's depth, through the
   RFOB's own first-order lag so that depth and force agree in time, less its contact
   deflection ``F / k``), so ``F / (1 + Ke v)`` is exact for Eq. 20, linear in ``v``. This
   estimate learns the gain and drives the stops. The estimate reported reads a **fast front**
   (the front's feed over the last half rotation at least :data:`FAST_FEED_MM_S`) over the last
   half rotation instead, as the force's sum over the sum of the regressor
   ``s_t (1 + Ke v)`` of every tick (Eq. 2 from the contact, Eq. 20 with that tick's feed;
   exact for a uniform material whatever the engagement and the feed do within the window):
   its lag in depth is half the whole rotation's. The half rotation cancels the even
   harmonics exactly and leaves at most 0.64 of the first's amplitude, which a fast front's
   force (at least ``2.25 S0`` at 5 mm/s) carries as a few per cent (demodulating the first
   harmonic instead: docs/teleop.md).
2. **Contact state**: from the contact (the low-passed force above :data:`CONTACT_N`, placed
   where the **force at rest** ``F / (1 + Ke v)`` (the tick's feed) last was below
   :data:`FREE_N` or the force fell by :data:`FALLING_N` in a tick, and following the force at
   rest down until it first passes :data:`FREE_N`: as the plan's contact is defined; a push
   meets the surface at 30-80 mm/s, where ``1 + Ke v`` is up to 13.5 and the raw force passes
   1 N on a lip that has barely touched; dropped again if the low-passed force falls below
   :data:`RELEASE_N` before the lip is engaged; moved to where the force was last free if an
   impact follows there before a force at rest over :data:`IMPACT_N` met a quarter-engaged
   lip: a start or an approach that the RFOB reads as a force in free flight, not an impact's
   bounce) the lip engages as Eq. 2 says, ``s_t = (x - x_c) / l_t``; the estimate divides by
   it and waits while ``s_t < MIN_ENGAGED``; beyond ``l_t``, ``s_t = 1``. It holds while the
   drill does not cut (feed below :data:`MIN_FEED_MM_S`: a resting drill's force is any
   value below ``S0``).
3. **Inverse of Eq. 20 with the adapted gain** (Eq. 25):
   ``log10 C' = (log10(F / (s_t (1 + Ke v))) - log10 gamma - b0) / n``, clipped to the set's
   range; below the gate's upper edge the gate ramp is inverted linearly.
4. **The force gain** ``log10 gamma``, learnt against the plan's CT as prior, **registered by
   the contact**: the plan's CT is read at the slave's depth less
   :attr:`HuEstimator.registration_mm`, the slave's contact less the depth where the plan's
   force first exceeds :data:`CONTACT_N` (:attr:`Prior.contact_mm`), so a plan shifted against
   the CT the slave cuts is shifted back before the first layer's votes. Once per profile
   step of new depth, where the plan's CT is uniform within :data:`~.prior.PRIOR_WINDOW_MM`, the lip
   fully engaged and the cut steady (:data:`STEADY_FRACTION`), the residual
   ``z = log10(F / (1 + Ke v)) - b0 - n log10 C'_plan`` is one vote, unless it lies further
   than :data:`MAX_VOTE_LOG10` from the model's gain (the plan's CT then shows another layer
   than the one cut: a misregistration). The gain is the model's own (``z = 0``) until the
   first vote, then the median of the votes; it learns force laws off by up to a factor 1.5 (a
   Kalman filter instead locked onto the wrong layer: docs/teleop.md). Without the
   registration the first layer cut (the cortex) had no vote under a misregistration of 1 mm
   or more and kept the force law's error (231-276 HU RMS with the law 20 % off). The CT number
   reported is the force's own with this gain (the prior's weight on it is 0), so a
   misregistered plan cannot pull it except through the gain.
5. **Stop** (:attr:`HuEstimator.stop_reason`), on a fully engaged lip only: ``cortex_exit``
   and ``density_rise`` from the whole rotation's estimate and a fast average of the force
   (:mod:`~ctdrill.haptics.bilateral.stop`).
"""

from __future__ import annotations

import bisect
import math

from ctdrill.haptics.bilateral.params import ENV_STIFFNESS_N_PER_MM
from ctdrill.haptics.bilateral.prior import CONTACT_N, Prior
from ctdrill.haptics.bilateral.stop import FAST_FRACTION, ForceStop
from ctdrill.hu import AIR_HU
from ctdrill.model.calibration import Calibration
from ctdrill.model.force import feed_factor_scalar

#: The contact is placed where the force last was below this, N (the low-pass lags half a
#: window).
FREE_N = 1.0
#: A contact whose low-passed force falls below this before the lip is engaged was none (the
#: RFOB reading the start or an approach as a force, a bounce): it is dropped and found again
#: where the force last was below :data:`FREE_N`, N.
RELEASE_N = 0.5
#: The contact is placed where the force last was below :data:`FREE_N` or fell by more than
#: this in a tick, N: the RFOB's transient at the start of a motion (a few N, decaying over
#: milliseconds) is free flight, a cut's force does not fall that fast while it presses on.
FALLING_N = 0.02
#: Before the lip is engaged, a force this far above the force where it was last free, from
#: below it and beyond the contact, moves the contact there: the first was the transient
#: the low-pass took for a contact, this is an impact, N.
IMPACT_N = 2.0
#: Below this share of the lip engaged (Eq. 2) the force is too small to read, so the
#: estimate waits.
MIN_ENGAGED = 0.25
#: From this feed of the front over the last half rotation the estimate reads the half
#: rotation (its lag in depth half the whole rotation's); below it the whole rotation, whose
#: 17-20 ms lag is within 0.1 mm of front and whose mean is steadier where the force is small
#: against the vibration and the hand's stick-slip, mm/s.
FAST_FEED_MM_S = 5.0
#: The gain learns only while the fast average is within this fraction of the low-passed
#: force (a steady cut, not the bounce of an impact).
STEADY_FRACTION = 0.15
#: Below this feed the drill does not cut and the force says nothing of the material, mm/s.
MIN_FEED_MM_S = 0.05
#: A vote further than this from the model's gain (log10: a factor 1.5) is the plan's CT
#: disagreeing with the slave's (another layer: a misregistration), not the force law. (Gated
#: against the current gain instead, a run of wrong votes first locks the gain out of the
#: right ones.)
MAX_VOTE_LOG10 = math.log10(1.5)


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
        contact_stiffness_n_per_mm: float = ENV_STIFFNESS_N_PER_MM,
        rfob_gain_rad_s: float = math.inf,
    ) -> None:
        self.b0 = calibration.a0.b0
        self.n = calibration.a0.n
        self.ke = calibration.ke_per_mm_s
        self.c_lo = math.log10(calibration.c_prime_range[0])
        self.c_hi = math.log10(calibration.c_prime_range[1])
        self.gate_lo = calibration.gate_hu - 0.5 * calibration.gate_width_hu
        self.gate_hi = calibration.gate_hu + 0.5 * calibration.gate_width_hu
        cp_hi = min(
            max(self.gate_hi - AIR_HU, calibration.c_prime_range[0]), calibration.c_prime_range[1]
        )
        self.log10_a0_gate = self.b0 + self.n * math.log10(cp_hi)
        self.prior = prior
        self.tip = tip_length_mm
        self.n_win = max(1, window_ticks)
        self._f = [0.0] * self.n_win
        self._x = [0.0] * self.n_win
        self._i = 0
        self._fsum = 0.0
        self._ticks = 0
        self._window_s = self.n_win * tick_s
        self._z: list[float] = []  # the votes, sorted
        self.n_fast = max(1, self.n_win // FAST_FRACTION)
        self._fast = 0.0
        self._free_mm = math.nan
        self._rest_mm = math.nan  # where the force at rest, F / (1 + Ke v), was last free
        self._found = False  # the force at rest has passed FREE_N since the contact
        self._material = False  # a material's force at rest on an engaged lip since the contact
        self.k_contact = contact_stiffness_n_per_mm
        # a fast front's estimate (module docstring, step 1): the last half rotation
        self.n_half = max(1, self.n_win // 2)
        self._phi = [0.0] * self.n_win
        self._hf = 0.0  # sums over the half rotation: the force, the regressor
        self._hphi = 0.0
        self._last_front = math.nan
        # the slave's depth through the RFOB's own lag, so that depth and force agree in time
        self._a_rfob = min(1.0, rfob_gain_rad_s * tick_s)
        self._x_lag = math.nan
        self._last_force_n = math.inf
        self._free_n = math.inf
        cp_exit = min(
            max(prior.exit_hu - AIR_HU, calibration.c_prime_range[0]),
            calibration.c_prime_range[1],
        )
        self.force_stop = ForceStop(
            prior,
            10.0 ** (self.b0 + self.n * math.log10(cp_exit)),
            [(h.b0, h.n) for h in calibration.harmonics],
        )
        self.contact_mm = math.nan
        self.log10_gain = 0.0
        self._next_update_mm = -math.inf
        self.hu = math.nan
        self.hu_slow = math.nan
        self.hu_fast = math.nan
        self.tick_s = tick_s
        self.valid = False
        self.stop_reason: str | None = None
        self.force_lp_n = 0.0
        self.feed_lp_mm_s = 0.0
        self.gain_updates = 0
        self.votes_rejected = 0

    @property
    def registration_mm(self) -> float:
        """The plan's shift against the slave's CT, read from the contact: the slave's contact
        less the plan's (0 until the contact is found or where the plan shows none), mm."""
        shift = self.contact_mm - self.prior.contact_mm
        return shift if math.isfinite(shift) else 0.0

    def _prior_index(self, depth_mm: float) -> int:
        pos = (depth_mm - self.prior.origin_mm) / self.prior.step_mm
        if not 0.0 <= pos < len(self.prior.log10_c) - 0.5:
            return -1
        return round(pos)

    def update(self, slave_mm: float, force_n: float) -> None:
        """One tick: the slave's depth (mm) and its environment force estimate (N, + against
        the advance)."""
        i = self._i
        n_win = self.n_win
        h = (i - self.n_half) % n_win  # the sample leaving the half rotation
        j = (i - self.n_fast) % n_win
        last_force = self._last_force_n
        self._last_force_n = force_n
        x_lag = self._x_lag
        x_lag = slave_mm if x_lag != x_lag else x_lag + self._a_rfob * (slave_mm - x_lag)
        self._x_lag = x_lag
        front = x_lag - force_n / self.k_contact  # the cut front: less the deflection
        phi = self._regressor(front, self._last_front)
        rest_n = force_n / self._feed_factor_tick(front, self._last_front)  # the force at rest
        self._last_front = front
        self._fsum += force_n - self._f[i]
        self._fast += force_n - self._f[j]
        self._hf += force_n - self._f[h]
        self._hphi += phi - self._phi[h]
        self._f[i] = force_n
        self._phi[i] = phi
        oldest = self._x[i]
        front_half = self._x[h]
        front_fast = self._x[j]
        self._x[i] = front
        i += 1
        if i == n_win:
            i = 0
        self._i = i
        if i == 0:  # re-sum once a window: no drift of the running sums
            self._resum()
        self._ticks += 1
        f = self._fsum / n_win
        # the front's mean feed over the window (exact for Eq. 20, linear in the feed)
        v = (front - oldest) / self._window_s if self._ticks > n_win else 0.0
        self.force_lp_n = f
        self.feed_lp_mm_s = v
        self.valid = False
        depth = front
        no_contact = math.isnan(self.contact_mm)
        if no_contact or depth < self.contact_mm + self.tip:
            # free where the force is small or falls (an observer's transient decaying)
            if force_n <= FREE_N or force_n < last_force - FALLING_N:
                self._free_mm = depth
                self._free_n = force_n
                self._rest_mm = depth
            elif rest_n <= FREE_N:
                self._rest_mm = depth
            if no_contact:
                if f > CONTACT_N:
                    self.contact_mm = depth if math.isnan(self._rest_mm) else self._rest_mm
                    self._found = rest_n > FREE_N
                    self._material = False
                    self._rebuild_regressor()
                return
            if not self._found:
                if rest_n > FREE_N:
                    self._found = True  # the force at rest passed the contact's level
                elif depth > self.contact_mm:
                    # the force at rest is still free here: the material begins beyond
                    self.contact_mm = depth
                    self._rebuild_regressor()
            if rest_n > IMPACT_N and depth >= self.contact_mm + MIN_ENGAGED * self.tip:
                self._material = True  # cut material: a later rise is a bounce, not an impact
            if (
                force_n > self._free_n + IMPACT_N
                and self._free_n < IMPACT_N
                and self._free_mm > self.contact_mm
                and not self._material
            ):
                # an impact from a valley beyond the contact: the contact was a transient
                self.contact_mm = self._rest_mm
                self._rebuild_regressor()
        if self.stop_reason:
            return
        s_t = (depth - self.contact_mm) / self.tip  # Eq. 2, the contact state
        if s_t < 1.0 and f < RELEASE_N:  # the force let go before the lip engaged: no contact
            self.contact_mm = math.nan
            self._free_mm = depth
            self._rest_mm = depth
            return
        if s_t < MIN_ENGAGED:
            return
        slow = False
        if v >= MIN_FEED_MM_S and self._ticks > n_win:  # the whole rotation: gain and stops
            factor = feed_factor_scalar(v, self.ke)
            y = math.log10(f / (factor * min(s_t, 1.0))) if f > 0.0 else -math.inf
            fast = self._fast / self.n_fast
            if s_t >= 1.0 and abs(fast - f) <= STEADY_FRACTION * f:
                self._adapt(depth, y)
            hu_slow, c_slow = self._invert(y)
            self.hu_slow = hu_slow
            slow = True
            if s_t >= 1.0:  # the stops read a fully engaged lip only
                # the fast test's feed (stop.py): its own or the half rotation's, the slower
                v_fast = (front - front_fast) / (self.n_fast * self.tick_s)
                self.stop_reason = self.force_stop.check(
                    depth,
                    hu_slow,
                    c_slow,
                    fast_force_n=fast,
                    feed_factor=feed_factor_scalar(v_fast, self.ke),
                    log10_gain=self.log10_gain,
                    prior_index=self._prior_index(depth),
                    rest_n=f / factor,
                )
        # a fast front: the force over the regressor, each summed over the last half rotation
        v_half = (front - front_half) / (self.n_half * self.tick_s)
        if v_half >= FAST_FEED_MM_S and self._hphi > 0.0:
            num = self._hf
            y_q = math.log10(num / self._hphi) if num > 0.0 else -math.inf
            self.hu, _ = self._invert(y_q)
            self.hu_fast = self.hu
            self.valid = True
        elif slow:
            self.hu = self.hu_slow
            self.valid = True

    def _regressor(self, front_mm: float, previous_mm: float) -> float:
        """One tick's ``s_t (1 + Ke v)`` (Eq. 2 from the contact, Eq. 20's feed factor with this
        tick's feed): the force is the material's ``gamma 10^b0 C'^n`` times it."""
        if math.isnan(self.contact_mm) or math.isnan(previous_mm):
            return 0.0
        e = (front_mm - self.contact_mm) / self.tip
        if e <= 0.0:
            return 0.0
        v = (front_mm - previous_mm) / self.tick_s
        return (e if e < 1.0 else 1.0) * feed_factor_scalar(v, self.ke)

    def _feed_factor_tick(self, front_mm: float, previous_mm: float) -> float:
        """Eq. 20's ``1 + Ke v`` with this tick's feed of the front (0 when it retreats)."""
        if math.isnan(previous_mm):
            return 1.0
        return feed_factor_scalar((front_mm - previous_mm) / self.tick_s, self.ke)

    def _rebuild_regressor(self) -> None:
        """The regressor of the ring's samples once the contact is placed behind them."""
        n = self.n_win
        order = [(self._i + k) % n for k in range(n)]  # oldest first
        prev = math.nan
        for k in order:
            x = self._x[k]
            self._phi[k] = self._regressor(x, prev)
            prev = x
        self._resum()

    def _resum(self) -> None:
        n = self.n_win
        i = self._i % n
        half = [(i - 1 - k) % n for k in range(self.n_half)]
        fast = [(i - 1 - k) % n for k in range(self.n_fast)]
        self._fsum = math.fsum(self._f)
        self._fast = math.fsum(self._f[k] for k in fast)
        self._hf = math.fsum(self._f[k] for k in half)
        self._hphi = math.fsum(self._phi[k] for k in half)

    def _invert(self, y: float) -> tuple[float, float]:
        """Eq. 25 on ``y = log10(F / (s_t (1 + Ke v)))`` with the gain: the CT number and
        ``log10 C'`` (clipped; the gate's ramp below its upper edge)."""
        y_gain = y - self.log10_gain
        if y_gain >= self.log10_a0_gate:
            c = (y_gain - self.b0) / self.n
            c = self.c_lo if c < self.c_lo else (self.c_hi if c > self.c_hi else c)
            return 10.0**c + AIR_HU, c
        share = 10.0 ** (y_gain - self.log10_a0_gate) if y > -math.inf else 0.0
        return self.gate_lo + (self.gate_hi - self.gate_lo) * share, self.c_lo

    def _adapt(self, slave_mm: float, y: float) -> None:
        if slave_mm < self._next_update_mm or not math.isfinite(y):
            return
        k = self._prior_index(slave_mm - self.registration_mm)
        if k < 0 or not self.prior.usable[k]:
            return
        self._next_update_mm = slave_mm + self.prior.step_mm
        z = y - self.b0 - self.n * self.prior.log10_c[k]
        if abs(z) > MAX_VOTE_LOG10:
            self.votes_rejected += 1
            return
        bisect.insort(self._z, z)
        m = len(self._z)
        mid = m // 2
        self.log10_gain = self._z[mid] if m % 2 else 0.5 * (self._z[mid - 1] + self._z[mid])
        self.gain_updates += 1
