"""Stability and passivity of the coupled master (docs/haptics-stability.md).

The device loop of one 10 kHz tick (:mod:`ctdrill.haptics.emulator`): the renderer computes the
force from the encoder and the *previous* tick's velocity estimate, the force controller
(:class:`ctdrill.haptics.plant.ForceController`: pseudo-differentiator, DOB, RFOB, force control
``Kf``) turns it into a current, and the plant (:class:`ctdrill.haptics.plant.MasterPlant`)
integrates the motor and hand forces over the tick. Around an operating point where nothing
clips (force between 0 and the peak, current within its limit, the master sliding so that the
RFOB's friction model cancels the Coulomb friction) that tick is a linear map of the state

``s = [x, v, z_v, y_d, y_r, u, v_e, f]``  (m, m/s, m, N, N, N, m/s, m)

(plant position and velocity, the pseudo-differentiator's state, the DOB and RFOB filter states,
the last motor force ``u = Kt i``, the last velocity estimate, and the cut front when it yields).
:func:`closed_loop_matrix` builds that map from the same constants the simulator runs with; its
eigenvalues decide the stability of the sampled loop exactly (all inside the unit circle, apart
from the translation mode of a yielding front). :func:`linear_tick` is the same arithmetic on
plain numbers, so a test can check the matrix against the simulator tick for tick.

The rendered environment is ``F = K (x - x0) + B v_e`` (a fixed front: the material at rest, or
the stop where ``K`` is the coupling plus the stop wall) or, while the front yields, a spring
``k`` in series with the material's viscosity ``c = S0 Ke`` (the front moves at
``(k e / S0 - 1) / Ke``, so an increment of force ``k de`` moves it at ``k de / c``).
Everything here is SI inside, mm at the interface (N/mm, N s/mm).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ctdrill.haptics.plant import G_DOB, G_RFOB, G_VEL, KF, KT_N_PER_A, MASS_KG
from ctdrill.haptics.tick import TICK_S

#: State names of :func:`closed_loop_matrix`, in order.
STATE = ("x_m", "v_m_s", "zv_m", "yd_n", "yr_n", "u_n", "ve_m_s", "front_m")


@dataclass(frozen=True)
class Loop:
    """The linearised device loop at one operating point.

    Attributes
    ----------
    stiffness_n_per_mm : float
        Stiffness the renderer puts between master and front (coupling, plus the stop wall
        beyond its anchor), N/mm.
    damping_n_s_per_mm : float
        The renderer's damping on the (previous tick's) velocity estimate, N s/mm.
    material_damping_n_s_per_mm : float or None
        ``S0 Ke`` while the front yields (a Maxwell element: the spring in series with the
        material), N s/mm; None for a fixed front (at rest below ``S0``, or at the stop).
    hand_stiffness_n_per_mm, hand_damping_n_s_per_mm : float
        A hand holding the handle as a spring-damper (0 for a pure force, ``push:N``).
    dt_s : float
        Control period, s.
    zoh_plant : bool
        Integrate the plant exactly over the tick (a rigid mass under the force held constant
        through the tick: the hardware and :class:`MasterPlant`); False: semi-implicit Euler
        (what the simulator did before; it conserves a held spring's energy, docs).
    """

    stiffness_n_per_mm: float
    damping_n_s_per_mm: float
    material_damping_n_s_per_mm: float | None = None
    hand_stiffness_n_per_mm: float = 0.0
    hand_damping_n_s_per_mm: float = 0.0
    dt_s: float = TICK_S
    zoh_plant: bool = True
    mass_kg: float = MASS_KG
    kt_n_per_a: float = KT_N_PER_A
    kf: float = KF
    g_dob: float = G_DOB
    g_rfob: float = G_RFOB
    g_vel: float = G_VEL


def linear_tick(loop: Loop, s: list[Any], force_offset_n: Any = 0.0, hand_n: Any = 0.0) -> Any:
    """One tick of the linearised loop; returns ``(next_state, force_n)``.

    ``s`` holds the eight state values (floats, or NumPy coefficient vectors: the arithmetic
    is linear). ``force_offset_n`` is the constant part of the rendered force (``-K x0``, and
    ``+S0`` terms while cutting), ``hand_n`` the hand's constant force. Mirrors
    :meth:`ctdrill.haptics.renderer.Renderer.tick`, :meth:`ForceController.update` and
    :meth:`MasterPlant.step` without their clips and friction.
    """
    x, v, zv, yd, yr, u, ve, front = s
    dt = loop.dt_s
    k = loop.stiffness_n_per_mm * 1e3
    b = loop.damping_n_s_per_mm * 1e3
    # renderer: spring on the penetration, damper on the previous velocity estimate
    if loop.material_damping_n_s_per_mm is None:
        force = k * (x - front) + b * ve + force_offset_n
        new_front = front
    else:
        c = loop.material_damping_n_s_per_mm * 1e3
        v_front = k * (x - front) / c  # (k e / S0 - 1) / Ke, its constant part in the offset
        force = k * (x - front) + b * (ve - v_front) + force_offset_n
        new_front = front + dt * v_front
    # force controller (ForceController.update)
    mn = loop.mass_kg
    v_est = loop.g_vel * (x - zv)
    new_zv = zv + dt * v_est
    new_yd = yd + dt * loop.g_dob * (u + mn * loop.g_dob * v_est - yd)
    d_hat = new_yd - mn * loop.g_dob * v_est
    new_yr = yr + dt * loop.g_rfob * (u + mn * loop.g_rfob * v_est - yr)
    hand_est = -(new_yr - mn * loop.g_rfob * v_est)
    new_u = loop.kf * (hand_est - force) + d_hat  # Kt i = Mn a_ref + d_hat
    # hand and plant (MasterPlant.step)
    hand = hand_n - loop.hand_stiffness_n_per_mm * 1e3 * x - loop.hand_damping_n_s_per_mm * 1e3 * v
    accel = (new_u + hand) / loop.mass_kg
    new_v = v + dt * accel
    new_x = x + dt * v + 0.5 * dt * dt * accel if loop.zoh_plant else x + dt * new_v
    return [new_x, new_v, new_zv, new_yd, new_yr, new_u, v_est, new_front], force


def closed_loop_matrix(loop: Loop) -> np.ndarray:
    """The matrix ``A`` with ``s[n+1] = A s[n] + const`` (:data:`STATE` order): 8 x 8 while the
    front yields, 7 x 7 (no front) while it is fixed (then it is a constant input)."""
    basis = list(np.eye(len(STATE)))
    nxt, _ = linear_tick(loop, basis)
    full = np.array([np.asarray(row, dtype=float) for row in nxt])
    return full if loop.material_damping_n_s_per_mm is not None else full[:-1, :-1]


def loop_poles(loop: Loop) -> np.ndarray:
    """Eigenvalues of the closed loop, the translation mode of a yielding front or of a
    master in no contact (zero stiffness) removed (shifting master, differentiator and front
    together changes nothing: eigenvalue 1)."""
    poles = np.linalg.eigvals(closed_loop_matrix(loop))
    free = loop.stiffness_n_per_mm == 0.0 and loop.hand_stiffness_n_per_mm == 0.0
    if loop.material_damping_n_s_per_mm is not None or free:
        i = int(np.argmin(np.abs(poles - 1.0)))
        if abs(poles[i] - 1.0) > 1e-6:
            raise AssertionError(f"no translation mode among the poles: {poles}")
        poles = np.delete(poles, i)
    return poles


def spectral_radius(loop: Loop) -> float:
    """Largest pole magnitude (< 1: stable; > 1: oscillations grow)."""
    return float(np.max(np.abs(loop_poles(loop))))


def dominant_pole(loop: Loop) -> dict[str, float]:
    """The largest pole as magnitude, frequency (Hz) and damping ratio of its continuous
    equivalent ``s = ln(z) / T``."""
    poles = loop_poles(loop)
    z = complex(poles[int(np.argmax(np.abs(poles)))])
    s = complex(np.log(z)) / loop.dt_s
    wn = abs(s)
    return {
        "magnitude": abs(z),
        "frequency_hz": abs(s.imag) / (2.0 * math.pi),
        "damping_ratio": -s.real / wn if wn > 0.0 else 1.0,
    }


def _limit(loop: Loop, lo: float, hi: float, unit: str, vary: Callable[[float], Loop]) -> float:
    """Smallest value above ``lo`` (``loop``'s own) at which ``vary(value)`` goes unstable
    (spectral radius reaches 1): scanned up on a geometric grid (4 % steps) and the first
    crossing bisected to 1e-6 relative; ``inf`` if stable up to ``hi``."""
    if not (lo > 0.0 and spectral_radius(loop) < 1.0):
        raise ValueError(f"the loop at {lo} {unit} is not stable: no margin to measure")

    def unstable(value: float) -> bool:
        return spectral_radius(vary(value)) >= 1.0

    while True:
        up = lo * 1.04
        if up > hi:
            return math.inf
        if unstable(up):
            break
        lo = up
    while up - lo > 1e-6 * up:
        mid = 0.5 * (lo + up)
        if unstable(mid):
            up = mid
        else:
            lo = mid
    return up


def stiffness_limit_n_per_mm(loop: Loop, *, hi_n_per_mm: float = 1e6) -> float:
    """Smallest stiffness above ``loop``'s own at which the loop goes unstable (spectral radius
    reaches 1), N/mm, found by scanning up on a geometric grid (4 % steps) and bisecting the
    first crossing to 1e-6 relative; ``inf`` if stable up to ``hi_n_per_mm``.

    Raises ValueError if ``loop`` itself is not stable."""
    return _limit(
        loop,
        loop.stiffness_n_per_mm,
        hi_n_per_mm,
        "N/mm",
        lambda k: replace(loop, stiffness_n_per_mm=k),
    )


def damping_limit_n_s_per_mm(loop: Loop, *, hi_n_s_per_mm: float = 1e3) -> float:
    """Smallest damping above ``loop``'s own at which the loop goes unstable (the damper, on
    the filtered and one tick old velocity estimate, drives the sampled loop past
    ``|z| = 1``), N s/mm, scanned and bisected as :func:`stiffness_limit_n_per_mm`;
    ``inf`` if stable up to ``hi_n_s_per_mm``.

    Raises ValueError if ``loop`` itself is not stable or has no damping."""
    return _limit(
        loop,
        loop.damping_n_s_per_mm,
        hi_n_s_per_mm,
        "N s/mm",
        lambda b: replace(loop, damping_n_s_per_mm=b),
    )


def release_speed_bound_mm_s(
    push_n: float, damping_n_s_per_mm: float, *, mass_kg: float = MASS_KG, g_dob: float = G_DOB
) -> float:
    """Bound on the fastest motion back of a master whose hand lets go of ``push_n``, mm/s.

    Two parts (docs/haptics-stability.md, "Letting go"): the force controller still balances
    the push until its observers (``g_dob``, 1/s) see it gone, an impulse of about
    ``F / g`` on the mass: ``F / (M g)``; and the springs, which cannot drive the master back
    faster than the damping that resists its retreat (``damping_n_s_per_mm``: the coupling's,
    the wall's at the stop, and the release damper's) lets them, since at the fastest point
    ``B v = K e <= F``: ``F / B``.
    """
    return push_n * (1.0 / (mass_kg * g_dob) * 1e3 + 1.0 / damping_n_s_per_mm)


def release_excursion_bound_mm(
    speed_mm_s: float,
    release_damping_n_s_per_mm: float,
    *,
    mass_kg: float = MASS_KG,
    kf: float = KF,
    g_dob: float = G_DOB,
) -> float:
    """Bound on how far a master leaving its contact at ``speed_mm_s`` goes on, mm: the
    release damper alone brakes it, the force controller making ``Mn / Kf`` the mass it
    brakes (time constant ``Mn / (Kf B)``), after the velocity estimate's lag ``1 / g``."""
    brake_s = mass_kg / (kf * release_damping_n_s_per_mm * 1e3)
    return speed_mm_s * (1.0 / g_dob + brake_s)


def colgate_terms(
    stiffness_n_per_mm: float, damping_n_s_per_mm: float, dt_s: float
) -> dict[str, float]:
    """Colgate and Schenkel's passivity condition for a sampled wall, ``b > K T / 2 + |B|``.

    Returns ``KT/2`` (the energy a sampled spring generates per sample, ``K dx^2 / 2``, as an
    equivalent damping) and ``KT/2 + |B|``, both N s/mm: the physical damping the device
    would need for the wall to be passive against every operator.
    """
    half = stiffness_n_per_mm * dt_s / 2.0
    return {"kt_half_n_s_per_mm": half, "required_b_n_s_per_mm": half + abs(damping_n_s_per_mm)}
