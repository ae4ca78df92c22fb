"""The compiled one-point bisection of ``ArchCurve.project`` against its Python-float path.

Both run the same IEEE operations in the same order (no fused multiply-add: numba compiles
without fastmath), so the arc positions and offsets are equal bit for bit: on the demo plan's
arch, and on a sharp polyline with no tangent window (the chord of the segment itself).
"""

from __future__ import annotations

import numpy as np
import pytest

from ctdrill import jit
from ctdrill.imaging.plan.load import load_plan
from ctdrill.imaging.sampling.arch import ArchCurve, arch_curve
from ctdrill.imaging.sampling.arch_kernel import ARCH_KERNEL
from tests.conftest import ASSETS


@pytest.fixture(scope="module", autouse=True)
def kernel() -> None:
    """The kernel as `make warmup` leaves it (compiled here when the cache is missing)."""
    jit.warm_up((ARCH_KERNEL,))
    assert ARCH_KERNEL.ready()


def _curves() -> dict[str, ArchCurve]:
    plan = load_plan(ASSETS / "demo" / "plan.json")
    assert plan.arch_lps is not None
    zigzag = np.array([[0.0, 0.0, 0.0], [10.0, 5.0, 1.0], [20.0, 0.0, 0.0], [30.0, 8.0, 2.0]])
    return {
        "demo": arch_curve(plan.arch_lps),
        "no window": ArchCurve(zigzag, 0.0),
        "wide window": ArchCurve(zigzag, 14.0),
    }


@pytest.mark.parametrize("name", ["demo", "no window", "wide window"])
def test_one_point_projection_is_bitwise_the_python_path(name: str) -> None:
    curve = _curves()[name]
    rng = np.random.default_rng(9)
    centre = np.mean(curve.arch_lps, axis=0)
    points = centre + rng.normal(0.0, 8.0, (200, 3))
    got = [curve.project(p[None]) for p in points]
    with jit.switched_off((ARCH_KERNEL,)):
        want = [curve.project(p[None]) for p in points]
    assert sum(bool(np.isfinite(s[0])) for s, _ in want) > 50
    for (s, t), (s0, t0) in zip(got, want, strict=True):
        assert np.array_equal(s, s0, equal_nan=True) and np.array_equal(t, t0, equal_nan=True)


def test_the_curve_is_built_once_per_arch() -> None:
    plan = load_plan(ASSETS / "demo" / "plan.json")
    assert plan.arch_lps is not None
    assert arch_curve(plan.arch_lps) is arch_curve(np.array(plan.arch_lps))
    assert arch_curve(plan.arch_lps) is not arch_curve(plan.arch_lps + 1.0)
