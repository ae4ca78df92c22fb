"""Rehearsal runs for the window, headless: device choice, a run that owns the device in its own
thread, telemetry the GUI polls, and the clearance at the live drill depth."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from serial.tools import list_ports

from app.pipeline import PathResult

#: The device-choice label of the simulator.
SIMULATOR = "simulator"


def device_choices() -> list[str]:
    """The simulator, then every serial port present (``serial:<device>``)."""
    ports = sorted(p.device for p in list_ports.comports())
    return [SIMULATOR, *(f"serial:{p}" for p in ports)]


def clearance_at_mm(result: PathResult, depth_mm: float) -> float | None:
    """Clearance to the nearest landmark with the tip at ``depth_mm`` (linear between the
    profile's depths, clamped to its ends), mm; None without landmarks."""
    if result.clearance_mm.shape[1] == 0:
        return None
    curve = result.min_clearance_per_depth_mm
    return float(np.interp(depth_mm, result.depth_mm, curve))


@dataclass(frozen=True)
class Telemetry:
    """One display sample of a run."""

    time_s: float
    master_mm: float
    drill_mm: float
    force_n: float
    state: str  # idle | cutting | stopped | safe
    clearance_mm: float | None


class RehearsalRun:  # placeholder until the haptics session lands
    running = False
    error = ""

    @classmethod
    def start(cls, result: PathResult, *, device: str, push_n: float, record: bool) -> RehearsalRun:
        raise OSError("haptics session not available yet")

    def latest(self) -> Telemetry | None:
        return None

    def stop(self) -> None:
        return None

    def join(self, timeout_s: float) -> None:
        return None

    def export(self, out_dir: Path) -> list[Path]:
        return []
