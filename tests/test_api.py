"""ctdrill.api: the names are there, the import is light, and docs/api.md's example runs."""

from __future__ import annotations

import contextlib
import io
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
NAMES = (
    "load_series",
    "load_ct",
    "load_plan",
    "plan_path",
    "implant_outcome",
    "implant_facts",
    "evaluate_batch",
    "export_case",
    "open_window",
)


def test_the_contract_names_and_the_summary_type() -> None:
    from ctdrill import api
    from ctdrill.engine.summary import TrajectorySummary

    assert set(NAMES) <= set(api.__all__)
    assert all(callable(getattr(api, name)) for name in NAMES)
    assert api.TrajectorySummary is TrajectorySummary
    assert "TrajectorySummary" in dir(api)


def test_importing_the_api_loads_nothing_heavy() -> None:
    code = "import json, sys, ctdrill.api\nprint(json.dumps(sorted(sys.modules)))\n"
    out = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True
    )
    loaded = set(json.loads(out.stdout))
    assert not {m.split(".")[0] for m in loaded} & {"numpy", "scipy", "pydicom", "matplotlib"}


def _example() -> str:
    text = (ROOT / "docs" / "api.md").read_text(encoding="utf-8")
    blocks = re.findall(r"```python\n(.*?)```", text, flags=re.S)
    assert len(blocks) == 1
    return blocks[0]


def test_the_documented_example_runs(tmp_path: Path) -> None:
    from ctdrill import api

    here = os.getcwd()
    os.chdir(tmp_path)
    out = io.StringIO()
    scope: dict[str, object] = {}
    try:
        with contextlib.redirect_stdout(out):
            exec(compile(_example(), "docs/api.md", "exec"), scope)
    finally:
        os.chdir(here)
    text = out.getvalue()
    path, batch, summary = scope["path"], scope["batch"], scope["summary"]
    assert isinstance(path, api.PathResult) and isinstance(batch, api.BatchResult)
    assert isinstance(summary, api.TrajectorySummary)
    # the demo: the canal's margin stops the drill (docs/export.md)
    assert path.stop_reason == "margin" and "stop 10.799 mm (margin)" in text
    # row 0 of the batch is the plan itself: the same engine, the same numbers
    assert batch.refusal[0] is None
    assert batch.stop_depth_mm[0] == path.stop_depth_mm
    m = path.depth_mm.size
    np.testing.assert_array_equal(batch.s0_n[0, :m], path.profile.s0_n)
    assert summary.outcome.feed_mm_s == 0.5 and summary.plot is False
    assert summary.outcome.stop_depth_mm == round(path.stop_depth_mm, 4)
    assert (tmp_path / "api-out" / "summary.json").is_file()
    assert not (tmp_path / "api-out" / "force.png").exists()
    # the demo's implant (tapered 4.1 x 11.5) lies inside the canal's 2 mm margin: every
    # output says so with the same number
    implant = scope["implant"]
    assert isinstance(implant, api.ImplantOutcome) and implant.clearance_mm is not None
    assert "implant_violates_margin" in implant.codes and implant.clearance_mm < 2.0
    assert summary.outcome.implant_clearance_mm == round(implant.clearance_mm, 4)
    assert path.implant is not None
    assert path.implant.clearance_mm == pytest.approx(implant.clearance_mm, abs=1e-9)
    assert path.planned_depth_mm == pytest.approx(12.6, abs=1e-9)  # apex 12 + tip 0.6
    facts = scope["facts"]
    assert isinstance(facts, api.ImplantFacts) and facts.angulation_deg == 0.0
    # the canal's top 12.8 mm below the crest, on the axis (the demo's truth; the noise moves
    # the 150 HU crossing of the crest by hundredths)
    assert facts.bone_height_mm == pytest.approx(12.8, abs=0.1)


def test_a_bad_input_is_the_packages_input_error(tmp_path: Path) -> None:
    from ctdrill import api
    from ctdrill.imaging.errors import ImagingInputError

    with pytest.raises(ImagingInputError):
        api.load_plan(tmp_path / "missing.json")
