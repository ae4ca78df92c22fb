"""The compiled first bone crossing (``surface_kernel``) against its NumPy path.

Both read the same trilinear samples (:func:`~ctdrill.imaging.sampling.trilinear.trilinear`
equals :meth:`CTVolume.sample` to float rounding of the index arithmetic, ~1e-9 HU) and apply
the same rules, so a line has a surface in one exactly when it has one in the other, and the
crossings agree to the bisection's tolerance (``SURFACE_TOL_MM``). Lines: around the demo's
planned entry in every direction (some start in bone, some never reach it, some leave the CT),
on the demo (int16), as float32, and on an irregular stack (slices dropped).
"""

from __future__ import annotations

import numpy as np
import pytest

from ctdrill import jit
from ctdrill.imaging.dicom.series import load_series
from ctdrill.imaging.plan.load import load_plan
from ctdrill.imaging.sampling.surface import SURFACE_TOL_MM, first_bone_crossing_mm
from ctdrill.imaging.sampling.surface_kernel import SURFACE_KERNEL
from ctdrill.imaging.volume import CTVolume
from tests.conftest import ASSETS


@pytest.fixture(scope="module", autouse=True)
def kernel() -> None:
    """The kernel as `make warmup` leaves it (compiled here when the cache is missing)."""
    jit.warm_up((SURFACE_KERNEL,))
    assert SURFACE_KERNEL.ready()


def _volumes() -> dict[str, CTVolume]:
    volume = load_series(ASSETS / "demo" / "ct")
    keep = np.ones(volume.hu.shape[0], dtype=bool)
    keep[[20, 41, 42]] = False
    irregular = CTVolume(
        volume.hu[keep],
        volume.affine_lps,
        None,
        volume.info,
        slice_positions_mm=volume.slice_positions_mm[keep],
    )
    f32 = CTVolume(volume.hu.astype(np.float32), volume.affine_lps, None, volume.info)
    return {"demo": volume, "float32": f32, "irregular": irregular}


@pytest.mark.parametrize("name", ["demo", "float32", "irregular"])
def test_crossings_match_numpy(name: str) -> None:
    volume = _volumes()[name]
    plan = load_plan(ASSETS / "demo" / "plan.json")
    rng = np.random.default_rng(5)
    n = 600
    origins = plan.entry_lps + rng.normal(0.0, 6.0, (n, 3))
    dirs = rng.normal(0.0, 1.0, (n, 3))
    dirs[: n // 2] = plan.direction + 0.3 * dirs[: n // 2]  # mostly into the ridge
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    origins[:20] += 60.0  # far outside the CT
    got = first_bone_crossing_mm(volume, origins, dirs, start_mm=-10.0, stop_mm=10.0)
    with jit.switched_off((SURFACE_KERNEL,)):
        want = first_bone_crossing_mm(volume, origins, dirs, start_mm=-10.0, stop_mm=10.0)
    assert np.array_equal(np.isnan(got), np.isnan(want))
    found = np.isfinite(want)
    assert 100 < found.sum() < n  # lines with and without a surface
    assert np.all(np.abs(got[found] - want[found]) <= SURFACE_TOL_MM)
