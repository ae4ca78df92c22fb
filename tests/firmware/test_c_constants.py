"""One owner per constant: every number the C core and its host build spell is the Python
device's, asked of its owner (the C is a translation; these are its bindings)."""

from __future__ import annotations

import re
from pathlib import Path

from ctdrill.haptics import emulator, physics, plant, realtime, renderer
from ctdrill.haptics.profile_table import MAX_PROFILE_STEPS
from ctdrill.haptics.protocol import MAX_CHUNK_ROWS, MAX_DECODED, PROTOCOL_VERSION
from ctdrill.haptics.tick import TICK_HZ
from ctdrill.model import cutting

FW = Path(__file__).resolve().parents[2] / "firmware"


def _defines(path: Path) -> dict[str, float]:
    out = {}
    for name, value in re.findall(r"^#define (\w+) (.+?)(?:\s*/\*.*)?$", path.read_text(), re.M):
        value = re.sub(r"^R\((.*)\)$", r"\1", value.strip()).rstrip("u")
        try:
            out[name] = float(eval(value, {"__builtins__": {}}))  # numbers and (a * b) only
        except (NameError, SyntaxError, TypeError):
            continue
    return out


def test_the_laws_constants_are_the_python_devices() -> None:
    law = _defines(FW / "fw_law.h")
    owners = {
        "PEAK_FORCE_N": renderer.PEAK_FORCE_N,
        "CONTINUOUS_FORCE_N": renderer.CONTINUOUS_FORCE_N,
        "THERMAL_BUDGET_N2_S": renderer.THERMAL_BUDGET_N2_S,
        "ARM_MAX_FORCE_N": renderer.ARM_MAX_FORCE_N,
        "K_N_PER_MM": cutting.DEFAULT_STIFFNESS_N_PER_MM,
        "B_N_S_PER_MM": cutting.DEFAULT_DAMPING_N_S_PER_MM,
        "K_STOP_N_PER_MM": renderer.STOP_WALL_N_PER_MM,
        "B_STOP_N_S_PER_MM": renderer.STOP_WALL_DAMPING_N_S_PER_MM,
        "STOP_GLIDE_MM_S": renderer.STOP_GLIDE_MM_S,
        "B_RELEASE_N_S_PER_MM": renderer.RELEASE_DAMPING_N_S_PER_MM,
        "RELEASE_PULL_N": renderer.RELEASE_PULL_N,
        "RELEASE_MAX_N": renderer.RELEASE_MAX_N,
        "RELEASE_OFF_PULL_N": renderer.RELEASE_OFF_PULL_N,
        "RELEASE_HOLD_TICKS": renderer.RELEASE_HOLD_TICKS,
        "MASS_KG": plant.MASS_KG,
        "KT_N_PER_A": plant.KT_N_PER_A,
        "COULOMB_N": plant.COULOMB_N,
        "KF": plant.KF,
        "G_DOB": plant.G_DOB,
        "G_RFOB": plant.G_RFOB,
        "G_VEL": plant.G_VEL,
        "FRICTION_VEL_M_S": plant.FRICTION_VEL_M_S,
        "TRAVEL_MIN_MM": plant.TRAVEL_MM[0],
        "TRAVEL_MAX_MM": plant.TRAVEL_MM[1],
    }
    assert law == owners  # and no constant of the law left unbound


def test_the_protocols_constants_are_the_python_devices() -> None:
    fw = _defines(FW / "fw.h")
    assert fw["FW_PROTOCOL_VERSION"] == PROTOCOL_VERSION
    assert (fw["FW_VERSION_MAJOR"], fw["FW_VERSION_MINOR"], fw["FW_VERSION_PATCH"]) == (
        emulator.FW_VERSION
    )
    assert fw["FW_TICK_HZ"] == TICK_HZ
    assert fw["FW_TELEMETRY_EVERY"] == emulator.TELEMETRY_EVERY
    assert fw["FW_MAX_DECODED"] == MAX_DECODED
    assert fw["FW_MAX_CHUNK_ROWS"] == MAX_CHUNK_ROWS
    assert fw["FW_MAX_PROFILE_STEPS"] == MAX_PROFILE_STEPS
    assert fw["FW_WATCHDOG_MS"] == round(renderer.WATCHDOG_S * 1000)
    assert fw["FW_WATCHDOG_TICKS"] == round(renderer.WATCHDOG_S * TICK_HZ)


def test_the_host_builds_master_and_hand_are_the_simulators() -> None:
    host = _defines(FW / "host" / "fw_host.c")
    assert host["PLANT_MASS_KG"] == plant.MASS_KG
    assert host["PLANT_KT"] == plant.KT_N_PER_A
    assert host["PLANT_COULOMB_N"] == plant.COULOMB_N
    assert host["ENCODER_M"] == plant.ENCODER_M
    assert (host["TRAVEL_LO_M"], host["TRAVEL_HI_M"]) == tuple(t * 1e-3 for t in plant.TRAVEL_MM)
    assert host["HAND_K"] == physics.HAND_STIFFNESS_N_PER_MM
    assert host["HAND_B"] == physics.HAND_DAMPING_N_S_PER_MM
    assert host["HAND_MAX_N"] == physics.HAND_MAX_N
    assert host["HAND_MAX_FEED"] == physics.HAND_MAX_FEED_MM_S
    assert host["RECEIVE_EVERY_TICKS"] == realtime.RECEIVE_EVERY_TICKS
