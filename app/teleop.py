"""Headless teleoperation: CT + plan -> the slave cutting it under bilateral control -> records.

``ctdrill teleop``, the benchmarks and the tests call :func:`prepare_teleop` (the plan's path,
the path the slave really cuts, the prior) and :func:`run_teleop` (one seeded run and its
figures); :func:`teleop` writes ``OUT/session.csv`` and ``OUT/summary.json`` whole
(docs/teleop.md).

The CT the slave cuts is the plan's CT shifted by ``misregister_mm`` against the drill's
direction (its anatomy that much shallower; negative: deeper): the slave's depth ``x`` meets
the plan CT's depth ``x + misregister_mm``. The slave starts :data:`STANDOFF_MM` above the
surface it really meets.
"""

from __future__ import annotations

import json
import math
import random
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from ctdrill.app.csv_cells import csv_text
from ctdrill.app.errors import AppInputError
from ctdrill.app.records import atomic_output_dir, write_file
from ctdrill.engine.path import PathInputError, PathResult, plan_path
from ctdrill.engine.plans import plan_calibration
from ctdrill.haptics.bilateral.loop import STATE_NAMES, TeleopRun, TeleopSetup, simulate_teleop
from ctdrill.haptics.bilateral.metrics import fig14, teleop_metrics
from ctdrill.haptics.bilateral.params import ChannelSpec, EnvSpec, HandSpec
from ctdrill.haptics.bilateral.prior import Prior, plan_prior
from ctdrill.haptics.hands import breakthrough_depths_mm
from ctdrill.haptics.profile_table import ProfileTable
from ctdrill.haptics.session import Operator, parse_operator
from ctdrill.imaging import load_ct
from ctdrill.imaging.misch import CORTICAL_HU
from ctdrill.imaging.plan.load import load_one_plan
from ctdrill.imaging.plan.types import Plan
from ctdrill.imaging.volume import CTVolume
from ctdrill.model.calibration import Calibration

#: The slave starts this far above the surface it meets, mm.
STANDOFF_MM = 0.5
#: The true CT is sampled this far beyond the planned depth (the slave may pass it), mm.
BEYOND_MM = 4.0
#: Largest misregistration accepted, mm.
MAX_MISREGISTER_MM = 10.0
SESSION_COLUMNS = (
    "time_s",
    "master_mm",
    "slave_mm",
    "front_mm",
    "env_force_n",
    "hand_n",
    "master_force_n",
    "fh_est_n",
    "fe_est_n",
    "force_lp_n",
    "hu_ct",
    "hu_est",
    "gain",
    "state",
    "energy_j",
)


@dataclass(frozen=True, eq=False)
class TeleopCase:
    """The plan's path and the path the slave cuts (module docstring), in slave depth."""

    plan_path: PathResult
    true_path: PathResult
    true_origin_mm: float
    start_mm: float
    calibration: Calibration
    prior: Prior
    misregister_mm: float

    @property
    def exit_mm(self) -> float | None:
        """The true first breakthrough (the cortex exit) in slave depth, mm (None: none)."""
        prof = self.true_path.profile
        table = ProfileTable.from_profile(prof, float(prof.depth_mm[-1]))
        depths = breakthrough_depths_mm(table)
        return depths[0] + self.true_origin_mm if depths else None


def prepare_teleop(
    ct: Path, plan_file: Path | Sequence[Path], *, misregister_mm: float = 0.0
) -> TeleopCase:
    """Load the CT and plan; the plan's path and the misregistered one the slave cuts."""
    check_misregistration(misregister_mm)
    volume = load_ct(ct)
    plan = load_one_plan([plan_file] if isinstance(plan_file, Path) else list(plan_file))
    return teleop_case(volume, plan, misregister_mm=misregister_mm)


def check_misregistration(misregister_mm: float) -> None:
    """Refuse a misregistration that is not a finite shift within the bound."""
    if not (math.isfinite(misregister_mm) and abs(misregister_mm) <= MAX_MISREGISTER_MM):
        raise AppInputError(
            f"--misregister-mm {misregister_mm}: give a shift within ±{MAX_MISREGISTER_MM:g} mm"
        )


def teleop_case(volume: CTVolume, plan: Plan, *, misregister_mm: float = 0.0) -> TeleopCase:
    """The plan's path on ``volume`` (its first drill) and the misregistered one the slave
    cuts (module docstring)."""
    check_misregistration(misregister_mm)
    plan = plan.drilled(0)
    cal = plan_calibration(plan)
    path = plan_path(volume, plan, cal)
    start = -(STANDOFF_MM + max(misregister_mm, 0.0))
    u = plan.direction
    entry = plan.entry_lps + (start + misregister_mm) * u
    try:
        try:
            target = plan.target_lps + (misregister_mm + BEYOND_MM) * u
            true_path = plan_path(
                volume, replace(plan, entry_lps=entry, target_lps=target, landmarks=()), cal
            )
        except PathInputError:  # the scan ends near the plan's end: no margin beyond it
            target = plan.target_lps + misregister_mm * u
            true_path = plan_path(
                volume, replace(plan, entry_lps=entry, target_lps=target, landmarks=()), cal
            )
    except PathInputError as exc:
        if misregister_mm == 0.0:
            raise
        raise AppInputError(
            f"--misregister-mm {misregister_mm:g}: the CT shifted this far along the drill's axis "
            f"cannot carry the slave's path ({exc}); give a smaller shift"
        ) from exc
    return TeleopCase(
        plan_path=path,
        true_path=true_path,
        true_origin_mm=start,
        start_mm=start,
        calibration=cal,
        prior=plan_prior(path.profile, cal),
        misregister_mm=misregister_mm,
    )


