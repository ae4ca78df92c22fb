"""Interactive cutting along one axis: material removal and the yielding cut front (DESIGN 1.7-1.8).

The hole is the set of depths the drill has already reached: with ``front_mm`` the deepest drill
depth so far (``x_max``), nothing is cut while the master is at ``master_mm <= front_mm``.
Beyond the front, the master is coupled to the front by a stiff spring ``k`` (the penetration
``e = master_mm - front_mm`` is what the hand feels) and the material yields:

* at rest it holds up to ``S0``: while ``k e <= S0`` the front does not move;
* pushed harder, the front advances with ``v = (k e / S0 - 1) / Ke`` (Eq. 19's
  ``A0 (1 + Ke v)`` solved for ``v``), so a constant hand force ``F = k e`` gives the steady feed
  ``v = (F / S0 - 1) / Ke``;
* ``Ke = 0`` is rigid-plastic (the front moves at once so that the force is ``S0``), ``S0 = 0``
  is nothing to cut (the front follows the master);
* an advance never overshoots the equilibrium penetration ``S0 / k`` within a tick (explicit
  Euler with that clamp: stable at any step, exact for a constant penetration);
* the vibration terms are added while the front advances; the resistance is never negative
  (material resists, it never pushes the hand back beyond the spring it compresses) and
  retraction is free.

Everything here is a pure function of floats (no arrays, no allocation beyond the result) so the
device renderer can call it 10 000 times a second. Depth and positions in mm, force in N, feed in
mm/s, time in s. The default stiffness is the stiffness the paper states for its master
(Table 1: 11 N/mm; a 30 N push holds the hand 30 / 11 = 2.7 mm past a stopped drill) and the
damping the paper's velocity gain on the nominal master mass (Table 4):
``b = Mn Kv = 0.5 kg * 160 /s = 0.08 N s/mm``. (The position gain of Table 4 on that mass,
``Mn Kp = 3.2 N/mm``, was the coupling before; the stability and passivity of 11 N/mm on the
simulated master are analysed in docs/haptics-stability.md and
:mod:`ctdrill.haptics.stability`.)
"""

from __future__ import annotations

import math

from ctdrill.model.force import feed_at_factor_mm_s

#: Nominal master mass (paper, Table 4), kg: the one owner (the simulated master,
#: :mod:`ctdrill.haptics.plant`, is this mass).
MASTER_MASS_KG = 0.5
#: The master's position and velocity gains (paper, Table 4), 1/s^2 and 1/s.
MASTER_KP_PER_S2 = 6400.0
MASTER_KV_PER_S = 160.0
#: Coupling stiffness master-front: the paper's master (Table 1), N/mm.
DEFAULT_STIFFNESS_N_PER_MM = 11.0
#: Coupling damping master-front, ``Mn * Kv``, N s/mm.
DEFAULT_DAMPING_N_S_PER_MM = MASTER_MASS_KG * MASTER_KV_PER_S / 1000.0


def equilibrium_penetration_mm(
    s0_n: float, *, stiffness_n_per_mm: float = DEFAULT_STIFFNESS_N_PER_MM
) -> float:
    """Penetration at which the coupling force equals ``S0``: ``S0 / k``, mm (0 if ``S0 <= 0``)."""
    if s0_n <= 0.0:
        return 0.0
    return s0_n / stiffness_n_per_mm


def steady_feed_mm_s(force_n: float, s0_n: float, ke_per_mm_s: float) -> float:
    """Steady feed under a constant hand force: ``(F / S0 - 1) / Ke``, mm/s, 0 if ``F <= S0``.

    ``inf`` when the material cannot resist (``S0 <= 0`` with ``F > 0``, or ``Ke <= 0`` with
    ``F > S0``).
    """
    if force_n <= max(s0_n, 0.0):
        return 0.0
    if s0_n <= 0.0 or ke_per_mm_s <= 0.0:
        return math.inf
    return feed_at_factor_mm_s(force_n / s0_n, ke_per_mm_s)


