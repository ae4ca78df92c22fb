"""The device-side renderer: one call per 10 kHz control tick (reference for the firmware).

Per tick, from the encoder depth of the master and its velocity estimate:

1. watchdog: no accepted host frame for more than ``watchdog_s`` (50 ms, counted in ticks: the
   firmware's counter, ``firmware/fw_render.c``) while armed -> safe state;
2. finite checks on the inputs and on the force command (non-finite -> safe state);
3. the cutting law (:mod:`ctdrill.model.cutting`) on the uploaded table: the front (deepest drill
   depth) yields to the hand, never past the stop depth; vibration from the device clock while
   the front advances; once the front has reached the stop depth, a rigid wall (200 N/mm and
   0.4 N s/mm on top of the coupling) anchored where the master was at that moment, so the force
   stays continuous; the anchor then glides to the stop depth at 20 mm/s, carrying the hand back
   to the stopped drill, and follows the master back when it retreats faster (down to the stop
   depth itself), so a push up to the peak force holds the hand within
   :data:`WALL_HOLD_MM` of the drill;
4. the release damper: while the master moves back (``v < 0``) and the hand does not draw it
   back, ``RELEASE_DAMPING_N_S_PER_MM * v`` is added: a hand that lets go is not thrown back by
   the springs it compressed nor by the force controller still balancing the push it no longer
   makes; the damper takes that energy out and the master comes to rest at the surface it left
   (docs/haptics-stability.md, "Letting go"). Its gate is a switch with hysteresis on the
   device's reading of the hand (corrected for the observer's lag behind an acceleration,
   low-passed at :data:`RELEASE_FILTER_RAD_S`): on while it pulls less than
   :data:`RELEASE_PULL_N`, off once it has pulled more than
   :data:`RELEASE_OFF_PULL_N` for :data:`RELEASE_HOLD_TICKS` ticks in a row (past the dip and
   the bias the damper's own force makes in the reading: the gate is not driven by the force
   it sets, and a rounding cannot flip it short of a threshold's crossing). It may pull (a
   negative force, at most :data:`RELEASE_MAX_N`) on a master the hand does not draw back; a
   retraction is free (once the hand has pulled for :data:`RELEASE_HOLD_TICKS`);
5. force limits: 78 N peak, and an I^2t thermal model that limits the force to the
   continuous rating (20 N) once ``thermal_budget_n2_s`` of excess ``F^2 - Fc^2`` has
   accumulated, until it has cooled to half.

States: ``IDLE`` (zero force), ``CUTTING`` (armed), ``STOPPED`` (armed, the front reached the
stop depth), ``SAFE`` (zero force, the drill stopped: the front frozen). SAFE is latched: only
a successful ARM (or a power cycle) leaves it; DISARM, HELLO and a new table do not.
The drill depth is ``min(master, front)``: it never exceeds the stop depth whatever the hand does.

Force convention: ``force_cmd_n > 0`` opposes the advance (pushes the hand back along -depth);
it is negative only from the release damper (item 4), braking a master the hand does not draw
back.
Plain float arithmetic only: no arrays, no allocation per tick.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from ctdrill.haptics.plant import COULOMB_N, G_RFOB, MASS_KG
from ctdrill.haptics.protocol import DeviceState, Fault, NakReason, ProfileBegin
from ctdrill.haptics.tick import TICK_HZ
from ctdrill.model.cutting import (
    DEFAULT_DAMPING_N_S_PER_MM,
    DEFAULT_STIFFNESS_N_PER_MM,
    cut_step,
    resistance_n,
)

PEAK_FORCE_N = 78.0
CONTINUOUS_FORCE_N = 20.0
#: Excess ``F^2 - Fc^2`` integrated before the thermal limit engages: 1 s at the peak force.
THERMAL_BUDGET_N2_S = PEAK_FORCE_N**2 - CONTINUOUS_FORCE_N**2
WATCHDOG_S = 0.050
#: Stiffness of the wall rendered beyond the stop's anchor, N/mm (on top of the cut coupling):
#: with the coupling, 211 N/mm hold the peak force 0.37 mm past the stop
#: (docs/haptics-stability.md: stable with a 7.6x margin).
STOP_WALL_N_PER_MM = 200.0
#: The wall's own damping beyond its anchor, N s/mm (on top of the coupling's): it damps the
#: 178 Hz mode of the stiff wall (damping ratio 0.24, 0.05 without it).
STOP_WALL_DAMPING_N_S_PER_MM = 0.4
#: Speed at which the wall's anchor glides from where the master met it to the stop depth,
#: mm/s: the hand is carried back to the stopped drill (7.1 mm at the peak force in 0.35 s).
STOP_GLIDE_MM_S = 20.0
#: A push up to the peak force is held within this of the stopped drill, mm (once the anchor
#: has glided to the stop; the summary names the force limit when the device could not).
WALL_HOLD_MM = 0.5
#: ARM is refused while the coupling would render more than this on arming, N.
ARM_MAX_FORCE_N = 5.0
#: The release damper, N s/mm: on a master moving back that the hand does not draw back
#: (docs/haptics-stability.md, "Letting go": it brakes a released handle within about a
#: millisecond, and keeps the loop's margins: 7.6x at the stop, 8.4x in damping alone).
RELEASE_DAMPING_N_S_PER_MM = 0.4
#: A hand pulling less than this is not drawing the handle back (the master's own friction), N;
#: the release damper fades out over the next as much of pull (none from twice this).
RELEASE_PULL_N = COULOMB_N
#: The force the release damper leaves pulls at most this, N (the continuous rating; so
#: bounded it never reaches the peak force, docs/haptics-stability.md, "Letting go").
RELEASE_MAX_N = CONTINUOUS_FORCE_N
#: The hand reading that gates the release damper is low-passed at this, rad/s (the reaction
#: force observer's own bandwidth: its transient after a release dips a few newtons below 0).
RELEASE_FILTER_RAD_S = G_RFOB
#: The release damper switches off once the hand reading has pulled more than this, N, for
#: :data:`RELEASE_HOLD_TICKS` ticks in a row (twice :data:`RELEASE_PULL_N`).
RELEASE_OFF_PULL_N = 2.0 * RELEASE_PULL_N
#: ... and the ticks in a row (8 ms): longer than the dip a step of the damper's own force
#: makes in the reading (the observer reads a step of the motor's force as a pull for a few
#: milliseconds: a 40 N step keeps the filtered reading past 2 N of pull for about 6 ms).
RELEASE_HOLD_TICKS = 80


class Renderer:
    """Device renderer state and its per-tick update.

    Attributes (read after each :meth:`tick`)
    ------------------------------------------
    state : int
        A :class:`DeviceState`.
    faults : int
        :class:`Fault` bits raised since the last ARM (sticky).
    front_mm, drill_mm : float
        Cut front (deepest drill depth so far) and drill depth, mm.
    force_cmd_n : float
        Force command of the last tick, N (> 0 opposes the advance; < 0 only from the release
        damper).
    hand_n : float
        The device's reading of the hand (the observer's lag behind an acceleration added
        back) low-passed at :data:`RELEASE_FILTER_RAD_S`, N (> 0 pushes): what gates the
        release damper.
    """

    def __init__(
        self,
        *,
        tick_hz: int = TICK_HZ,
        peak_force_n: float = PEAK_FORCE_N,
        continuous_force_n: float = CONTINUOUS_FORCE_N,
        thermal_budget_n2_s: float = THERMAL_BUDGET_N2_S,
        watchdog_s: float = WATCHDOG_S,
        stiffness_n_per_mm: float = DEFAULT_STIFFNESS_N_PER_MM,
        damping_n_s_per_mm: float = DEFAULT_DAMPING_N_S_PER_MM,
        stop_wall_n_per_mm: float = STOP_WALL_N_PER_MM,
        stop_wall_damping_n_s_per_mm: float = STOP_WALL_DAMPING_N_S_PER_MM,
        stop_glide_mm_s: float = STOP_GLIDE_MM_S,
        release_damping_n_s_per_mm: float = RELEASE_DAMPING_N_S_PER_MM,
    ) -> None:
        self.dt_s = 1.0 / tick_hz
        self.peak_force_n = peak_force_n
        self.continuous_force_n = continuous_force_n
        self.thermal_budget_n2_s = thermal_budget_n2_s
        self.watchdog_s = watchdog_s
        self._tick_hz = tick_hz
        self.k = stiffness_n_per_mm
        self.b = damping_n_s_per_mm
        self.k_stop = stop_wall_n_per_mm
        self.b_stop = stop_wall_damping_n_s_per_mm
        self.glide_mm = stop_glide_mm_s * self.dt_s
        self.b_release = release_damping_n_s_per_mm
        self._hand_gain = min(1.0, RELEASE_FILTER_RAD_S * self.dt_s)
        # The reaction force observer reads a steady acceleration ``a`` of the master as a push
        # of ``-G_RFOB T Mn a`` (its forward-Euler step lags a tick): the damper braking a free
        # master at 20 N read as a 2.4 N pull. The reading that gates it adds that back, from
        # the change of the velocity estimate, N per mm/s^2.
        self._lag_n_per_mm_s2 = G_RFOB * self.dt_s * MASS_KG * 1e-3
        self._last_v_mm_s = 0.0
        self.hand_n = 0.0
        #: The release damper's gate (see :meth:`release_gain`) and the ticks the hand reading
        #: has pulled more than :data:`RELEASE_OFF_PULL_N` in a row (up to the hold).
        self.release_on = True
        self.pull_ticks = 0
        self.state = int(DeviceState.IDLE)
        self.faults = 0
        self.new_faults = 0
        self.front_mm = 0.0
        self.drill_mm = 0.0
        self.force_cmd_n = 0.0
        self.thermal_n2_s = 0.0
        self.thermal_limited = False
        self.last_host_s = 0.0
        self.t_arm_s = 0.0
        self.safe_since_s = math.nan
        self._s0: list[float] = []
        self._s1: list[float] = []
        self._s2: list[float] = []
        self._inv_step = 0.0
        self._last = -1
        self.ke = 0.0
        self.w1 = 0.0
        self.w2 = 0.0
        self.stop_depth_mm = 0.0
        self.stop_anchor_mm = math.inf
        #: The coupling's force when the hand met the wall short of the stop, N (0: not on it).
        self.contact_n = 0.0

    # ------------------------------------------------------------ commands

    @property
    def watchdog_ticks(self) -> float:
        """The watchdog counts ticks, as the firmware does: it trips past this many without an
        accepted host frame (``watchdog_s`` in ticks; inf: never)."""
        ticks = self.watchdog_s * self._tick_hz
        return float(round(ticks)) if math.isfinite(ticks) else ticks

    @property
    def has_profile(self) -> bool:
        """A table has been loaded."""
        return self._last >= 0

    def load(self, begin: ProfileBegin, rows: Sequence[tuple[float, float, float]]) -> None:
        """Install a verified table (finite, ``s0 >= 0``); disarms and resets the hole."""
        self._s0 = [r[0] for r in rows]
        self._s1 = [r[1] for r in rows]
        self._s2 = [r[2] for r in rows]
        self._inv_step = 1.0 / begin.depth_step_mm
        self._last = len(rows) - 1
        self.ke = begin.ke_per_mm_s
        self.w1 = 2.0 * math.pi * begin.f1_hz
        self.w2 = 2.0 * math.pi * begin.f2_hz
        self.stop_depth_mm = begin.stop_depth_mm
        self.stop_anchor_mm = math.inf
        self.front_mm = 0.0
        self.disarm()

    def clear(self) -> None:
        """Forget the table (power-on state)."""
        self._s0, self._s1, self._s2 = [], [], []
        self._last = -1
        self.front_mm = 0.0
        self.disarm()

    def arm(self, now_s: float, master_mm: float) -> NakReason | None:
        """Start rendering (clears latched faults); the reason if refused.

        Refused without a table (``NOT_READY``) and while the master is so far beyond the cut
        front that arming would step the force above :data:`ARM_MAX_FORCE_N`
        (``NOT_RETRACTED``: retract the handle first; no force step on arming).
        """
        if not self.has_profile:
            return NakReason.NOT_READY
        if not math.isfinite(master_mm) or self.k * (master_mm - self.front_mm) > ARM_MAX_FORCE_N:
            return NakReason.NOT_RETRACTED
        self.state = int(
            DeviceState.STOPPED if self.front_mm >= self.stop_depth_mm else DeviceState.CUTTING
        )
        self.faults = 0
        self.new_faults = 0
        self.hand_n = 0.0
        self.release_on = True
        self.pull_ticks = 0
        self.last_host_s = now_s
        self.t_arm_s = now_s
        self.safe_since_s = math.nan
        return None

    def disarm(self) -> None:
        """Zero force; idle unless the safe state is latched (it stays safe until ARM)."""
        if self.state != DeviceState.SAFE:
            self.state = int(DeviceState.IDLE)
        self.force_cmd_n = 0.0

    def host_frame(self, now_s: float) -> None:
        """An accepted host frame arrived (decoded, host type, this session, fresh seq): feed
        the watchdog."""
        self.last_host_s = now_s

    def host_stop(self, now_s: float) -> None:
        """Emergency stop from the host: latched safe state."""
        self._go_safe(now_s, Fault.HOST_STOP)

    def _raise(self, fault: int) -> None:
        if not self.faults & fault:
            self.new_faults |= fault
        self.faults |= fault

    def _go_safe(self, now_s: float, fault: int) -> None:
        self._raise(fault)
        if self.state != DeviceState.SAFE:
            self.safe_since_s = now_s
        self.state = int(DeviceState.SAFE)
        self.force_cmd_n = 0.0

    # ------------------------------------------------------------ the tick

    def coefficients(self, depth_mm: float) -> tuple[float, float, float]:
        """``(S0, S1, S2)`` at ``depth_mm``, linear between rows, 0 outside the table."""
        pos = depth_mm * self._inv_step
        if not 0.0 <= pos <= self._last:
            return 0.0, 0.0, 0.0
        i = int(pos)
        if i >= self._last:
            return self._s0[self._last], self._s1[self._last], self._s2[self._last]
        frac = pos - i
        s0, s1, s2 = self._s0, self._s1, self._s2
        return (
            s0[i] + frac * (s0[i + 1] - s0[i]),
            s1[i] + frac * (s1[i + 1] - s1[i]),
            s2[i] + frac * (s2[i + 1] - s2[i]),
        )

    def release_gain(self) -> float:
        """How much of the release damper acts: 1 (on) or 0 (off, the hand draws the handle
        back), the gate :meth:`_gate` keeps from the hand reading :attr:`hand_n`."""
        return 1.0 if self.release_on else 0.0

    def _gate(self) -> None:
        """The release damper's switch, once a tick from :attr:`hand_n`: on while the hand
        pulls less than :data:`RELEASE_PULL_N`; off after :data:`RELEASE_HOLD_TICKS` ticks in
        a row of more than :data:`RELEASE_OFF_PULL_N`; between the two it keeps its state
        (hysteresis)."""
        hand = self.hand_n
        if hand > -RELEASE_PULL_N:
            self.release_on = True
            self.pull_ticks = 0
        elif hand < -RELEASE_OFF_PULL_N:
            if self.pull_ticks < RELEASE_HOLD_TICKS:
                self.pull_ticks += 1
            if self.pull_ticks >= RELEASE_HOLD_TICKS:
                self.release_on = False
        else:
            self.pull_ticks = 0

    def tick(
        self, now_s: float, master_mm: float, master_v_mm_s: float, hand_n: float = 0.0
    ) -> float:
        """One control tick at device time ``now_s``; returns the force command, N.

        ``hand_n`` is the device's reading of the hand (the force controller's reaction force
        observer, N, > 0 pushing; 0: no hand); it gates the release damper.
        """
        if math.isfinite(hand_n) and math.isfinite(master_v_mm_s):  # else: ends below
            # the observer's lag behind an acceleration added back (see __init__)
            accel = (master_v_mm_s - self._last_v_mm_s) * self._tick_hz
            reading = hand_n + self._lag_n_per_mm_s2 * accel
            self.hand_n += self._hand_gain * (reading - self.hand_n)
            self._last_v_mm_s = master_v_mm_s
        self._gate()
        state = self.state
        if state == DeviceState.IDLE or state == DeviceState.SAFE:
            self.force_cmd_n = 0.0
            cooled = self.thermal_n2_s - self.continuous_force_n**2 * self.dt_s
            self.thermal_n2_s = cooled if cooled > 0.0 else 0.0
            if master_mm == master_mm:  # finite-or-inf, not NaN
                self.drill_mm = master_mm if master_mm < self.front_mm else self.front_mm
            return 0.0
        if round((now_s - self.last_host_s) * self._tick_hz) > self.watchdog_ticks:
            self._go_safe(now_s, Fault.WATCHDOG)
            return 0.0
        if not (
            math.isfinite(master_mm) and math.isfinite(master_v_mm_s) and math.isfinite(hand_n)
        ):
            self._go_safe(now_s, Fault.NONFINITE)
            return 0.0
        front = self.front_mm
        stop = self.stop_depth_mm
        anchor = self.stop_anchor_mm
        back_v = master_v_mm_s  # the master's motion away from what it presses on
        if anchor == math.inf and (front >= stop or master_mm >= stop):
            # the wall stands at the stop depth from the hand's first touch of it (continuous):
            # the hand never runs past the stop on the coupling's stretch
            anchor = master_mm if master_mm > stop else stop
        elif anchor != math.inf:
            # glides to the stop (the hand is carried to the drill), or follows a faster retreat
            glided = anchor - self.glide_mm
            if master_mm < glided:
                anchor = master_mm if master_mm > stop else stop
            elif anchor > stop:
                anchor = glided if glided > stop else stop
                back_v = master_v_mm_s + (self.stop_anchor_mm - anchor) / self.dt_s
        self.stop_anchor_mm = anchor
        spring = self.k_stop * (master_mm - anchor) if master_mm > anchor else 0.0
        s0, s1, s2 = self.coefficients(front)
        # short of the stop the front is driven by the whole force the hand meets (coupling and
        # wall): the drill cuts on to the stop behind a hand the wall holds
        drive_mm = master_mm
        if front < stop and spring > 0.0:
            if self.contact_n == 0.0:  # the hand meets the wall: the push it cut with
                self.contact_n = self.k * (master_mm - front)
            # the master held still, its friction hides up to 1 N of the push: the drill cuts
            # on with the push the hand met the wall with, or more, up to what the device renders
            push = self.k * (master_mm - front) + spring
            push = min(max(push, self.contact_n), self.peak_force_n)
            drive_mm = front + push / self.k
        else:
            self.contact_n = 0.0
        new_front, coupling = cut_step(
            front, drive_mm, s0, self.ke, self.dt_s, stiffness_n_per_mm=self.k, limit_mm=stop
        )
        if drive_mm != master_mm:  # the coupling's own share of the force
            coupling -= self.k * (drive_mm - master_mm)
        front_v = (new_front - front) / self.dt_s
        vib = 0.0
        if new_front > front:
            t = now_s - self.t_arm_s
            vib = s1 * math.sin(self.w1 * t) + s2 * math.sin(self.w2 * t)
        force = resistance_n(coupling, master_v_mm_s, front_v, vib, damping_n_s_per_mm=self.b)
        if spring > 0.0:
            # spring and damper, the damper within the spring's force: the wall starts from 0
            # on contact at any speed, and never pulls
            damper = self.b_stop * master_v_mm_s
            force += spring + (
                damper if -spring < damper < spring else math.copysign(spring, damper)
            )
        if back_v < 0.0:
            # the release damper: a master moving back that the hand does not draw back (on
            # the wall, relative to its gliding anchor: the glide carries the hand unbraked),
            # the force it leaves pulling at most the continuous rating
            force += self.b_release * self.release_gain() * back_v
            if force < -RELEASE_MAX_N:
                force = -RELEASE_MAX_N
        self.front_mm = new_front
        self.drill_mm = master_mm if master_mm < new_front else new_front
        self.state = int(DeviceState.STOPPED if new_front >= stop else DeviceState.CUTTING)
        if not math.isfinite(force):
            self._go_safe(now_s, Fault.NONFINITE)
            return 0.0
        if force > self.peak_force_n:
            force = self.peak_force_n
            self._raise(Fault.PEAK_LIMIT)
        fc = self.continuous_force_n
        if self.thermal_limited and force > fc:
            force = fc
            self._raise(Fault.THERMAL_LIMIT)
        # I^2t on the force actually delivered
        thermal = self.thermal_n2_s + (force * force - fc * fc) * self.dt_s
        self.thermal_n2_s = thermal if thermal > 0.0 else 0.0
        if self.thermal_n2_s >= self.thermal_budget_n2_s:
            self.thermal_limited = True
        elif self.thermal_n2_s < 0.5 * self.thermal_budget_n2_s:
            self.thermal_limited = False
        self.force_cmd_n = force
        return force
