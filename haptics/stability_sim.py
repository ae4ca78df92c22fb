"""The coupled master simulated tick by tick, with its energy books (docs/haptics-stability.md).

:func:`simulate_push` runs the device emulator's own control tick
(:meth:`ctdrill.haptics.emulator.DeviceEmulator.control_tick`: renderer, DOB/RFOB force
controller, plant, simulated hand) on a homogeneous slab with a stop, a hand pushing with a
constant force (from the start, or stepped on later), and records per tick what the coupling
did. No protocol, no watchdog: the loop alone.

Energy (the discrete passivity check): over tick ``j`` the rendered force ``F_j`` is held while
the master moves from ``x_j`` to ``x_{j+1}``, so the energy the virtual coupling absorbed up to
tick ``n`` is ``E(n) = sum F_j (x_{j+1} - x_j)``. Its springs (the coupling ``k`` on the
penetration, the stop wall beyond its anchor) store ``V(n)``. A passive coupling never gives
back more than it took: ``E(n) >= 0``, and, while no force limit clips the springs,
``D(n) = E(n) - V(n) >= 0`` (what the damper and the material dissipated, less what sampling
generated: a held spring force generates ``K dx^2 / 2`` per tick).

The stop wall's anchor glides from where the master met it to the stop depth (the hand is
carried back to the stopped drill): a commanded motion of the wall's reference, not feedback.
The energy it puts into the wall, ``G(n) = sum F_w,j (a_j - a_{j+1})`` (the wall's force,
at most the rendered one, times the anchor's step), is booked separately: it is bounded (at
most the force times the glide, once per stop) and the books show that the coupling gives back
no more than it took even so.

A hand that lets go (``release_at_s``: the push drops to 0 N there, as a ``human`` operator's
does) is the release the release damper is for (:mod:`ctdrill.haptics.renderer`):
:func:`release_account` measures what the master did afterwards, and what the books gave back.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ctdrill.haptics.emulator import DeviceEmulator
from ctdrill.haptics.physics import MasterPhysics
from ctdrill.haptics.profile_table import ProfileTable
from ctdrill.haptics.protocol import Fault, OperatorKind
from ctdrill.haptics.renderer import (
    RELEASE_DAMPING_N_S_PER_MM,
    STOP_GLIDE_MM_S,
    STOP_WALL_DAMPING_N_S_PER_MM,
    STOP_WALL_N_PER_MM,
    Renderer,
)
from ctdrill.model.cutting import DEFAULT_DAMPING_N_S_PER_MM, DEFAULT_STIFFNESS_N_PER_MM


@dataclass(frozen=True, eq=False)
class PushRun:
    """One simulated push (per-tick arrays, SI energies).

    Attributes
    ----------
    time_s, master_mm, front_mm, force_n, hand_n : ndarray
        After each tick: time, master (true position), cut front, rendered force, hand force.
    velocity_mm_s : ndarray
        After each tick: the master's true velocity, mm/s.
    energy_in_j : ndarray
        ``E(n)``: energy the coupling absorbed so far, J.
    stored_j : ndarray
        ``V(n)``: energy in the coupling's springs, J.
    glide_j : ndarray
        ``G(n)``: energy the stop anchor's glide put into the wall so far, J.
    stop_reached_s : float
        When the front reached the stop depth, s (nan: never).
    faults : int
        The renderer's fault bits at the end (:class:`Fault`).
    clipped : bool
        A force limit (peak or thermal) acted: ``V`` is then not the rendered force's energy.
    travel_end : bool
        The stage met an end of its travel.
    """

    time_s: np.ndarray
    master_mm: np.ndarray
    front_mm: np.ndarray
    force_n: np.ndarray
    hand_n: np.ndarray
    velocity_mm_s: np.ndarray
    energy_in_j: np.ndarray
    stored_j: np.ndarray
    glide_j: np.ndarray
    stop_reached_s: float
    faults: int
    clipped: bool
    travel_end: bool

    @property
    def dissipated_j(self) -> np.ndarray:
        """``D(n) = E(n) - V(n)``, J."""
        return self.energy_in_j - self.stored_j

    def settled_range_mm(self, window_s: float = 0.1) -> float:
        """Peak-to-peak master motion over the last ``window_s``, mm (0: at rest)."""
        n = max(1, round(window_s / float(self.time_s[1] - self.time_s[0])))
        tail = self.master_mm[-n:]
        return float(tail.max() - tail.min())


def simulate_push(
    push_n: float,
    *,
    s0_n: float = 4.0,
    ke_per_mm_s: float = 0.25,
    stop_depth_mm: float = 1.0,
    duration_s: float = 1.0,
    step_at_s: float = 0.0,
    stiffness_n_per_mm: float = DEFAULT_STIFFNESS_N_PER_MM,
    damping_n_s_per_mm: float = DEFAULT_DAMPING_N_S_PER_MM,
    coulomb_n: float | None = None,
    stop_wall_n_per_mm: float = STOP_WALL_N_PER_MM,
    stop_wall_damping_n_s_per_mm: float = STOP_WALL_DAMPING_N_S_PER_MM,
    stop_glide_mm_s: float = STOP_GLIDE_MM_S,
    release_damping_n_s_per_mm: float = RELEASE_DAMPING_N_S_PER_MM,
    release_at_s: float = math.inf,
) -> PushRun:
    """Simulate a hand pushing ``push_n`` from ``step_at_s`` on a slab of ``S0 = s0_n`` from
    depth 0 whose stop is at ``stop_depth_mm``; the master starts at rest at the surface. At
    ``release_at_s`` the hand lets go (0 N from then on).

    ``coulomb_n`` replaces the Coulomb friction of plant and friction model (None: the
    paper's 1.0 N); the stiffness and damping those of the renderer's coupling, the
    ``stop_*`` values those of its stop wall (stiffness, damping, the anchor's glide speed),
    ``release_damping_n_s_per_mm`` its release damper (0: none, the renderer before it).
    """
    emu = DeviceEmulator(nonce_seed=0)
    master = MasterPhysics(dt_s=emu.dt_s, coulomb_n=coulomb_n)
    emu.physics = master
    emu.renderer = Renderer(
        tick_hz=emu.tick_hz,
        stiffness_n_per_mm=stiffness_n_per_mm,
        damping_n_s_per_mm=damping_n_s_per_mm,
        stop_wall_n_per_mm=stop_wall_n_per_mm,
        stop_wall_damping_n_s_per_mm=stop_wall_damping_n_s_per_mm,
        stop_glide_mm_s=stop_glide_mm_s,
        release_damping_n_s_per_mm=release_damping_n_s_per_mm,
        watchdog_s=math.inf,
    )
    table = ProfileTable.slab(
        s0_n=s0_n,
        top_mm=0.0,
        bottom_mm=stop_depth_mm + 10.0,
        stop_depth_mm=stop_depth_mm,
        ke_per_mm_s=ke_per_mm_s,
    )
    r = emu.renderer
    r.load(table.begin_message(), table.rows())
    if r.arm(0.0, master.plant.encoder_mm()) is not None:
        raise AssertionError("the renderer refused to arm at the surface")
    n = round(duration_s * emu.tick_hz)
    out = np.zeros((9, n))
    energy = 0.0
    glide = 0.0
    stop_at = math.nan
    travel_end = False
    k_n_per_m = stiffness_n_per_mm * 1e3
    wall_n_per_m = r.k_stop * 1e3
    master.set_operator(int(OperatorKind.NONE), 0.0)
    for i in range(n):
        if emu.now_s >= release_at_s - 1e-12:
            if master.hand.value != 0.0:
                master.set_operator(int(OperatorKind.PUSH), 0.0)
        elif emu.now_s >= step_at_s - 1e-12 and master.hand.kind != OperatorKind.PUSH:
            master.set_operator(int(OperatorKind.PUSH), push_n)
        x0 = master.plant.x_m
        anchor0 = r.stop_anchor_mm
        emu.control_tick()
        x1 = master.plant.x_m
        force = r.force_cmd_n
        energy += force * (x1 - x0)
        e_m = x1 - r.front_mm * 1e-3
        stored = 0.5 * k_n_per_m * e_m * e_m if e_m > 0.0 else 0.0
        beyond_m = x1 - r.stop_anchor_mm * 1e-3
        if beyond_m > 0.0:
            stored += 0.5 * wall_n_per_m * beyond_m * beyond_m
            if math.isfinite(anchor0) and r.stop_anchor_mm < anchor0:  # the anchor glided
                # the wall's force on the glide (the spring's, at most what was rendered)
                pushed_n = min(wall_n_per_m * beyond_m, force)
                glide += pushed_n * (anchor0 - r.stop_anchor_mm) * 1e-3
        if math.isnan(stop_at) and r.front_mm >= stop_depth_mm:
            stop_at = emu.now_s
        travel_end = travel_end or master.plant.at_end_stop
        v = master.plant.v_m_s * 1e3
        out[:, i] = (emu.now_s, x1 * 1e3, r.front_mm, force, emu.hand_n, v, energy, stored, glide)
    return PushRun(
        time_s=out[0],
        master_mm=out[1],
        front_mm=out[2],
        force_n=out[3],
        hand_n=out[4],
        velocity_mm_s=out[5],
        energy_in_j=out[6],
        stored_j=out[7],
        glide_j=out[8],
        stop_reached_s=stop_at,
        faults=r.faults,
        clipped=bool(r.faults & (Fault.PEAK_LIMIT | Fault.THERMAL_LIMIT)),
        travel_end=travel_end,
    )


@dataclass(frozen=True)
class ReleaseAccount:
    """What the master did after the hand let go (:func:`release_account`).

    Attributes
    ----------
    push_n : float
        The push the hand let go of, N.
    at_stop : bool
        The drill was at its stop (the wall) when the hand let go; else it was cutting.
    peak_back_mm_s : float
        The master's fastest motion back after the release, mm/s.
    behind_mm : float
        How far the master went behind the cut front (the drill's depth, the surface it
        left) after the release, mm (0: never).
    final_speed_mm_s : float
        The master's speed at the end of the run, mm/s.
    rest_mm : float
        Where the master is at the end, past the cut front (negative: behind it), mm.
    travel_end : bool
        The master met an end of its travel.
    stored_j : float
        ``V``: what the coupling's springs held when the hand let go, J.
    returned_j : float
        The most the books gave back after the release, ``E(release) - min E(after)``, J.
    """

    push_n: float
    at_stop: bool
    peak_back_mm_s: float
    behind_mm: float
    final_speed_mm_s: float
    rest_mm: float
    travel_end: bool
    stored_j: float
    returned_j: float


def release_account(run: PushRun, release_at_s: float) -> ReleaseAccount:
    """The release of ``run`` (simulated with ``release_at_s``): :class:`ReleaseAccount`."""
    i = int(np.searchsorted(run.time_s, release_at_s - 1e-12))
    after = slice(i, None)
    front = float(run.front_mm[-1])
    return ReleaseAccount(
        push_n=float(run.hand_n[i - 1]),
        at_stop=bool(math.isfinite(run.stop_reached_s) and run.stop_reached_s < release_at_s),
        peak_back_mm_s=max(0.0, -float(run.velocity_mm_s[after].min())),
        behind_mm=max(0.0, front - float(run.master_mm[after].min())),
        final_speed_mm_s=abs(float(run.velocity_mm_s[-1])),
        rest_mm=float(run.master_mm[-1]) - front,
        travel_end=run.travel_end,
        stored_j=float(run.stored_j[i - 1]),
        returned_j=float(run.energy_in_j[i - 1] - run.energy_in_j[after].min()),
    )