def advance_front_mm(
    front_mm: float,
    master_mm: float,
    s0_n: float,
    ke_per_mm_s: float,
    dt_s: float,
    *,
    stiffness_n_per_mm: float = DEFAULT_STIFFNESS_N_PER_MM,
    limit_mm: float = math.inf,
) -> float:
    """The cut front after one step of ``dt_s`` with the master held at ``master_mm``.

    Parameters
    ----------
    front_mm : float
        Cut front (deepest drill depth so far, ``x_max``), mm.
    master_mm : float
        Master (hand) depth, mm.
    s0_n : float
        Cutting force at zero feed at the front, N (``<= 0``: nothing to cut).
    ke_per_mm_s : float
        Feed sensitivity ``Ke``, per (mm/s) (``<= 0``: rigid-plastic).
    dt_s : float
        Step, s (> 0).
    stiffness_n_per_mm : float
        Coupling stiffness ``k``, N/mm (> 0).
    limit_mm : float
        The front never passes this depth (the device's stop depth), mm.

    Returns
    -------
    float
        New front, mm: never behind ``front_mm``, never beyond ``max(front_mm, limit_mm)`` nor
        ``max(front_mm, master_mm)``.
    """
    return cut_step(
        front_mm,
        master_mm,
        s0_n,
        ke_per_mm_s,
        dt_s,
        stiffness_n_per_mm=stiffness_n_per_mm,
        limit_mm=limit_mm,
    )[0]


def cut_step(
    front_mm: float,
    master_mm: float,
    s0_n: float,
    ke_per_mm_s: float,
    dt_s: float,
    *,
    stiffness_n_per_mm: float = DEFAULT_STIFFNESS_N_PER_MM,
    limit_mm: float = math.inf,
) -> tuple[float, float]:
    """One tick of the yielding front and the coupling (spring) force it sustained.

    Returns ``(new_front_mm, coupling_n)``. While the front advances freely it moved at
    ``v = (k e / S0 - 1) / Ke`` under the penetration ``e`` at the start of the tick, so the
    force it sustained is ``k e = S0 (1 + Ke v)`` (this makes the steady cut exact at any step);
    when the advance was clamped (rigid-plastic, air, the equilibrium, or ``limit_mm``) the
    force is the spring's after the step. 0 inside the hole.
    """
    e_mm = master_mm - front_mm
    if e_mm <= 0.0 or front_mm >= limit_mm:
        return front_mm, (stiffness_n_per_mm * e_mm if e_mm > 0.0 else 0.0)
    e_star = equilibrium_penetration_mm(s0_n, stiffness_n_per_mm=stiffness_n_per_mm)
    if e_mm <= e_star:
        return front_mm, stiffness_n_per_mm * e_mm
    room_mm = e_mm - e_star
    free = False
    if s0_n <= 0.0 or ke_per_mm_s <= 0.0:
        step_mm = room_mm
    else:
        step_mm = feed_at_factor_mm_s(stiffness_n_per_mm * e_mm / s0_n, ke_per_mm_s) * dt_s
        free = step_mm < room_mm
        if not free:
            step_mm = room_mm
    new_front = front_mm + step_mm
    if new_front >= limit_mm:
        new_front, free = limit_mm, False
    if free:
        return new_front, stiffness_n_per_mm * e_mm
    e_after = master_mm - new_front
    return new_front, (stiffness_n_per_mm * e_after if e_after > 0.0 else 0.0)


def resistance_n(
    coupling_n: float,
    master_feed_mm_s: float,
    front_feed_mm_s: float,
    vibration_n: float,
    *,
    damping_n_s_per_mm: float = DEFAULT_DAMPING_N_S_PER_MM,
) -> float:
    """Force the material puts on the hand, against the advance, N (``>= 0``).

    ``coupling + b (v_master - v_front) + vibration`` while the master is beyond the front
    (``coupling_n > 0``, from :func:`cut_step`), else 0 (in the hole; retraction is free).
    Pass ``vibration_n = 0`` when the front is not advancing.
    """
    if coupling_n <= 0.0:
        return 0.0
    force = coupling_n + damping_n_s_per_mm * (master_feed_mm_s - front_feed_mm_s) + vibration_n
    return force if force > 0.0 else 0.0


def vibration_n(s1_n: float, s2_n: float, f1_hz: float, f2_hz: float, t_s: float) -> float:
    """Cutting vibration ``S1 sin(2 pi f1 t) + S2 sin(2 pi f2 t)``, N (Eq. 19)."""
    return s1_n * math.sin(2.0 * math.pi * f1_hz * t_s) + s2_n * math.sin(
        2.0 * math.pi * f2_hz * t_s
    )
