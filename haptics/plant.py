"""The paper's master robot (Table 4) and its force controller, for the simulator and emulator.

:class:`MasterPlant` is the physics: a linear motor of mass 0.5 kg, thrust constant 33 N/A,
Coulomb friction 1.0 N, hard end stops, an encoder quantised to 0.1 um; the operator's hand
applies a force. :class:`ForceController` is what the device firmware runs around the renderer:
a pseudo-differentiator for velocity, a disturbance observer (DOB, 1000 rad/s) that makes the
motor an acceleration source, a reaction-force observer (RFOB, 1000 rad/s) that estimates the
hand's force, and force control ``a_ref = Kf (F_hand_est - F_cmd) / Mn`` with ``Kf = 1.2``, so
the hand balances the rendered force and otherwise drives an apparent mass ``Mn / Kf``.
(``Kv`` of Table 4 sets the cutting coupling's damping, Table 1's 11 N/mm its stiffness,
:mod:`ctdrill.model.cutting`; the loop's stability: :mod:`ctdrill.haptics.stability`.)

Internally SI (m, m/s, N); the interfaces are in mm and mm/s. Plain floats, no arrays.
"""

from __future__ import annotations

import math

from ctdrill.haptics.tick import TICK_S
from ctdrill.model.cutting import MASTER_MASS_KG

#: The master's mass, kg (Table 4; owned by :mod:`ctdrill.model.cutting`).
MASS_KG = MASTER_MASS_KG
KT_N_PER_A = 33.0
COULOMB_N = 1.0
ENCODER_M = 0.1e-6
KF = 1.2
G_DOB = 1000.0
G_RFOB = 1000.0
G_VEL = 1000.0
#: Motor current limit, A (the 78 N peak force plus the friction compensation).
CURRENT_LIMIT_A = 80.0 / KT_N_PER_A
TRAVEL_MM = (-20.0, 60.0)
#: Below this speed the friction model of the RFOB fades linearly to 0, m/s.
FRICTION_VEL_M_S = 0.1e-3


class MasterPlant:
    """Rigid linear stage with Coulomb friction and hard stops, integrated exactly over a tick.

    The motor current and the hand's force are held through the tick (zero-order hold), so a
    rigid mass moves exactly ``x + v dt + a dt^2 / 2``: the sampled loop then sees the energy a
    held spring force leaks per sample, as the hardware does (a semi-implicit Euler step would
    conserve it and hide the stability limit: docs/haptics-stability.md).

    Attributes
    ----------
    x_m, v_m_s : float
        Position (depth, +into the patient), m, and velocity, m/s.
    """

    def __init__(
        self,
        *,
        start_mm: float = 0.0,
        mass_kg: float = MASS_KG,
        kt_n_per_a: float = KT_N_PER_A,
        coulomb_n: float = COULOMB_N,
        travel_mm: tuple[float, float] = TRAVEL_MM,
    ) -> None:
        self.x_m = start_mm * 1e-3
        self.v_m_s = 0.0
        self.mass_kg = mass_kg
        self.kt = kt_n_per_a
        self.coulomb_n = coulomb_n
        self.lo_m = travel_mm[0] * 1e-3
        self.hi_m = travel_mm[1] * 1e-3
        self.at_end_stop = False

    @property
    def position_mm(self) -> float:
        """True position, mm."""
        return self.x_m * 1e3

    def encoder_mm(self) -> float:
        """Encoder reading quantised to 0.1 um, mm."""
        return round(self.x_m / ENCODER_M) * ENCODER_M * 1e3

    def step(self, current_a: float, hand_n: float, dt_s: float) -> None:
        """Advance ``dt_s`` with motor current ``current_a`` and the hand's force ``hand_n``."""
        drive = self.kt * current_a + hand_n
        v = self.v_m_s
        fc = self.coulomb_n
        if v == 0.0:
            if -fc <= drive <= fc:
                return  # stiction
            friction = fc if drive > 0.0 else -fc
        else:
            friction = fc if v > 0.0 else -fc
        accel = (drive - friction) / self.mass_kg
        v_new = v + accel * dt_s
        if v != 0.0 and (v_new > 0.0) != (v > 0.0):
            # the stage stops within the step (after -v / a); there it sticks unless the drive
            # beats the friction the other way, then it moves off for the rest of the step
            x_new = self.x_m - 0.5 * v * v / accel
            v_new = 0.0
            if abs(drive) > fc:
                rest_s = dt_s + v / accel
                accel = (drive - (fc if drive > 0.0 else -fc)) / self.mass_kg
                v_new = accel * rest_s
                x_new += 0.5 * accel * rest_s * rest_s
        else:
            x_new = self.x_m + v * dt_s + 0.5 * accel * dt_s * dt_s
        self.at_end_stop = False
        if x_new < self.lo_m:
            x_new, v_new, self.at_end_stop = self.lo_m, 0.0, True
        elif x_new > self.hi_m:
            x_new, v_new, self.at_end_stop = self.hi_m, 0.0, True
        self.x_m = x_new
        self.v_m_s = v_new


