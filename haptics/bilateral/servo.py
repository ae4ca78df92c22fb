"""One robot's acceleration servo: pseudo-differentiated velocity, DOB and RFOB (Table 4).

The same observers as the master's force controller (:class:`ctdrill.haptics.plant.
ForceController`), with the acceleration reference given from outside (the bilateral law):
the DOB makes the stage an acceleration source, the RFOB estimates the external force with the
Coulomb friction model removed. Internally SI; encoder in mm.
"""

from __future__ import annotations

#: The servos' friction model is a Dahl state ``z`` in [-1, 1] (the model is ``Fc z``) that
#: follows the travel, ``dz = dx / x0 (1 - z sign(dx))``, and relaxes to 0 at rest with the time
#: constant :data:`SERVO_FRICTION_RELAX_S`. Travel, not speed, sets it: at a steady feed ``v``
#: it holds ``Fc v tau / (x0 + v tau)`` (91 % of the friction at 0.4 mm/s, 98 % at 2 mm/s),
#: where the former model, a linear fade below 1 mm/s, removed 40 % at 0.4 mm/s (the hand felt
#: the cut 14.6 % off there); at rest, where the friction is static and cannot be observed, it
#: goes to 0 as the fade did, so the stop's ``|F_h + F_e|`` stays small. The figures this gives
#: (the hand at 0.4 mm/s; force and tracking at the stop, pushes 12-30 N) are measured in
#: bench/bench_teleop.py and quoted in docs/benchmarks.md. Tried on the same runs: a longer
#: relaxation (0.2 s) or a shorter travel (1 um) brings the 0.4 mm/s figure closer but the
#: held model kicks a 1-2 um stick-slip cycle at the stop (goal 1 um); a longer travel
#: (3-5 um) leaves 4-6 % at 0.4 mm/s. Travel ``x0``, m.
SERVO_FRICTION_TRAVEL_M = 2e-6
#: Relaxation time of the friction model at rest, s (see :data:`SERVO_FRICTION_TRAVEL_M`).
SERVO_FRICTION_RELAX_S = 0.05


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
        self._fric_z = 0.0
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
        dx = v * dt
        z = self._fric_z
        z += dx / SERVO_FRICTION_TRAVEL_M * (1.0 - (z if dx > 0.0 else -z))
        z -= z * dt / SERVO_FRICTION_RELAX_S
        z = -1.0 if z < -1.0 else (1.0 if z > 1.0 else z)
        self._fric_z = z
        fric = self.fc * z
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
