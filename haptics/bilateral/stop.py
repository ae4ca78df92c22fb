"""The slave's automatic stop from force alone (docs/teleop.md, "The CT number from the slave's
force", step 5).

:class:`ForceStop` reads the estimator's whole-rotation estimate on a fully engaged lip:
``cortex_exit`` when the estimate, after :data:`IN_BONE_MM` in bone, falls below the exit level
(half-way from the gate's upper edge to the softest bone of the plan's CT along the whole path,
:attr:`~.prior.Prior.exit_hu`: a level, never a position, so the registration does not enter). The
same fires sooner from a fast average (:data:`FAST_FRACTION` of the window) when even at the
vibration's crest (the model's ``sum Bk`` at the current estimate) the force is below the exit
level's ``A0`` times the feed factor ``1 + Ke v`` (a fast feed crosses the lip's exit in less than
a window) **and** below :data:`~ctdrill.haptics.hands.BREAKTHROUGH_RATIO` of the peak force at rest
over the last :data:`~ctdrill.haptics.hands.BREAKTHROUGH_WINDOW_MM` times that factor (the
sessions' breakthrough rule, so that the stop does not come before the exit it catches). The feed
is the fast average's own: a front slowing down in bone (a push's impact decelerating) lowers its
force with its feed, and a drill plunging through an exit (~58 mm/s) raises it. With the window's
mean feed, 33 ms behind, the first read as an exit 2.1 mm into bone on the Philips head phantom
(``push:20``, force law 20 % low) and the second fired 0.33-0.36 mm past the exit (the canal's roof
lag 0.29-0.41 mm); with the fast feed alone, without the breakthrough ratio, ``push:15`` onto a
plan misregistered by 3 mm was stopped 0.056 mm before the exit. ``density_rise`` when the estimate
exceeds the plan's CT anywhere within :data:`~.prior.RISE_WINDOW_MM` by :data:`RISE_MARGIN_HU`.
"""

from __future__ import annotations

import math
from collections import deque

from ctdrill.haptics.bilateral.prior import Prior
from ctdrill.haptics.hands import BREAKTHROUGH_RATIO, BREAKTHROUGH_WINDOW_MM

#: The fast exit test averages over this fraction of the low-pass window.
FAST_FRACTION = 10
#: Depth in bone before an exit counts, mm.
IN_BONE_MM = 0.5
#: A density rise the plan does not expect: this much above its CT's maximum nearby, HU.
RISE_MARGIN_HU = 500.0


class ForceStop:
    """The force-based stop's state (module docstring).

    Parameters
    ----------
    prior : Prior
        The plan's CT along the path (its exit level and maximum nearby).
    exit_a0_n : float
        The model's ``A0`` at the exit level, at rest and unit gain, N.
    harmonics : list of (float, float)
        The vibration's power laws ``(b0, n)``.

    Attributes
    ----------
    bone_since_mm : float
        Where the estimate last rose above the exit level (NaN: not in bone), mm.
    reason : str or None
        ``cortex_exit`` or ``density_rise`` once fired.
    """

    def __init__(self, prior: Prior, exit_a0_n: float, harmonics: list[tuple[float, float]]):
        self.prior = prior
        self.exit_a0_n = exit_a0_n
        self.harmonics = harmonics
        self.bone_since_mm = math.nan
        self.reason: str | None = None
        self._peak: deque[tuple[float, float]] = deque()  # (depth, force at rest), falling

    def check(
        self,
        depth_mm: float,
        hu: float,
        log10_c: float,
        *,
        fast_force_n: float,
        feed_factor: float,
        log10_gain: float,
        prior_index: int,
        rest_n: float = math.inf,
    ) -> str | None:
        """One tick on a fully engaged lip: the front's depth (mm), the whole rotation's
        estimate (HU, ``log10 C'``), the fast average's force (N), its feed factor, the learnt
        gain, the plan's index at the depth (-1: off the plan) and the whole rotation's force
        at rest (N). Returns the reason once fired."""
        pk = self._peak
        while pk and pk[-1][1] <= rest_n:
            pk.pop()
        pk.append((depth_mm, rest_n))
        while pk[0][0] < depth_mm - BREAKTHROUGH_WINDOW_MM:
            pk.popleft()
        if hu >= self.prior.exit_hu:
            if math.isnan(self.bone_since_mm):
                self.bone_since_mm = depth_mm
        elif not math.isnan(self.bone_since_mm):
            if depth_mm - self.bone_since_mm >= IN_BONE_MM:
                self.reason = "cortex_exit"
                return self.reason
            self.bone_since_mm = math.nan
        if not math.isnan(self.bone_since_mm) and depth_mm - self.bone_since_mm >= IN_BONE_MM:
            # the fast test: even at the vibration's crest the force is below the exit level
            gain = 10.0**log10_gain
            vib = gain * sum(10.0 ** (b0 + n * log10_c) for b0, n in self.harmonics)
            crest = fast_force_n + vib
            if (
                crest < gain * self.exit_a0_n * feed_factor
                and crest < BREAKTHROUGH_RATIO * pk[0][1] * feed_factor
            ):
                self.reason = "cortex_exit"
                return self.reason
        k = prior_index
        if k >= 0 and hu > self.prior.window_max_hu[k] + RISE_MARGIN_HU:
            self.reason = "density_rise"
        return self.reason