class ForceController:
    """Velocity estimate, DOB, RFOB and force control at one tick (Table 4 gains).

    Attributes
    ----------
    velocity_mm_s : float
        Pseudo-differentiated encoder velocity, mm/s.
    hand_est_n : float
        RFOB estimate of the hand's force along +depth, N.
    current_a : float
        Last current command, A.
    """

    def __init__(
        self,
        *,
        start_mm: float = 0.0,
        dt_s: float = TICK_S,
        mass_kg: float = MASS_KG,
        kt_n_per_a: float = KT_N_PER_A,
        kf: float = KF,
        g_dob: float = G_DOB,
        g_rfob: float = G_RFOB,
        g_vel: float = G_VEL,
        coulomb_n: float = COULOMB_N,
        current_limit_a: float = CURRENT_LIMIT_A,
    ) -> None:
        self.dt = dt_s
        self.mn = mass_kg
        self.kt = kt_n_per_a
        self.kf = kf
        self.gd = g_dob
        self.gr = g_rfob
        self.gv = g_vel
        self.fc = coulomb_n
        self.i_max = current_limit_a
        self._zv = start_mm * 1e-3
        self._yd = 0.0
        self._yr = 0.0
        self.velocity_mm_s = 0.0
        self.hand_est_n = 0.0
        self.current_a = 0.0

    def update(self, encoder_mm: float, force_cmd_n: float) -> float:
        """Current command (A) for this tick; ``force_cmd_n >= 0`` opposes the advance."""
        dt = self.dt
        x = encoder_mm * 1e-3
        v = self.gv * (x - self._zv)
        self._zv += v * dt
        ti = self.kt * self.current_a
        mn = self.mn
        # DOB: d = Kt i - M a (everything that is not the motor), low-passed at gd.
        self._yd += dt * self.gd * (ti + mn * self.gd * v - self._yd)
        d_hat = self._yd - mn * self.gd * v
        # RFOB: the hand's force, friction model removed (smooth sign below 0.5 mm/s).
        self._yr += dt * self.gr * (ti + mn * self.gr * v - self._yr)
        fric = self.fc * max(-1.0, min(1.0, v / FRICTION_VEL_M_S))
        hand = -(self._yr - mn * self.gr * v) + fric
        a_ref = self.kf * (hand - force_cmd_n) / mn
        i = (mn * a_ref + d_hat) / self.kt
        if not math.isfinite(i):
            i = 0.0
        i = max(-self.i_max, min(self.i_max, i))
        self.current_a = i
        self.velocity_mm_s = v * 1e3
        self.hand_est_n = hand
        return i

    def idle(self, encoder_mm: float) -> float:
        """Zero current, observers kept tracking (IDLE and SAFE states)."""
        dt = self.dt
        x = encoder_mm * 1e-3
        v = self.gv * (x - self._zv)
        self._zv += v * dt
        ti = self.kt * self.current_a
        self._yd += dt * self.gd * (ti + self.mn * self.gd * v - self._yd)
        self._yr += dt * self.gr * (ti + self.mn * self.gr * v - self._yr)
        fric = self.fc * max(-1.0, min(1.0, v / FRICTION_VEL_M_S))
        self.hand_est_n = -(self._yr - self.mn * self.gr * v) + fric
        self.velocity_mm_s = v * 1e3
        self.current_a = 0.0
        return 0.0
