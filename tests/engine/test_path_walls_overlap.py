"""``plan_path`` with an implant starts the walls' rays on the worker thread and computes the
drill's path meanwhile (:func:`ctdrill.claims.start_claimed`): its outcome is the one computed
step by step (``path_curves``, then ``implant_outcome``), to the bit, however many threads
claim the rays; and a refused path leaves no rays running."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from ctdrill import jit
from ctdrill.app.search.warmup import search_kernels
from ctdrill.engine.implant import implant_outcome
from ctdrill.engine.path import PathInputError, complete_path, path_curves, plan_path
from ctdrill.engine.plans import plan_calibration
from ctdrill.imaging.dicom.series import load_series
from ctdrill.imaging.plan.load import load_plan
from tests.conftest import ASSETS


@pytest.fixture(scope="module")
def demo():  # type: ignore[no-untyped-def]
    jit.warm_up(search_kernels())
    volume = load_series(ASSETS / "demo" / "ct")
    plan = load_plan(ASSETS / "demo" / "plan.json")
    return volume, plan, plan_calibration(plan)


@pytest.mark.parametrize("cpus", [1, 2, 3])
def test_the_overlapped_path_is_the_step_by_step_one(demo, cpus, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    volume, plan, cal = demo
    monkeypatch.setattr(jit, "cpus", lambda: cpus)
    got = plan_path(volume, plan, cal)
    curves = path_curves(volume, plan, cal)
    want_implant = implant_outcome(volume, curves.plan)
    want = complete_path(volume, curves, want_implant)
    assert got.implant is not None and want.implant is not None
    np.testing.assert_array_equal(got.implant.walls.wall_mm, want.implant.walls.wall_mm)
    assert got.implant.bone_walls_json() == want.implant.bone_walls_json()
    assert got.implant.clearance_mm == want.implant.clearance_mm
    assert [(w.code, w.message) for w in got.warnings] == [
        (w.code, w.message) for w in want.warnings
    ]
    assert got.stop_depth_mm == want.stop_depth_mm


def test_a_refused_path_with_an_implant_refuses_as_before(demo) -> None:  # type: ignore[no-untyped-def]
    volume, plan, cal = demo
    # the entry far outside the CT: refused before any force is computed
    far = replace(plan, entry_lps=plan.entry_lps + np.array([0.0, 0.0, 500.0]))
    with pytest.raises(PathInputError):
        plan_path(volume, far, cal)
    assert plan_path(volume, plan, cal).implant is not None  # the worker is free again
