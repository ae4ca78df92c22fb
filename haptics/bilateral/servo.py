"""One robot's acceleration servo: pseudo-differentiated velocity, DOB and RFOB (Table 4).

The same observers as the master's force controller (:class:`ctdrill.haptics.plant.
ForceController`), with the acceleration reference given from outside (the bilateral law):
the DOB makes the stage an acceleration source, the RFOB estimates the external force with the
Coulomb friction model removed. Internally SI; encoder in mm.
"""

from __future__ import annotations

#: Below this speed the servos' friction model fades linearly to 0, m/s. The master's force
#: controller fades it below 0.1 mm/s (:data:`ctdrill.haptics.plant.FRICTION_VEL_M_S`); in the
#: bilateral loop that leaves a 1-4 um stick-slip cycle between the stages at rest (the model's
#: 1 N steps in at every slip and kicks the force loop). Fading it over 1 mm/s lets both stages
#: settle at the stop within 0.04 um RMS with ``|F_h + F_e|`` within 2.5 % (pushes 12-30 N);
#: the price is at slow feeds, where the friction is only partly removed from the force
#: estimates: the hand feels the cut 2 % off at 2 mm/s, 15 % at 0.4 mm/s (measured in
#: bench/bench_teleop.py). A 0.3 mm/s fade on a 30 rad/s low-passed velocity gives 2.6 % at
#: 0.4 mm/s and 0.2-0.5 um at the stop, but 7-10 % force error at the stop for 12-15 N pushes.
SERVO_FRICTION_VEL_M_S = 1e-3


class Servo:
    """Observers and the current command of one linear stage.

    Attributes
    ----------
    velocity_m_s : float
        Pseudo-differentiated velocity.
    external_n : float
        RFOB estimate of the external force along +depth, N.
    current_a : float
        Last current command, A.
    """

    def __init__(
        self,
        *,
        mass_kg: float,
        kt_n_per_a: float,
        coulomb_n: float,
        current_limit_a: float,
        g_dob: float,
        g_rfob: float,
        g_vel: float,
        dt_s: float,
        start_mm: float,
    ) -> None:
        self.mn = mass_kg
        self.kt = kt_n_per_a
        self.fc = coulomb_n
        self.i_max = current_limit_a
        self.gd = g_dob
        self.gr = g_rfob
        self.gv = g_vel
        self.dt = dt_s
        self._zv = start_mm * 1e-3
        self._yd = 0.0
        self._yr = 0.0
        self._d_hat = 0.0
        self.velocity_m_s = 0.0
        self.external_n = 0.0
        self.current_a = 0.0

    @property
    def position_m(self) -> float:
        """The observer's position (the pseudo-differentiator's state), m."""
        return self._zv

    def observe(self, encoder_mm: float) -> None:
        """Update velocity, disturbance and external force from this tick's encoder."""
        dt = self.dt
        v = self.gv * (encoder_mm * 1e-3 - self._zv)
        self._zv += v * dt
        ti = self.kt * self.current_a
        mn = self.mn
        self._yd += dt * self.gd * (ti + mn * self.gd * v - self._yd)
        self._d_hat = self._yd - mn * self.gd * v
        self._yr += dt * self.gr * (ti + mn * self.gr * v - self._yr)
        r = v / SERVO_FRICTION_VEL_M_S
        fric = self.fc * (-1.0 if r < -1.0 else (1.0 if r > 1.0 else r))
        self.external_n = -(self._yr - mn * self.gr * v) + fric
        self.velocity_m_s = v

    def command(self, accel_m_s2: float) -> float:
        """Current (A) realising ``accel_m_s2`` through the DOB, within the current limit."""
        i = (self.mn * accel_m_s2 + self._d_hat) / self.kt
        if i != i:  # NaN
            i = 0.0
        i = -self.i_max if i < -self.i_max else (self.i_max if i > self.i_max else i)
        self.current_a = i
        return i
