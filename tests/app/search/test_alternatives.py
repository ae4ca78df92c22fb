"""When no axis is feasible, ``suggest`` says what would be: shorter or narrower implants of the
library at the same site (``alternatives.csv``), each checked by the one feasibility rule."""

from __future__ import annotations

import contextlib
import csv
import io
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from ctdrill.app.cli import main
from ctdrill.app.search.alternatives import ALTERNATIVE_COLUMNS, alternative_plan, alternatives
from ctdrill.imaging.plan.implants import implant_placement, load_implant_library
from tests.app.search import plate
from tests.conftest import ASSETS


def test_a_shorter_implant_keeps_the_margin_where_the_planned_one_cannot() -> None:
    vol = plate.plate_volume()
    library = load_implant_library()
    ten = next(s for s in library if s.name == "parallel 4.1 x 10")
    # the 10 mm implant's apex 10.5 mm deep, its 3.5 mm drill's tip 11.5: 1.5 mm above the canal
    base = replace(plate.plate_plan((plate.canal(-14.0),)), target_lps=np.array([0, 0, -10.5]))
    plan = alternative_plan(replace(base, implant=ten, target_lps=base.target_lps), ten)
    alts = alternatives(vol, plan, library)
    names = [a.spec.name for a in alts]
    assert ten.name not in names and all(
        a.spec.length_mm <= 10 and a.spec.diameter_mm <= 4.1 for a in alts
    )
    good = [a for a in alts if a.verdict.feasible]
    assert good and all(a.spec.length_mm == 8.0 for a in good)
    first = alts[0]
    assert first.verdict.feasible and first.spec.diameter_mm == 4.1  # the widest of the longest
    # the platform stays where it was; the apex moves up by the length saved
    p0, p1 = implant_placement(plan), implant_placement(first.plan)
    assert p0 is not None and p1 is not None
    np.testing.assert_allclose(p1.platform_lps, p0.platform_lps, atol=1e-9)
    # its clearances, from the canal's surface (z = -13): drill tip at -9.5, apex at -8.5
    assert first.verdict.drill_clearance_mm == pytest.approx(3.5, abs=0.05)
    assert first.verdict.implant_clearance_mm == pytest.approx(4.5, abs=0.05)
    assert [d.tip_length_mm for d in first.plan.drills] == [0.6, 0.8, 1.0]


def test_suggest_writes_alternatives_when_no_axis_is_feasible(tmp_path: Path) -> None:
    out = tmp_path / "s"
    argv = ["suggest", "--ct", str(ASSETS / "demo" / "ct"), "--plan"]
    argv += [str(ASSETS / "demo" / "plan.json"), "--out", str(out), "--count", "8"]
    text = io.StringIO()
    with contextlib.redirect_stdout(text), contextlib.redirect_stderr(io.StringIO()):
        assert main(argv) == 0
    assert not (out / "best.plan.json").exists()
    with (out / "alternatives.csv").open(newline="") as f:
        rows = list(csv.DictReader(f))
    assert tuple(rows[0]) == ALTERNATIVE_COLUMNS
    good = [r for r in rows if r["feasible"] == "true"]
    assert good and good[0]["length_mm"] == "8"
    assert float(good[0]["implant_clearance_mm"]) >= 2.0
    assert "keeps the 2 mm margin" in good[0]["keeps"]
    assert "alternatives.csv" in text.getvalue()
