"""ctdrill batch: the manifest, the status table, the cohort table, resume, workers and Dask."""

from __future__ import annotations

import contextlib
import csv
import io
import json
import os
import signal
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from ctdrill.app.batch.run import COHORT_COLUMNS, EXIT_ROWS_FAILED, STATUS_COLUMNS
from ctdrill.app.batch.task import ROW_MARKER
from ctdrill.app.cli import main
from ctdrill.imaging.plan.load import load_plan
from ctdrill.imaging.plan.write import save_plan
from tests.conftest import ASSETS

DEMO = ASSETS / "demo"
FAST = ["--rate-hz", "100"]


def _run(argv: list[str]) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(argv)
        except SystemExit as exc:
            code = int(exc.code or 0)
    return code, out.getvalue(), err.getvalue()


def _csv(path: Path) -> list[dict[str, str]]:
    with path.open(newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


def _cohort(tmp: Path) -> Path:
    """A manifest of three cases on the demo CT (paths relative to the manifest): the demo
    plan, a shifted plan (several trajectories in one folder), and a missing plan."""
    plans = tmp / "plans"
    plans.mkdir()
    demo = load_plan(DEMO / "plan.json")
    save_plan(demo, plans / "demo.json")
    two = plans / "two"
    two.mkdir()
    for k in (1, 2):
        shift = np.array([0.5 * k, 0.0, 0.0])
        save_plan(
            replace(
                demo,
                name=f"shift {k}",
                entry_lps=demo.entry_lps + shift,
                target_lps=demo.target_lps + shift,
            ),
            two / f"s{k}.json",
        )
    ct = os.path.relpath(DEMO / "ct", tmp)
    manifest = tmp / "manifest.csv"
    manifest.write_text(
        f"dicom,plan\n{ct},plans/demo.json\n{ct},plans/missing.json\n{ct},plans/two\n",
        encoding="utf-8",
    )
    return manifest


def _files(out: Path) -> dict[str, bytes]:
    """Every file of a batch's output, by relative path, except the status table's timings."""
    got = {}
    for path in sorted(out.rglob("*")):
        if path.is_file():
            rel = path.relative_to(out).as_posix()
            data = path.read_bytes()
            if rel == "status.csv":
                rows = _csv(path)
                data = json.dumps([{**r, "seconds": "", "resumed": ""} for r in rows]).encode()
            if rel == "batch.json":
                doc = json.loads(data)
                data = json.dumps({k: v for k, v in doc.items() if k != "resumed"}).encode()
            got[rel] = data
    return got


@pytest.mark.parametrize(
    ("text", "expect"),
    [
        (None, "not found"),
        ("", "empty"),
        ("dicom\nct\n", "missing column(s) plan"),
        ("dicom,plan,patient\nct,p.json,x\n", "unknown column(s) 'patient'"),
        ("dicom,plan\n", "no rows below the header"),
        ("dicom,plan\nct,\n", "row 1: column plan is empty"),
        ("dicom,plan\nct,p.json,extra\n", "row 1 has 3 cells"),
        ("id,dicom,plan\na,ct,p.json\na,ct,q.json\n", "rows 1 and 2 have the same id 'a'"),
        ("id,dicom,plan\n../x,ct,p.json\n", "id '../x' must be"),
        (b"dicom,plan\n\xff\xfe,p\n", "not UTF-8"),
    ],
)
def test_bad_manifest_is_one_error_line(
    tmp_path: Path, text: str | bytes | None, expect: str
) -> None:
    manifest = tmp_path / "m.csv"
    if isinstance(text, bytes):
        manifest.write_bytes(text)
    elif text is not None:
        manifest.write_text(text, encoding="utf-8")
    code, out, err = _run(["batch", str(manifest), "--out", str(tmp_path / "o")])
    assert code == 2, err
    assert err.startswith("error: ") and err.count("\n") == 1 and expect in err, err
    assert "m.csv" in err and out == ""
    assert not (tmp_path / "o").exists()


def test_status_table_cohort_table_and_exit_code(tmp_path: Path) -> None:
    manifest = _cohort(tmp_path)
    out = tmp_path / "out"
    code, stdout, err = _run(
        ["batch", str(manifest), "--out", str(out), "--workers", "1", "--no-plot", *FAST]
    )
    assert code == EXIT_ROWS_FAILED, err
    *progress, last = stdout.splitlines()
    assert last == f"batch: 3 rows: 2 ok (0 resumed), 1 failed; status in {out / 'status.csv'}"
    assert [line[:11] for line in progress] == ["batch [1/3]", "batch [2/3]", "batch [3/3]"]
    assert err.startswith("row 2 (0002): error: ") and "missing.json" in err
    status = _csv(out / "status.csv")
    assert tuple(status[0]) == STATUS_COLUMNS
    assert [(s["row"], s["id"], s["status"][:6], s["folder"]) for s in status] == [
        ("1", "0001", "ok", "rows/0001"),
        ("2", "0002", "error:", ""),
        ("3", "0003", "ok", "rows/0003"),
    ]
    assert status[1]["plan"] == "plans/missing.json"
    assert "plans/missing.json: plan file not found" in status[1]["status"]
    assert not (out / "rows" / "0002").exists()
    # the cohort table: every trajectory of the ok rows, values from their own outputs
    cohort = _csv(out / "trajectories.csv")
    assert tuple(cohort[0]) == COHORT_COLUMNS
    assert [(c["row"], c["trajectory"]) for c in cohort] == [
        ("1", "plan"),
        ("3", "shift 1"),
        ("3", "shift 2"),
    ]
    doc = json.loads((out / "rows" / "0001" / "summary.json").read_text(encoding="utf-8"))
    assert doc["plot"] is False and not (out / "rows" / "0001" / "force.png").exists()
    assert cohort[0]["folder"] == "rows/0001"
    assert float(cohort[0]["stop_depth_mm"]) == doc["stop_depth_mm"]
    assert float(cohort[0]["peak_force_n"]) == doc["peak_force_n"]
    row3 = _csv(out / "rows" / "0003" / "trajectories.csv")
    assert [float(r["stop_depth_mm"]) for r in row3] == [
        float(c["stop_depth_mm"]) for c in cohort[1:]
    ]
    marker = json.loads((out / "rows" / "0003" / ROW_MARKER).read_text(encoding="utf-8"))
    assert marker["row"] == 3 and marker["plan"] == "plans/two" and len(marker["fingerprint"]) == 64
    batch = json.loads((out / "batch.json").read_text(encoding="utf-8"))
    assert (batch["rows"], batch["ok"], batch["failed"]) == (3, 2, 1)


def test_workers_and_dask_write_what_the_serial_run_writes(
    tmp_path: Path, shared_data: Path
) -> None:
    """Several series (the demo phantom and a real Philips CT): byte-identical outputs
    (force.png included) from one process, a process pool and a Dask LocalCluster; the
    status tables agree but for the timings."""
    from distributed import LocalCluster

    manifest = _cohort(tmp_path)
    plan = {
        "format": "ctdrill-plan/1",
        "coordinate_system": "RAS",
        "entry_mm": [0.0, -170.0, 766.21],
        "target_mm": [0.0, -215.0, 766.21],
        "landmarks": [
            {
                "name": "canal",
                "kind": "canal",
                "radius_mm": 1.2,
                "points_mm": [[20.0, -205.0, 766.21], [-20.0, -205.0, 766.21]],
            }
        ],
    }
    (tmp_path / "plans" / "philips.json").write_text(json.dumps(plan), encoding="utf-8")
    real = shared_data / "dcmqa_ct_Philips_phantom_notilt_5mm"
    with manifest.open("a", encoding="utf-8") as fh:
        fh.write(f"{real},plans/philips.json\n")
    args = [str(manifest), *FAST]
    code, _, err = _run(["batch", *args, "--out", str(tmp_path / "serial"), "--workers", "1"])
    assert code == EXIT_ROWS_FAILED, err
    code, _, err = _run(["batch", *args, "--out", str(tmp_path / "pool"), "--workers", "2"])
    assert code == EXIT_ROWS_FAILED, err
    with LocalCluster(
        n_workers=1, threads_per_worker=2, processes=False, dashboard_address=None
    ) as cluster:
        code, stdout, err = _run(
            [
                "batch",
                *args,
                "--out",
                str(tmp_path / "dask"),
                "--scheduler",
                cluster.scheduler_address,
            ]
        )
    assert code == EXIT_ROWS_FAILED, err
    assert "3 ok (0 resumed), 1 failed" in stdout
    serial = _files(tmp_path / "serial")
    assert "rows/0001/force.png" in serial and "rows/0003/trajectories.csv" in serial
    real_row = json.loads(serial["rows/0004/summary.json"])
    assert real_row["stop_depth_mm"] == pytest.approx(31.8, abs=1e-3)  # 35 - 1.2 - 2.0
    assert _files(tmp_path / "pool") == serial
    assert _files(tmp_path / "dask") == serial


def test_resume_skips_complete_rows_and_redoes_changed_or_partial_ones(tmp_path: Path) -> None:
    manifest = _cohort(tmp_path)
    out = tmp_path / "out"
    argv = ["batch", str(manifest), "--out", str(out), "--workers", "1", "--no-plot", *FAST]
    assert _run(argv)[0] == EXIT_ROWS_FAILED
    first = _files(out)
    stamp = (out / "rows" / "0001" / "force.csv").stat().st_mtime_ns
    # 1. nothing changed: both ok rows are skipped, their files untouched
    code, stdout, _ = _run(argv)
    assert code == EXIT_ROWS_FAILED and "2 ok (2 resumed)" in stdout
    assert [s["resumed"] for s in _csv(out / "status.csv")] == ["true", "false", "true"]
    assert (out / "rows" / "0001" / "force.csv").stat().st_mtime_ns == stamp
    assert _files(out) == first
    # 2. partial outputs: a row folder without its marker (not written by a whole swap),
    # a staging leftover of a killed run; 3. an edited plan: those rows are redone
    (out / "rows" / "0001" / ROW_MARKER).unlink()
    (out / "rows" / "0001" / "force.csv").write_text("half", encoding="utf-8")
    leftover = out / "rows" / ".0003.ctdrill-new-999999999-abcd"
    leftover.mkdir()
    (leftover / "force.csv").write_text("partial", encoding="utf-8")
    code, stdout, err = _run(argv)
    assert code == EXIT_ROWS_FAILED and "2 ok (1 resumed)" in stdout, err
    assert not leftover.exists()
    assert _files(out) == first
    plan = tmp_path / "plans" / "two" / "s2.json"
    doc = json.loads(plan.read_text(encoding="utf-8"))
    doc["margin_mm"] = 3.0
    plan.write_text(json.dumps(doc), encoding="utf-8")
    code, stdout, _ = _run(argv)
    assert "2 ok (1 resumed)" in stdout
    assert [s["resumed"] for s in _csv(out / "status.csv")] == ["true", "false", "false"]
    cohort = _csv(out / "trajectories.csv")
    assert cohort[2]["trajectory"] == "shift 2" and cohort[2]["binding_margin_mm"] == "3.0"
    # 4. the missing plan appears: the failed row runs and the batch is all ok
    save_plan(load_plan(DEMO / "plan.json"), tmp_path / "plans" / "missing.json")
    code, stdout, _ = _run(argv)
    assert code == 0 and "3 ok (2 resumed), 0 failed" in stdout


def test_killed_batch_resumes_where_it_stopped(tmp_path: Path) -> None:
    manifest = _cohort(tmp_path)
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "ctdrill.app.cli", "batch", str(manifest), "--out", str(out)]
    cmd += ["--workers", "1", "--no-plot", *FAST]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    deadline = time.monotonic() + 240
    marker = out / "rows" / "0001" / ROW_MARKER
    # row 1 is complete once its marker is sealed with its outputs (docs/batch.md, Resume)
    while not (marker.exists() and '"outputs"' in marker.read_text(encoding="utf-8")):
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline
        time.sleep(0.02)
    proc.send_signal(signal.SIGKILL)
    proc.communicate()
    assert not (out / "status.csv").exists()  # killed before the end
    code, _, err = _run(["batch", *cmd[4:]])
    assert code == EXIT_ROWS_FAILED, err
    status = _csv(out / "status.csv")
    assert status[0]["resumed"] == "true" and status[0]["status"] == "ok"
    clean = tmp_path / "clean"
    assert _run(["batch", str(manifest), "--out", str(clean), *cmd[7:]])[0] == EXIT_ROWS_FAILED
    assert _files(out) == _files(clean)


