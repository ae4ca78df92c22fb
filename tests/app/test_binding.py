"""Two landmarks of different margins: the one whose margin sets the stop is the one export
and rehearsal name (issue 13: the stop came from the 2.5 mm landmark while the GUI drew the
0.5 mm line). The GUI's test uses ``PathResult.binding_landmark`` the same way."""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path

import pytest

from ctdrill.app.cli import main
from tests.conftest import ASSETS

DEMO = ASSETS / "demo"
#: The demo canal runs 14 mm below the crest entry, radius 1.2 mm, straight under the axis.
CANAL_DEPTH_MM, CANAL_RADIUS_MM = 14.0, 1.2


def _plan(tmp_path: Path, apex_depth_mm: float) -> Path:
    """The demo plan with the canal's margin 2.5 mm and an apex (margin 0.5 mm) on the axis."""
    doc = json.loads((DEMO / "plan.json").read_text(encoding="utf-8"))
    doc["landmarks"][0]["margin_mm"] = 2.5
    entry = doc["entry_mm"]
    apex = [entry[0], entry[1], entry[2] - apex_depth_mm]  # the axis runs straight down (-S)
    doc["landmarks"].append({"name": "apex", "kind": "point", "point_mm": apex, "margin_mm": 0.5})
    path = tmp_path / f"apex{apex_depth_mm:g}.json"
    path.write_text(json.dumps(doc), encoding="utf-8")
    return path


def _main(argv: list[str]) -> tuple[int, str]:
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = main(argv)
    return code, out.getvalue()


@pytest.mark.parametrize(
    ("apex_depth_mm", "binding", "margin", "stop"),
    [
        # the canal allows 14 - 1.2 - 2.5 = 10.3 mm, the apex 11.5 - 0.5 = 11.0: the canal
        # binds, although the apex is nearer the drill at the stop (1.2 mm against 2.5 mm)
        (11.5, "left mandibular canal", 2.5, CANAL_DEPTH_MM - CANAL_RADIUS_MM - 2.5),
        # the apex at 10 mm allows 9.5 mm: now it binds
        (10.0, "apex", 0.5, 9.5),
    ],
)
def test_export_and_rehearsal_name_the_landmark_that_binds(
    tmp_path: Path, apex_depth_mm: float, binding: str, margin: float, stop: float
) -> None:
    plan = _plan(tmp_path, apex_depth_mm)
    code, stdout = _main(
        ["export", "--dicom", str(DEMO / "ct"), "--plan", str(plan), "--out", str(tmp_path / "x")]
    )
    assert code == 0
    s = json.loads((tmp_path / "x" / "summary.json").read_text(encoding="utf-8"))
    assert s["stop_reason"] == "margin"
    assert s["stop_depth_mm"] == pytest.approx(stop, abs=1e-3) and s["stop_depth_mm"] <= stop
    assert s["binding_landmark"]["name"] == binding
    assert s["binding_landmark"]["margin_mm"] == margin
    assert s["binding_landmark"]["clearance_at_stop_mm"] == pytest.approx(margin, abs=1e-3)
    assert f"(margin: {binding!r}, margin {margin:g} mm)" in stdout
    codes = [w["code"] for w in s["warnings"]]
    assert codes.count("margin_below_clinical") == 1  # the apex's 0.5 mm
    code, _ = _main(
        [
            "rehearse",
            "--dicom",
            str(DEMO / "ct"),
            "--plan",
            str(plan),
            "--out",
            str(tmp_path / "r"),
            "--operator",
            "push:20",
            "--duration-s",
            "0.5",
        ]
    )
    assert code == 0
    r = json.loads((tmp_path / "r" / "summary.json").read_text(encoding="utf-8"))
    assert r["stop_depth_mm"] == pytest.approx(s["stop_depth_mm"], abs=1e-4)  # rounded
    assert r["binding_landmark"]["name"] == binding and r["binding_landmark"]["margin_mm"] == margin