def vibration_phases(seed: int, count: int) -> tuple[float, ...]:
    """The drill's vibration phases of run ``seed`` (uniform, from the seed), rad."""
    rng = random.Random(f"vibration-{seed}")
    return tuple(rng.uniform(0.0, 2.0 * math.pi) for _ in range(count))


def run_teleop(
    case: TeleopCase,
    operator: Operator,
    *,
    duration_s: float,
    seed: int = 0,
    hand_damping_n_s_per_m: float = HandSpec().damping_n_s_per_m,
    delay_ms: float = 0.0,
    jitter_ms: float = 0.0,
    loss: float = 0.0,
    model_error: float = 0.0,
    env_stiffness_n_per_mm: float = EnvSpec().stiffness_n_per_mm,
    force_stop: bool = True,
    record_every: int = 10,
) -> tuple[TeleopRun, dict[str, Any]]:
    """One seeded run on ``case`` and its figures (:func:`teleop_metrics`)."""
    setup = TeleopSetup(
        duration_s=duration_s,
        seed=seed,
        start_mm=case.start_mm,
        plan_stop_mm=case.plan_path.stop_depth_mm,
        force_stop=force_stop,
        record_every=record_every,
        channel=ChannelSpec(delay_ms=delay_ms, jitter_ms=jitter_ms, loss=loss),
        hand=replace(HandSpec(), damping_n_s_per_m=hand_damping_n_s_per_m),
        env=replace(
            EnvSpec(),
            model_error=model_error,
            stiffness_n_per_mm=env_stiffness_n_per_mm,
            vibration_phase_rad=vibration_phases(seed, len(case.calibration.harmonics)),
        ),
    )
    run = simulate_teleop(
        case.true_path.profile,
        case.true_origin_mm,
        case.calibration,
        case.prior,
        operator,
        setup,
        tip_length_mm=case.plan_path.plan.drill.tip_length_mm,
    )
    figures = teleop_metrics(
        run,
        gate_hu=case.calibration.gate_hu,
        cortical_hu=CORTICAL_HU,
        tip_length_mm=case.plan_path.plan.drill.tip_length_mm,
        exit_mm=case.exit_mm,
    )
    figures["fig14"] = fig14(run, case.plan_path.profile, 0.0)
    figures["plan_stop_depth_mm"] = case.plan_path.stop_depth_mm
    figures["plan_stop_reason"] = case.plan_path.stop_reason
    return run, figures


def session_csv_text(run: TeleopRun) -> str:
    """``session.csv`` of ``run`` (:data:`SESSION_COLUMNS`; ``hu_est`` empty while gated)."""
    cols = [
        run.time_s,
        run.master_mm,
        run.slave_mm,
        run.front_mm,
        run.env_force_n,
        run.hand_n,
        run.felt_n,
        run.fh_est_n,
        run.fe_est_n,
        run.force_lp_n,
        run.hu_ct,
    ]
    rows = []
    for i in range(run.time_s.shape[0]):
        hu = float(run.hu_est[i])
        rows.append(
            [f"{float(c[i]):.6g}" for c in cols]
            + [
                "" if math.isnan(hu) else f"{hu:.1f}",
                f"{float(run.gain[i]):.5f}",
                STATE_NAMES[int(run.state[i])],
                f"{float(run.energy_j[i]):.6g}",
            ]
        )
    return csv_text(SESSION_COLUMNS, rows)


def _finite(value: Any) -> Any:
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_finite(v) for v in value]
    return value


def _check(name: str, value: float, lo: float, hi: float) -> None:
    if not (math.isfinite(value) and lo <= value <= hi):
        raise AppInputError(f"{name} {value}: give a number in [{lo:g}, {hi:g}]")


def teleop(
    *,
    ct: Path,
    plan: Path | Sequence[Path],
    out: Path,
    operator: str,
    duration_s: float,
    hand_damping_n_s_per_m: float = HandSpec().damping_n_s_per_m,
    delay_ms: float = 0.0,
    jitter_ms: float = 0.0,
    loss: float = 0.0,
    model_error: float = 0.0,
    misregister_mm: float = 0.0,
    seed: int = 0,
) -> dict[str, Any]:
    """Run one teleoperation and write ``OUT/session.csv`` and ``OUT/summary.json`` (whole)."""
    _check("--duration-s", duration_s, 1e-3, 600.0)
    _check("--hand-damping", hand_damping_n_s_per_m, 0.0, 1e4)
    _check("--delay-ms", delay_ms, 0.0, 1000.0)
    _check("--jitter-ms", jitter_ms, 0.0, 1000.0)
    _check("--loss", loss, 0.0, 0.99)
    _check("--model-error", model_error, -0.9, 9.0)
    op = parse_operator(operator)
    case = prepare_teleop(ct, plan, misregister_mm=misregister_mm)
    run, figures = run_teleop(
        case,
        op,
        duration_s=duration_s,
        seed=seed,
        hand_damping_n_s_per_m=hand_damping_n_s_per_m,
        delay_ms=delay_ms,
        jitter_ms=jitter_ms,
        loss=loss,
        model_error=model_error,
    )
    summary: dict[str, Any] = {
        "format": "ctdrill-teleop/1",
        "operator": op.spec,
        "duration_s": duration_s,
        "seed": seed,
        "hand_damping_n_s_per_m": hand_damping_n_s_per_m,
        "delay_ms": delay_ms,
        "jitter_ms": jitter_ms,
        "loss": loss,
        "model_error": model_error,
        "misregister_mm": misregister_mm,
        "calibration": case.calibration.name,
        **figures,
    }
    with atomic_output_dir(out) as stage:
        write_file(stage / "session.csv", session_csv_text(run))
        write_file(
            stage / "summary.json", json.dumps(_finite(summary), indent=2, allow_nan=False) + "\n"
        )
    return summary
