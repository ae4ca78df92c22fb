"""Fuzz the JSON readers: plans (ctdrill-plan/1 and Slicer markups) and calibration sets.

Only the package's own input error may escape; whatever loads must be finite and usable.
"""

from __future__ import annotations

import json
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given

from tests.robustness.fuzz import (
    EXAMPLE_LIMIT_S,
    FUZZ_TIMEOUT_S,
    SEED_MARKUPS,
    SEED_PLAN,
    SEED_PLAN_SET,
    fuzz_settings,
    mutated_json,
    seed_calibration,
    timed,
    write_text,
)
from tests.robustness.mutate import bounded_memory, finite_numbers
from tests.robustness.test_found_bugs import known_bug

pytestmark = [pytest.mark.fuzz, pytest.mark.timeout(FUZZ_TIMEOUT_S)]


def check_plan_text(text: str, suffix: str) -> None:
    """Load a plan text: a Plan with finite, sane fields, or a PlanInputError."""
    from ctdrill.imaging import ImagingInputError
    from ctdrill.imaging.plan.load import load_plans

    with tempfile.TemporaryDirectory() as tmp:
        path = write_text(Path(tmp) / f"plan{suffix}", text)
        try:
            with bounded_memory():
                plans = timed(EXAMPLE_LIMIT_S, lambda: load_plans(path))
        except ImagingInputError as exc:
            assert str(exc).strip() and "\n" not in str(exc).strip()
            return
        except Exception as exc:
            if known_bug(exc) is None:
                raise
            return
    for plan in plans:
        assert finite_numbers(plan), plan
        assert plan.planned_depth_mm > 0.0
        assert plan.drill.diameter_mm > 0.0 and plan.drill.tip_length_mm >= 0.0
        assert plan.margin_mm >= 0.0 and plan.feed_mm_s >= 0.0
        for landmark in plan.landmarks:
            assert finite_numbers(landmark), landmark
            assert landmark.radius_mm >= 0.0
        if plan.arch_lps is not None:
            arch = plan.arch_lps
            assert arch.ndim == 2 and arch.shape[1] == 3 and len(arch) >= 2
            assert np.isfinite(arch).all()
            assert (np.linalg.norm(np.diff(arch, axis=0), axis=1) > 0.0).all()
        if plan.implant is not None:
            spec = plan.implant
            assert 0.0 < spec.apex_diameter_mm <= spec.diameter_mm and spec.length_mm > 0.0
            s_mm, r_mm = spec.profile_mm()
            assert np.isfinite(s_mm).all() and np.isfinite(r_mm).all()
    assert len({p.name for p in plans}) == len(plans)


def test_seed_plans_load() -> None:
    """The seeds are valid, so the fuzzing starts from accepted documents."""
    from ctdrill.imaging.plan.load import load_plan, load_plans

    with tempfile.TemporaryDirectory() as tmp:
        plan = load_plan(write_text(Path(tmp) / "p.json", json.dumps(SEED_PLAN)))
        assert plan.planned_depth_mm == pytest.approx(np.linalg.norm([0.5, 1.0, -12.0]))
        assert len(plan.landmarks) == 2
        markups = load_plans(write_text(Path(tmp) / "p.mrk.json", json.dumps(SEED_MARKUPS)))
        np.testing.assert_allclose(markups[0].entry_lps, [10.0, -20.0, 35.0])  # RAS -> LPS
        assert markups[1].implant is not None and markups[0].arch_lps is not None
        both = load_plans(write_text(Path(tmp) / "s.json", json.dumps(SEED_PLAN_SET)))
        assert [p.name for p in both] == ["36", "37"] and len(both[1].drills) == 2
        assert both[0].implant is not None and both[0].arch_lps is not None


@fuzz_settings
@given(text=mutated_json(SEED_PLAN_SET))
def test_fuzz_plan_set_json(text: str) -> None:
    check_plan_text(text, ".json")


@fuzz_settings
@given(text=mutated_json(SEED_PLAN))
def test_fuzz_plan_json(text: str) -> None:
    check_plan_text(text, ".json")


@fuzz_settings
@given(text=mutated_json(SEED_MARKUPS))
def test_fuzz_slicer_markups(text: str) -> None:
    check_plan_text(text, ".mrk.json")


HU_ALL_INT16 = np.arange(-32768, 32768, dtype=np.float64)


def check_calibration_text(text: str) -> None:
    """Load a calibration text: a set whose force law is finite for every int16 HU, or an error."""
    from ctdrill.model import ModelInputError, a0_n, bk_n, load_calibration

    with tempfile.TemporaryDirectory() as tmp:
        path = write_text(Path(tmp) / "cal.json", text)
        try:
            with bounded_memory():
                cal = timed(EXAMPLE_LIMIT_S, lambda: load_calibration(path))
        except ModelInputError as exc:
            assert str(exc).strip() and "\n" not in str(exc).strip()
            return
        except Exception as exc:
            if known_bug(exc) is None:
                raise
            return
    assert finite_numbers(cal), cal
    lo, hi = cal.c_prime_range
    assert 0.0 < lo < hi, cal.c_prime_range
    assert cal.gate_width_hu > 0.0
    try:
        with np.errstate(over="raise", invalid="raise"):  # overflow: a validation gap
            a0 = a0_n(HU_ALL_INT16, 2.0, cal)
            bk = bk_n(HU_ALL_INT16, cal)
    except (OverflowError, FloatingPointError) as exc:
        if known_bug(exc) is None:
            raise
        return
    assert np.isfinite(a0).all() and (a0 >= 0.0).all()
    assert np.isfinite(bk).all()


@fuzz_settings
@given(text=mutated_json(seed_calibration()))
def test_fuzz_calibration_json(text: str) -> None:
    check_calibration_text(text)
