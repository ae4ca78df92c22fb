"""Parameters of the teleoperation simulation: frozen values with the paper's defaults.

Table 4 gives the slave's nominal mass (1.2 kg), the thrust constant (33 N/A), the gains
``Kp, Kv, Kf = 6400, 160, 1.2`` and the DOB and RFOB gains (1000 rad/s), the encoder
(0.1 um). It gives no Coulomb friction nor current limit for the slave: the slave here takes
the master's measured friction (1.0 N) and a 150 N peak thrust (the cortical forces of the
literature set reach 50 N at fast feeds, Fig. 14's pine wood 5 N).
"""

from __future__ import annotations

from dataclasses import dataclass

from ctdrill.haptics.plant import COULOMB_N, G_DOB, G_RFOB, G_VEL, KF, KT_N_PER_A, MASS_KG
from ctdrill.model.cutting import MASTER_KP_PER_S2, MASTER_KV_PER_S

#: The slave's nominal mass (Table 4), kg.
SLAVE_MASS_KG = 1.2
#: The slave's peak thrust, N (not in the paper: see the module docstring).
SLAVE_PEAK_FORCE_N = 150.0
#: Contact stiffness of the drill on bone seen by the slave, N/mm (drill, chuck and bone
#: in series; the stability map spans 1-100 N/mm).
ENV_STIFFNESS_N_PER_MM = 100.0
#: Contact damping, N s/mm.
ENV_DAMPING_N_S_PER_MM = 0.05
#: A firm hand's damping, N s/m (the goals' "firm hand").
FIRM_GRIP_N_S_PER_M = 20.0
#: The hand's mass on the handle, kg.
HAND_MASS_KG = 0.3
#: A hand that follows an intended motion (``feed:V``) holds it with this stiffness, N/m.
HAND_FEED_STIFFNESS_N_PER_M = 2000.0


@dataclass(frozen=True)
class SlaveSpec:
    """The slave linear stage (Table 4 and the module docstring's assumptions)."""

    mass_kg: float = SLAVE_MASS_KG
    kt_n_per_a: float = KT_N_PER_A
    coulomb_n: float = COULOMB_N
    current_limit_a: float = SLAVE_PEAK_FORCE_N / KT_N_PER_A


@dataclass(frozen=True)
class Gains:
    """The acceleration-based four-channel controller (Table 4).

    ``a_d = Kp (x_s - x_m) + Kv (v_s - v_m)`` (differential mode, master units),
    ``a_c = Kf (F_h + beta F_e) / Mn`` (common mode), ``a_m = (a_c + a_d) / 2``,
    ``a_s = alpha (a_c - a_d) / 2``; every side is an acceleration source through its DOB.
    """

    kp_per_s2: float = MASTER_KP_PER_S2
    kv_per_s: float = MASTER_KV_PER_S
    kf: float = KF
    force_mass_kg: float = MASS_KG
    g_dob: float = G_DOB
    g_rfob: float = G_RFOB
    g_vel: float = G_VEL
    #: Position scale: the slave moves ``alpha`` mm per master mm.
    position_scale: float = 1.0
    #: Force scale: the hand feels ``beta`` N per N on the slave.
    force_scale: float = 1.0


@dataclass(frozen=True)
class ChannelSpec:
    """One-way link: every packet takes ``delay_ms`` plus a uniform jitter in
    ``[0, jitter_ms]``, is lost with probability ``loss`` (the receiver holds the last one),
    and never overtakes the one before it."""

    delay_ms: float = 0.0
    jitter_ms: float = 0.0
    loss: float = 0.0


@dataclass(frozen=True)
class HandSpec:
    """The operator's hand as an impedance on the handle.

    The hand applies ``push(t) + K (x_ref(t) - x_m) + B (v_ref(t) - v_m)`` and adds its mass
    to the handle's: ``push`` and the reference come from the operator (a push holds no
    reference, ``K = 0``; ``feed:V`` moves the reference at V with ``K`` =
    :data:`HAND_FEED_STIFFNESS_N_PER_M`).
    """

    mass_kg: float = HAND_MASS_KG
    damping_n_s_per_m: float = FIRM_GRIP_N_S_PER_M
    stiffness_n_per_m: float = 0.0


@dataclass(frozen=True)
class EnvSpec:
    """How the slave's environment reacts (beside the force law of the profile)."""

    stiffness_n_per_mm: float = ENV_STIFFNESS_N_PER_MM
    damping_n_s_per_mm: float = ENV_DAMPING_N_S_PER_MM
    #: The true force law is the model's times ``1 + model_error`` (the estimator assumes 1).
    model_error: float = 0.0
    #: Phase of each vibration harmonic at ``t = 0``, rad (a real drill's is random; Eq. 19
    #: has 0). Missing harmonics take 0.
    vibration_phase_rad: tuple[float, ...] = ()
