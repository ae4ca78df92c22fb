"""Tables at the edges of float32 on both builds: no floating-point exception is raised (the
core's calls are checked for invalid, divide-by-zero and overflow), the force stays finite and
within the device's limits, and the float build goes through the states the double build does
(not at the same tick: a vibration at the float range flips the clipped force with the sign
of a sine, and the two builds' sines differ in their last bits)."""

from __future__ import annotations

import numpy as np
import pytest

from ctdrill.haptics.ccore import CDeviceEmulator, Precision, load_core
from ctdrill.haptics.host import HostDevice
from ctdrill.haptics.profile_table import ProfileTable
from ctdrill.haptics.protocol import OperatorKind
from ctdrill.haptics.sim import SimLink

F32_MAX = float(np.finfo(np.float32).max)
F32_TINY = float(np.finfo(np.float32).smallest_subnormal)


def _run(precision: Precision, table: ProfileTable, push_n: float) -> list[tuple[int, float]]:
    core = CDeviceEmulator(nonce_seed=0, precision=precision)
    lib = load_core(precision)
    dev = HostDevice(SimLink(core), token_seed=0)
    dev.hello()
    lib.fw_host_fe_raised()
    dev.upload_profile(table)
    dev.arm()
    dev.set_operator(int(OperatorKind.PUSH), push_n)
    out = []
    for _ in range(30):
        core.run_ticks(100)
        dev.heartbeat()
        samples = dev.poll()
        out += [(s.state, s.force_cmd_n) for s in samples]
    assert lib.fw_host_fe_raised() == 0, f"{precision}: a floating-point exception was raised"
    return out


@pytest.mark.parametrize(
    ("s0", "s1", "ke", "step"),
    [
        (2.0, F32_MAX, 0.25, 0.1),  # vibration at the float range: clipped to the peak or 0
        (F32_TINY, 1.0, 0.25, 0.1),  # next to nothing to cut
        (2.0, -F32_MAX, F32_TINY, 0.1),  # rigid-plastic in all but name, rows of opposite sign
        (F32_MAX, 0.0, 0.25, 2e-6),  # an uncuttable wall on a step near the host's finest
    ],
)
def test_extreme_tables_raise_nothing_and_render_alike(
    s0: float, s1: float, ke: float, step: float
) -> None:
    n = 50
    s1_rows = np.full(n, s1, dtype=np.float32)
    s1_rows[1::2] = -s1  # alternating rows: their differences are twice the float range
    table = ProfileTable(
        depth_step_mm=step,
        s0_n=np.full(n, s0),
        s1_n=s1_rows,
        s2_n=np.full(n, s1),
        ke_per_mm_s=ke,
        freqs_hz=np.array([30.0, 60.0]),
        stop_depth_mm=3.0,
    )
    double = _run("double", table, 20.0)
    single = _run("single", table, 20.0)
    assert {s for s, _ in double} == {s for s, _ in single}
    assert double[-1][0] == single[-1][0]
    assert all(np.isfinite(f) and -20.0 <= f <= 78.0 for _, f in double + single)
