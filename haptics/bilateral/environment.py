"""The slave's environment: the model's cutting force on a yielding cut front (DESIGN.md 1.7).

The drill on the slave meets the material through a contact of stiffness ``k`` (drill, chuck
and bone) and damping ``b``; the material yields as :func:`ctdrill.model.cutting.cut_step` says
(it holds up to ``S0``, gives way at ``v = (F / S0 - 1) / Ke`` beyond), where ``S0`` and the
vibration amplitudes ``Sk`` are the lip-integrated profile of the CT along the path
(:class:`ctdrill.model.profile.Profile`: Eq. 19-22 with ``s_t`` of Eq. 2-4, the vibration at
``order x blades x rpm / 60`` Hz), times ``1 + model_error``. Unilateral: the drill feels
nothing inside its hole (behind the front) and nothing where nothing is cut (``S0 = 0``:
the front follows the drill; at a bone's exit ``s_t`` falls to 0 with the lip).

When the drill is stopped (:meth:`CuttingEnvironment.stop`) the spindle halts, so the front no
longer yields, and the slave's brake holds it: a unilateral wall of :data:`BRAKE_N_PER_MM` at
the depth it stopped at.
"""

from __future__ import annotations

import math

from ctdrill.haptics.bilateral.params import EnvSpec
from ctdrill.model.cutting import cut_step, resistance_n
from ctdrill.model.profile import Profile

#: The slave's brake once stopped, N/mm (a unilateral wall at the stop).
BRAKE_N_PER_MM = 100.0
#: ... and its damping, N s/mm.
BRAKE_N_S_PER_MM = 0.5


class CuttingEnvironment:
    """The material the slave cuts along one path.

    Parameters
    ----------
    profile : Profile
        The true CT's force profile along the slave's axis.
    origin_mm : float
        The slave depth of the profile's depth 0, mm (the profile's depth ``d`` is the slave
        depth ``origin_mm + d``).
    spec : EnvSpec

    Attributes
    ----------
    front_mm : float
        The cut front (the deepest depth cut so far) in slave depth, mm.
    stop_mm : float
        Where the brake holds (inf: running).
    """

    def __init__(self, profile: Profile, origin_mm: float, spec: EnvSpec) -> None:
        gain = 1.0 + spec.model_error
        self._d0 = float(profile.depth_mm[0]) + origin_mm
        self._inv = 1.0 / profile.step_mm
        self._last = len(profile.depth_mm) - 1
        self._s0 = [gain * float(v) for v in profile.s0_n]
        self._sk = [[gain * float(v) for v in row] for row in profile.sk_n]
        self._hu = [float(v) for v in profile.hu_mean]
        self._w = [2.0 * math.pi * float(f) for f in profile.freqs_hz]
        self._periods = [1.0 / float(f) for f in profile.freqs_hz]
        phases = list(spec.vibration_phase_rad)
        self._phase = [phases[k] if k < len(phases) else 0.0 for k in range(len(self._w))]
        self.ke = profile.ke_per_mm_s
        self.k = spec.stiffness_n_per_mm
        self.b = spec.damping_n_s_per_mm
        self.front_mm = self._d0
        self.stop_mm = math.inf
        self.front_feed_mm_s = 0.0

    def _at(self, values: list[float], depth_mm: float) -> float:
        pos = (depth_mm - self._d0) * self._inv
        if not 0.0 <= pos <= self._last:
            return 0.0
        i = int(pos)
        if i == self._last:
            i -= 1
        frac = pos - i
        return values[i] + frac * (values[i + 1] - values[i])

    def s0_n(self, depth_mm: float) -> float:
        """True ``S0`` at slave depth ``depth_mm``, N."""
        return self._at(self._s0, depth_mm)

    def hu_mn(self, depth_mm: float) -> float:
        """The CT's lip-mean HU with the tip at slave depth ``depth_mm`` (the truth)."""
        return self._at(self._hu, depth_mm)

    def stop(self, at_mm: float) -> None:
        """Halt the spindle and brake the slave at ``at_mm`` (slave depth)."""
        if math.isinf(self.stop_mm):
            self.stop_mm = at_mm

    def force_n(self, slave_mm: float, slave_mm_s: float, t_s: float, dt_s: float) -> float:
        """One tick: advance the front; the force against the advance on the slave, N (>= 0)."""
        front = self.front_mm
        stopped = not math.isinf(self.stop_mm)
        s0 = self._at(self._s0, front)
        new_front, coupling = cut_step(
            front,
            slave_mm,
            s0,
            self.ke,
            dt_s,
            stiffness_n_per_mm=self.k,
            limit_mm=front if stopped else math.inf,
        )
        feed = (new_front - front) / dt_s
        vib = 0.0
        if feed > 0.0:
            pos = (front - self._d0) * self._inv
            if 0.0 <= pos <= self._last:
                for row, w, period, phase in zip(
                    self._sk, self._w, self._periods, self._phase, strict=True
                ):
                    vib += self._at(row, front) * math.sin(w * math.fmod(t_s, period) + phase)
        self.front_mm = new_front
        self.front_feed_mm_s = feed
        force = resistance_n(coupling, slave_mm_s, feed, vib, damping_n_s_per_mm=self.b)
        if stopped and slave_mm > self.stop_mm:
            brake = BRAKE_N_PER_MM * (slave_mm - self.stop_mm) + BRAKE_N_S_PER_MM * slave_mm_s
            if brake > 0.0:
                force += brake
        return force
