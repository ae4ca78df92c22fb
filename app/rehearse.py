"""Headless rehearsal: CT + plan -> force table -> a device session -> session.csv, summary.json.

``ctdrill rehearse`` and the tests call :func:`rehearse`; the GUI can call the same pieces
(:func:`load_table`, :func:`open_device`, :func:`ctdrill.haptics.session.run_session`).
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ctdrill.app.errors import AppInputError
from ctdrill.app.pipeline import PathResult, plan_calibration, plan_path
from ctdrill.haptics.device import Device
from ctdrill.haptics.profile_table import ProfileTable
from ctdrill.haptics.serial_device import SerialDevice
from ctdrill.haptics.session import SessionCsv, parse_fault, parse_operator, run_session
from ctdrill.haptics.sim import SimulatedDevice
from ctdrill.imaging import load_series
from ctdrill.imaging.plan.types import load_one_plan


@dataclass(frozen=True, eq=False)
class RehearsalTable:
    """The uploaded table and where it came from."""

    table: ProfileTable
    path: PathResult


def load_table(
    dicom: Path, plan_file: Path | Sequence[Path], *, interpolate_gaps: bool = False
) -> RehearsalTable:
    """Load the CT and the plan (one file, or several merged into one trajectory), compute
    the path and adapt its profile to a device table.

    ``interpolate_gaps`` interpolates across slice gaps the drill crosses instead of refusing
    (the path's warnings then say so).
    """
    volume = load_series(dicom)
    plan = load_one_plan([plan_file] if isinstance(plan_file, Path) else plan_file)
    path = plan_path(volume, plan, plan_calibration(plan), interpolate_gaps=interpolate_gaps)
    return RehearsalTable(ProfileTable.from_profile(path.profile, path.stop_depth_mm), path)


def open_device(spec: str) -> Device:
    """``sim`` or ``serial:PORT`` (a device path, a pty link, or a pyserial URL)."""
    if spec == "sim":
        return SimulatedDevice()
    kind, sep, port = spec.partition(":")
    if kind == "serial" and sep and port:
        return SerialDevice(port)
    raise AppInputError(f"--device {spec!r}: use sim or serial:PORT (e.g. serial:/dev/ttyUSB0)")


def rehearse(
    *,
    dicom: Path,
    plan: Path | Sequence[Path],
    out: Path,
    operator: str,
    duration_s: float,
    device: str = "sim",
    faults: Sequence[str] = (),
    seed: int = 0,
    interpolate_gaps: bool = False,
) -> dict[str, Any]:
    """Run one rehearsal and write ``OUT/session.csv`` (flushed per block) and ``summary.json``.

    Returns the summary written.
    """
    if not (math.isfinite(duration_s) and 0.0 < duration_s <= 3600.0):
        raise AppInputError(f"--duration-s {duration_s}: give 0 < seconds <= 3600")
    op = parse_operator(operator)
    fault_specs = [parse_fault(f) for f in faults]
    loaded = load_table(dicom, plan, interpolate_gaps=interpolate_gaps)
    try:
        out.mkdir(parents=True, exist_ok=True)
        csv_out = SessionCsv(out / "session.csv")
    except OSError as exc:
        raise AppInputError(f"--out {out}: cannot write there ({exc.strerror})") from exc
    dev = open_device(device)
    try:
        result = run_session(
            dev,
            loaded.table,
            op,
            duration_s,
            faults=fault_specs,
            seed=seed,
            sink=csv_out.write,
        )
    finally:
        csv_out.close()
        dev.close()
    path = loaded.path
    summary = result.to_json()
    summary.update(
        {
            "stop_reason": path.stop_reason,
            "planned_depth_mm": float(path.plan.planned_depth_mm),
            "max_safe_depth_mm": float(path.max_safe_depth_mm),
            "calibration": path.calibration.name,
            "calibration_illustrative": bool(path.calibration.illustrative),
            "operator": op.spec,
            "device": device,
            "duration_s": duration_s,
            "seed": seed,
            "profile_steps": loaded.table.n_steps,
            "depth_step_mm": loaded.table.depth_step_mm,
            "warnings": [w.code for w in path.warnings],
            "interpolated_gaps": len(path.interpolated_gaps),
        }
    )
    (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n", encoding="utf-8")
    return summary