def test_an_out_folder_of_other_files_is_refused(tmp_path: Path) -> None:
    manifest = _cohort(tmp_path)
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("mine", encoding="utf-8")
    code, _, err = _run(["batch", str(manifest), "--out", str(out)])
    assert code == 2 and "notes.txt" in err and err.count("\n") == 1
    code, _, err = _run(["batch", str(manifest), "--out", str(tmp_path / "o"), "--workers", "0"])
    assert code == 2 and "--workers" in err


def test_unreachable_scheduler_is_one_error_line_and_writes_nothing(tmp_path: Path) -> None:
    manifest = _cohort(tmp_path)
    out = tmp_path / "out"
    code, _, err = _run(
        ["batch", str(manifest), "--out", str(out), "--scheduler", "tcp://127.0.0.1:1"]
    )
    assert code == 2 and err.startswith("error: --scheduler tcp://127.0.0.1:1: cannot connect")
    assert err.count("\n") == 1 and not out.exists()


def test_a_drill_sequence_row_has_one_cohort_row_per_drill(tmp_path: Path) -> None:
    from ctdrill.imaging.plan.types import DrillSpec

    drills = (
        DrillSpec(diameter_mm=2.0, tip_length_mm=0.6),
        DrillSpec(diameter_mm=2.8, tip_length_mm=0.84),
    )
    save_plan(load_plan(DEMO / "plan.json").with_drills(drills), tmp_path / "seq.json")
    manifest = tmp_path / "m.csv"
    manifest.write_text(f"id,dicom,plan\nseq,{DEMO / 'ct'},seq.json\n", encoding="utf-8")
    out = tmp_path / "out"
    code, _, err = _run(["batch", str(manifest), "--out", str(out), "--no-plot", *FAST])
    assert code == 0, err
    cohort = _csv(out / "trajectories.csv")
    assert [c["drill_diameter_mm"] for c in cohort] == ["2.0", "2.8"]
    assert [c["folder"] for c in cohort] == ["rows/seq/drill_1", "rows/seq/drill_2"]
    for c in cohort:
        doc = json.loads((out / c["folder"] / "summary.json").read_text(encoding="utf-8"))
        assert float(c["stop_depth_mm"]) == doc["stop_depth_mm"]


