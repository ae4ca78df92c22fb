"""ctdrill demo: exports the bundled phantom into a fresh folder, refuses foreign folders."""

from __future__ import annotations

import contextlib
import io
import json
import re
from pathlib import Path

from ctdrill.app.cli import main
from ctdrill.app.export_demo import DEMO_MARKER


def _run(argv: list[str]) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(argv)
    return code, out.getvalue(), err.getvalue()


def test_demo_writes_reruns_and_refuses_foreign_folders(tmp_path: Path) -> None:
    out = tmp_path / "demo-out"
    code, stdout, err = _run(["demo", "--out", str(out)])
    assert (code, err) == (0, "")
    for name in ("force.csv", "profile.csv", "summary.json", "force.png"):
        assert f"wrote {out / name}" in stdout
    stop = re.search(
        r"stop at ([0-9.]+) mm \(margin: 'left mandibular canal', margin 2 mm\) of "
        r"12.600 mm planned; clearance along the planned path 0.2 mm",
        stdout,
    )  # the drill's tip 0.6 mm beyond the implant's apex; one decimal on 0.4 mm voxels
    assert "implant 'tapered 4.1 x 11.5' clearance 0.8 mm to 'left mandibular canal'" in stdout
    assert stop is not None and 10.799 <= float(stop.group(1)) <= 10.8  # truth: 10.8 mm
    # The demo plan goes past its margin on purpose (the stop shows it): the terminal says so.
    assert "warning [plan_violates_margin]: " in stdout
    assert "calibration bone-illustrative (illustrative)" in stdout
    assert (out / DEMO_MARKER).is_file()
    summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    assert summary["stop_reason"] == "margin"
    # a folder made by the demo may be refreshed
    (out / "summary.json").write_text("{}", encoding="utf-8")
    code, _, err = _run(["demo", "--out", str(out)])
    assert (code, err) == (0, "")
    assert json.loads((out / "summary.json").read_text(encoding="utf-8"))["stop_reason"] == "margin"
    # anything else that is not empty is left alone
    foreign = tmp_path / "mine"
    foreign.mkdir()
    (foreign / "notes.txt").write_text("keep me", encoding="utf-8")
    code, stdout, err = _run(["demo", "--out", str(foreign)])
    assert code == 2 and stdout == ""
    assert err.startswith("error: --out ") and "not made by 'ctdrill demo'" in err
    assert err.count("\n") == 1
    assert [p.name for p in foreign.iterdir()] == ["notes.txt"]
