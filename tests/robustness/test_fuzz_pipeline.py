"""Fuzz the whole force path: mutated demo plans that still load go through ``plan_path``.

A plan the reader accepts (odd drill sizes, far landmarks, zero margins, landmarks behind the
entry) must give a finite profile and a stop depth within the planned depth, or be refused with
one of the project's input errors; within 5 s and 1 GiB of extra address space.
"""

from __future__ import annotations

import json
import tempfile
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given

from tests.robustness.fuzz import (
    EXAMPLE_LIMIT_S,
    FUZZ_TIMEOUT_S,
    fuzz_settings,
    mutated_json,
    timed,
    write_text,
)
from tests.robustness.make_corpus import ROOT
from tests.robustness.mutate import bounded_memory
from tests.robustness.test_found_bugs import known_bug

pytestmark = [pytest.mark.fuzz, pytest.mark.timeout(FUZZ_TIMEOUT_S)]

DEMO = ROOT / "assets" / "demo"
DEMO_PLAN: dict[str, Any] = json.loads((DEMO / "plan.json").read_text())


@cache
def demo_volume() -> object:
    from ctdrill.imaging import load_series

    return load_series(DEMO / "ct")


def run_plan_text(text: str) -> str:
    """Load the plan text and run the force path on the demo CT; "refuse", "ok" or a bug key."""
    from ctdrill.app.errors import AppInputError
    from ctdrill.engine.path import plan_path
    from ctdrill.imaging import ImagingInputError
    from ctdrill.imaging.plan.load import load_plan
    from ctdrill.model import ModelInputError, load_calibration

    errors = (AppInputError, ImagingInputError, ModelInputError)
    with tempfile.TemporaryDirectory() as tmp:
        path = write_text(Path(tmp) / "plan.json", text)
        try:
            with bounded_memory():
                plan = load_plan(path)
                calibration = load_calibration(plan.calibration)
                result = timed(
                    EXAMPLE_LIMIT_S,
                    lambda: plan_path(demo_volume(), plan, calibration),  # type: ignore[arg-type]
                )
        except errors as exc:
            assert str(exc).strip() and "\n" not in str(exc).strip(), repr(str(exc))
            return "refuse"
        except Exception as exc:
            key = known_bug(exc)
            if key is None:
                raise
            return key
    assert 0.0 <= result.stop_depth_mm <= plan.planned_depth_mm + 1e-9
    for arr in (result.profile.s0_n, result.profile.sk_n, result.lip.hu, result.depth_mm):
        assert np.isfinite(arr).all()
    assert not np.isnan(result.clearance_mm).any()
    return "ok"


def test_demo_plan_runs() -> None:
    assert run_plan_text(json.dumps(DEMO_PLAN)) == "ok"


@fuzz_settings
@given(text=mutated_json(DEMO_PLAN, max_mutations=2))
def test_fuzz_plan_through_force_path(text: str) -> None:
    run_plan_text(text)
