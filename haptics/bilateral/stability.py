"""The stability map of the bilateral loop (docs/teleop.md): hand damping x contact stiffness
x delay, judged by the passivity observer and the slave's position spread.

Each point: the hand pushes :data:`PUSH_N` from :data:`STANDOFF_MM` above a slab that does not
yield to it (its ``S0`` is :data:`HOLD_FACTOR` times the push), so the slave comes to rest in
contact with a spring of the given stiffness; the run is stable when the slave's peak-to-peak
motion over the last :data:`TAIL_S` stays within :data:`SPREAD_LIMIT_UM` and passive when the
observer's energy never falls below ``-PASSIVITY_TOL_J``.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ctdrill.haptics.bilateral.loop import TeleopSetup, simulate_teleop
from ctdrill.haptics.bilateral.metrics import PASSIVITY_TOL_J
from ctdrill.haptics.bilateral.params import ChannelSpec, EnvSpec, HandSpec
from ctdrill.haptics.bilateral.prior import plan_prior
from ctdrill.haptics.session import Operator
from ctdrill.model.calibration import Calibration, load_calibration
from ctdrill.model.force import a0_n
from ctdrill.model.profile import build_profile

#: The map's axes (the issue's): hand damping N s/m, contact stiffness N/mm, delay ms.
HAND_DAMPINGS_N_S_PER_M = (2.0, 5.0, 20.0, 50.0)
ENV_STIFFNESSES_N_PER_MM = (1.0, 11.0, 100.0)
DELAYS_MS = (0.0, 1.0, 5.0, 20.0)
PUSH_N = 15.0
HOLD_FACTOR = 2.0
SLAB_HU = 1500.0
STANDOFF_MM = 0.5
TAIL_S = 0.5
#: Peak-to-peak slave motion at rest beyond which a point is unstable, um (twice the largest
#: stick-slip cycle of the stages at rest without delay, 10 um: the encoder's 0.1 um step
#: winds the DOB's integral up against the Coulomb friction until the stage slips).
SPREAD_LIMIT_UM = 20.0


@dataclass(frozen=True)
class StabilityPoint:
    """One point of the map."""

    hand_damping_n_s_per_m: float
    env_stiffness_n_per_mm: float
    delay_ms: float
    energy_min_j: float
    spread_um: float
    passive: bool
    stable: bool


def _slab(calibration: Calibration):  # type: ignore[no-untyped-def]
    depth = np.arange(0.0, 10.0, 0.05)
    lip = np.full((depth.size, 1, 1), SLAB_HU)
    return build_profile(lip, np.ones(1), depth, calibration, blades=2, rpm=900)


def stability_point(
    hand_damping_n_s_per_m: float,
    env_stiffness_n_per_mm: float,
    delay_ms: float,
    *,
    duration_s: float = 1.5,
    seed: int = 0,
) -> StabilityPoint:
    """Simulate one point of the map (module docstring)."""
    cal = load_calibration("bone-illustrative")
    prof = _slab(cal)
    s0 = float(a0_n(SLAB_HU, 0.0, cal))
    setup = TeleopSetup(
        duration_s=duration_s,
        seed=seed,
        start_mm=-STANDOFF_MM,
        force_stop=False,
        channel=ChannelSpec(delay_ms=delay_ms),
        hand=replace(HandSpec(), damping_n_s_per_m=hand_damping_n_s_per_m),
        env=EnvSpec(
            stiffness_n_per_mm=env_stiffness_n_per_mm,
            model_error=HOLD_FACTOR * PUSH_N / s0 - 1.0,
        ),
    )
    run = simulate_teleop(
        prof,
        0.0,
        cal,
        plan_prior(prof, cal),
        Operator("push", PUSH_N, spec=f"push:{PUSH_N:g}"),
        setup,
        tip_length_mm=0.6,
    )
    tail = run.slave_mm[run.time_s >= duration_s - TAIL_S]
    spread = 1e3 * float(tail.max() - tail.min()) if tail.size else float("inf")
    return StabilityPoint(
        hand_damping_n_s_per_m=hand_damping_n_s_per_m,
        env_stiffness_n_per_mm=env_stiffness_n_per_mm,
        delay_ms=delay_ms,
        energy_min_j=run.energy_min_j,
        spread_um=spread,
        passive=run.energy_min_j >= -PASSIVITY_TOL_J,
        stable=bool(np.isfinite(spread) and spread <= SPREAD_LIMIT_UM),
    )
