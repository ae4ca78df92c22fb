"""The margin budget: the sourced table, its arithmetic, ``margin_below_budget`` between the
margin and the budget, ``--placement`` and the summary's ``margin_budget_mm``."""

from __future__ import annotations

import contextlib
import io
import json
import math
from dataclasses import replace
from pathlib import Path

import pytest

from ctdrill.app.cli import main
from ctdrill.engine.path import plan_path
from ctdrill.imaging.plan.budget import (
    CANAL_P95_MM,
    PLACEMENT_P95_MM,
    PLACEMENTS,
    ct_p95_mm,
    margin_budget,
)
from ctdrill.imaging.plan.types import PlanInputError
from ctdrill.model.calibration import load_calibration
from tests.app.search import plate
from tests.conftest import ASSETS


def test_the_table_and_its_arithmetic() -> None:
    # mean + 1.645 SD of the cited deviations (docs/margin_budget.md)
    assert PLACEMENT_P95_MM["static"] == pytest.approx(1.28 + 1.645 * 0.46, abs=0.006)
    assert PLACEMENT_P95_MM["freehand"] > PLACEMENT_P95_MM["static"] > PLACEMENT_P95_MM["robot"]
    b = margin_budget("static", "traced", 0.25)
    assert b.budget_mm == pytest.approx(math.sqrt(2.04**2 + 1.3**2 + 0.48**2), abs=1e-9)
    assert 2.4 < b.budget_mm < 2.6  # "about 2.5 mm even with a static guide"
    assert ct_p95_mm(0.5) == pytest.approx(2 * ct_p95_mm(0.25)) and ct_p95_mm(0.1) == 0.48
    assert CANAL_P95_MM["imported"] < CANAL_P95_MM["traced"]
    for mode in PLACEMENTS:  # a coarser CT never lowers the budget
        assert (
            margin_budget(mode, "traced", 0.6).budget_mm
            > margin_budget(mode, "traced", 0.2).budget_mm
        )
    with pytest.raises(ValueError, match="placement must be one of"):
        margin_budget("wand", "traced", 0.3)
    with pytest.raises(PlanInputError, match="placement must be one of"):
        replace(plate.plate_plan(), placement="wand")


def _plan(placement: str):  # type: ignore[no-untyped-def]
    # the final 3.5 mm drill's tip 9.5 mm deep, the canal (r 1 mm) centred 13 mm deep: 2.5 mm
    return replace(plate.plate_plan((plate.canal(-13.0),)), placement=placement)


def test_a_clearance_between_the_margin_and_the_budget_warns() -> None:
    vol, cal = plate.plate_volume(), load_calibration("bone-illustrative")
    plan = _plan("freehand")
    result = plan_path(vol, plan.drilled(len(plan.drills) - 1), cal)
    assert result.plan_clearance_mm == pytest.approx(2.5, abs=0.05)
    (budget,) = result.budgets
    assert budget.budget_mm == pytest.approx(math.sqrt(3.05**2 + 1.3**2 + 0.96**2), abs=1e-9)
    codes = [w.code for w in result.warnings]
    assert "margin_below_budget" in codes and "plan_violates_margin" not in codes
    (msg,) = [w.message for w in result.warnings if w.code == "margin_below_budget"]
    assert "'canal' 2.50 mm" in msg and "placement freehand" in msg
    robot = plan_path(vol, _plan("robot").drilled(2), cal)  # budget 1.9 mm < the 2 mm margin
    assert "margin_below_budget" not in [w.code for w in robot.warnings]


def test_export_writes_the_budget_and_takes_placement(tmp_path: Path) -> None:
    def run(*extra: str) -> dict:  # type: ignore[type-arg]
        out = tmp_path / f"o{len(list(tmp_path.iterdir()))}"
        argv = ["export", "--dicom", str(ASSETS / "demo" / "ct"), "--plan"]
        argv += [str(ASSETS / "demo" / "plan.json"), "--out", str(out), "--no-plot", *extra]
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            assert main(argv) == 0
        return json.loads((out / "summary.json").read_text())

    default, static = run(), run("--placement", "static")
    assert default["margin_budget"]["placement"] == "freehand"
    assert static["margin_budget"]["placement"] == "static"
    assert static["margin_budget_mm"] < default["margin_budget_mm"]
    voxel = default["margin_budget"]["voxel_mm"]
    expect = margin_budget("static", "traced", voxel).budget_mm
    assert static["margin_budget_mm"] == pytest.approx(expect, abs=1e-3)
