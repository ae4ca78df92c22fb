"""``ctdrill teleop`` on the demo phantom: files, columns, keys, refusals."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from ctdrill.app.cli import main

ROOT = Path(__file__).resolve().parents[2]
DEMO = ROOT / "assets" / "demo"
COLUMNS = ("time_s", "master_mm", "slave_mm", "env_force_n", "hu_ct", "hu_est", "state")
KEYS = (
    "tracking_rms_um",
    "force_error_pct",
    "passive",
    "hu_rmse_by_layer",
    "boundary_lag_mm",
    "layers_detected",
    "layers_missed",
    "false_alarms",
    "stop_depth_mm",
    "stop_reason",
    "overshoot_mm",
)


def test_teleop_writes_the_session_and_the_summary(tmp_path: Path) -> None:
    out = tmp_path / "out"
    argv = ["teleop", "--ct", str(DEMO / "ct"), "--plan", str(DEMO / "plan.json")]
    argv += ["--out", str(out), "--operator", "push:15", "--duration-s", "0.8"]
    argv += ["--hand-damping", "5", "--delay-ms", "1", "--model-error", "0.1", "--seed", "3"]
    assert main(argv) == 0
    with (out / "session.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert set(COLUMNS) <= set(rows[0])
    assert len(rows) == 800  # 1 kHz
    assert {r["state"] for r in rows} <= {"free", "cutting", "stopped"}
    assert any(r["hu_est"] for r in rows)
    s = json.loads((out / "summary.json").read_text())
    assert set(KEYS) <= set(s)
    assert isinstance(s["passive"], bool)
    for layer in s["hu_rmse_by_layer"]:
        assert {"layer", "rmse_hu", "bias_hu"} <= set(layer)
    assert s["delay_ms"] == 1.0 and s["model_error"] == 0.1


@pytest.mark.parametrize(
    ("extra", "word"),
    [
        (["--delay-ms", "-1"], "--delay-ms"),
        (["--model-error", "nan"], "--model-error"),
        (["--misregister-mm", "50"], "--misregister-mm"),
        (["--misregister-mm", "-10"], "--misregister-mm"),  # the shifted CT leaves the scan
        (["--operator", "shove:3"], "shove"),
    ],
)
def test_bad_input_is_one_error_line_and_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], extra: list[str], word: str
) -> None:
    argv = ["teleop", "--ct", str(DEMO / "ct"), "--plan", str(DEMO / "plan.json")]
    argv += ["--out", str(tmp_path / "o"), "--operator", "push:10", "--duration-s", "0.1", *extra]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error:") and word in err[0]
    assert not (tmp_path / "o").exists()