def test_progress_on_a_terminal_is_a_rich_bar_and_plain_lines_otherwise() -> None:
    from ctdrill.app.batch.progress import make_progress
    from ctdrill.app.batch.task import RowOutcome

    class Tty(io.StringIO):
        def isatty(self) -> bool:
            return True

    ids = {1: "a", 2: "b"}
    outcomes = [RowOutcome(1, "ok", 0.1), RowOutcome(2, "error: x.json: bad", 0.1)]
    tty = Tty()
    with make_progress(tty, ids) as progress:
        for n, o in enumerate(outcomes, start=1):
            progress(n, 2, o)
    text = tty.getvalue()
    assert "2/2" in text and "row 2 (b): error: x.json: bad" in text
    plain = io.StringIO()
    with make_progress(plain, ids) as progress:
        for n, o in enumerate(outcomes, start=1):
            progress(n, 2, o)
    assert plain.getvalue() == (
        "batch [1/2] row 1 (a): ok\nbatch [2/2] row 2 (b): error: x.json: bad\n"
    )


def test_hu_sigma_and_grey_map_reach_every_row_as_in_export(tmp_path: Path) -> None:
    """``--hu-sigma`` and ``--grey-to-hu`` give each row the files ``ctdrill export`` writes
    with the same options (profile.csv with its band byte for byte); a bad one is one line."""
    manifest = tmp_path / "m.csv"
    manifest.write_text(f"dicom,plan\n{DEMO / 'ct'},{DEMO / 'plan.json'}\n", encoding="utf-8")
    opts = [*FAST, "--calibration", "bone-literature", "--hu-sigma", "30"]
    opts += ["--grey-to-hu", "1,0,0.01,2"]
    code, _, err = _run(["batch", str(manifest), "--out", str(tmp_path / "b"), *opts])
    assert code == 0, err
    export = ["export", "--dicom", str(DEMO / "ct"), "--plan", str(DEMO / "plan.json")]
    code, _, err = _run([*export, "--out", str(tmp_path / "e"), *opts])
    assert code == 0, err
    row = tmp_path / "b" / "rows" / "0001"
    assert (row / "profile.csv").read_bytes() == (tmp_path / "e" / "profile.csv").read_bytes()
    summary = json.loads((row / "summary.json").read_text(encoding="utf-8"))
    assert summary["hu_uncertainty"] is not None and summary["grey_to_hu"] is not None
    lo = [r["mean_force_lo_n"] for r in _csv(row / "profile.csv")]
    assert all(v != "" for v in lo)
    code, _, err = _run(["batch", str(manifest), "--out", str(tmp_path / "c"), "--hu-sigma", "-1"])
    assert code == 2 and err.startswith("error:") and err.count("\n") == 1
    assert not (tmp_path / "c").exists()
