"""Issue 15's hostile inputs, each pinned: exit 2 with one ``error:`` line, or the right result.

Every CLI run is a fresh process under ``RLIMIT_AS`` (2 GiB; a real load needs ~0.4 GiB) and
a timeout, so a hang, a memory bomb or a recursion crash fails the test instead of the run.
The DICOM classes (nested undefined-length sequences, lying RLE lengths) are corpus cases
(``corpus_hostile.py``); here they go through ``export``, ``rehearse`` and the GUI too.
"""

from __future__ import annotations

import csv
import io
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import ASSETS
from tests.robustness.corpus_hostile import NESTED_LEVELS, nested_undefined_sequences
from tests.robustness.outcomes import CliRun, error_line_problems, run_cli_subprocess

DEMO = ASSETS / "demo"
CAP = 2 << 30
TIMEOUT_S = 60.0


def _cli(args: list[str]) -> CliRun:
    return run_cli_subprocess(args, address_space_bytes=CAP, timeout_s=TIMEOUT_S)


def _refused(run: CliRun, *fragments: str) -> str:
    assert not error_line_problems(run), error_line_problems(run)
    for fragment in fragments:
        assert fragment in run.stderr, run.stderr
    return run.stderr


def _export(dicom: Path, plan: Path, out: Path, *extra: str) -> CliRun:
    return _cli(
        [
            "export",
            "--dicom",
            str(dicom),
            "--plan",
            str(plan),
            "--out",
            str(out),
            "--rate-hz",
            "100",
            *extra,
        ]
    )


# -- JSON: calibration sets ------------------------------------------------------------------


def _calibration_doc() -> dict[str, object]:
    doc: dict[str, object] = json.loads(
        (ASSETS / "calibration" / "pine-wood-paper.json").read_text()
    )
    return doc


@pytest.mark.parametrize(
    ("name", "text", "fragment"),
    [
        ("deep.json", "[" * 1000 + "]" * 1000, "nests arrays/objects 1000 deep"),
        ("digits.json", '{"gate_hu": ' + "9" * 4301 + "}", "cannot be read"),
        ("surrogate.json", None, "lone surrogate"),
    ],
    ids=["nested-1000", "int-4301-digits", "lone-surrogate-name"],
)
def test_hostile_calibration_sets_are_refused_in_one_line(
    tmp_path: Path, name: str, text: str | None, fragment: str
) -> None:
    path = tmp_path / name
    if text is None:  # a name no text can hold: a JSON escape of half a surrogate pair
        path.write_text(json.dumps(_calibration_doc()).replace("pine-wood-paper", "\\udcff"))
    else:
        path.write_text(text)
    run = _export(DEMO / "ct", DEMO / "plan.json", tmp_path / "out", "--calibration", str(path))
    _refused(run, str(path), fragment)
    assert not (tmp_path / "out").exists()


# -- special files and huge operator scripts ------------------------------------------------


def _rehearse(tmp_path: Path, operator: str) -> CliRun:
    return _cli(
        [
            "rehearse",
            "--dicom",
            str(DEMO / "ct"),
            "--plan",
            str(DEMO / "plan.json"),
            "--out",
            str(tmp_path / "session"),
            "--operator",
            operator,
            "--duration-s",
            "0.2",
        ]
    )


@pytest.mark.parametrize("kind", ["fifo", "dev-zero", "folder"])
def test_operator_script_that_is_not_a_file_is_refused_without_opening(
    tmp_path: Path, kind: str
) -> None:
    path = {"fifo": tmp_path / "hand.csv", "dev-zero": Path("/dev/zero"), "folder": tmp_path}[kind]
    if kind == "fifo":
        os.mkfifo(path)  # open() would block until a writer comes: forever
    run = _rehearse(tmp_path, f"script:{path}")
    what = {"fifo": "a named pipe (FIFO)", "dev-zero": "a device", "folder": "a folder"}[kind]
    _refused(run, f"{path}: the operator script is {what}, not a regular file")
    assert not (tmp_path / "session").exists()


def test_operator_script_over_the_row_limit_is_refused_before_the_device(tmp_path: Path) -> None:
    from ctdrill.haptics.session import MAX_SCRIPT_ROWS

    path = tmp_path / "hand.csv"
    rows = "".join(f"{i / 1000:.3f},5\n" for i in range(MAX_SCRIPT_ROWS + 1))
    path.write_text("time_s,force_n\n" + rows)
    run = _rehearse(tmp_path, f"script:{path}")
    _refused(run, f"{MAX_SCRIPT_ROWS + 1} rows, more than the {MAX_SCRIPT_ROWS} accepted")
    assert not (tmp_path / "session").exists()


@pytest.mark.parametrize("kind", ["manifest-fifo", "recording-fifo", "recording-dev-zero"])
def test_calibration_recordings_that_are_not_files_are_refused(tmp_path: Path, kind: str) -> None:
    fifo = tmp_path / "pipe.csv"
    os.mkfifo(fifo)
    manifest = fifo
    if kind != "manifest-fifo":
        manifest = tmp_path / "manifest.csv"
        target = "pipe.csv" if kind == "recording-fifo" else "/dev/zero"
        manifest.write_text(f"file,hu,feed_mm_s\n{target},-600,0.4\n")
    out = tmp_path / "cal.json"
    run = _cli(["calibrate", str(manifest), "--rpm", "900", "--blades", "2", "--out", str(out)])
    what = "manifest" if kind == "manifest-fifo" else "recording"
    _refused(run, f"the {what} is a ")
    assert not out.exists()


def test_include_phi_never_opens_a_pipe_beside_the_series(tmp_path: Path) -> None:
    """read_patient_fields opened every file of the folder with pydicom: a FIFO sorted first
    blocked export --include-phi forever."""
    dicom = tmp_path / "ct"
    shutil.copytree(DEMO / "ct", dicom)
    os.mkfifo(dicom / "0000.dcm")
    run = _export(dicom, DEMO / "plan.json", tmp_path / "out", "--include-phi")
    assert run.code == 0, run.stderr
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["patient"]["patient_id"]


# -- file names that are not UTF-8 -------------------------------------------------------------


def test_plan_file_name_that_is_not_utf8_exports_with_a_replacement_character(
    tmp_path: Path,
) -> None:
    """matplotlib failed to draw the title of force.png (a traceback, exit 1)."""
    plans = os.fsencode(tmp_path / "plans")
    os.mkdir(plans)
    plan = os.path.join(plans, b"pl\xffan.json")
    shutil.copyfile(DEMO / "plan.json", plan)
    out = tmp_path / "out"
    run = _export(DEMO / "ct", Path(os.fsdecode(plan)), out)
    assert run.code == 0, run.stderr
    summary = json.loads((out / "summary.json").read_bytes().decode("utf-8"))
    assert summary["plan"] == "pl\ufffdan" and summary["plan_file"] == "pl\ufffdan.json"
    assert (out / "force.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


# -- DICOM through every command --------------------------------------------------------------


@pytest.fixture(scope="module")
def nested_ct(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The demo CT with 1200 nested undefined-length sequences in one slice (43 KB)."""
    dicom = tmp_path_factory.mktemp("nested") / "ct"
    shutil.copytree(DEMO / "ct", dicom)
    path = sorted(dicom.iterdir())[40]
    data = bytearray(path.read_bytes())
    at = data.rfind(b"\xe0\x7f\x10\x00")
    data[at:at] = nested_undefined_sequences(NESTED_LEVELS)
    path.write_bytes(bytes(data))
    return dicom


def test_nested_sequences_export_the_same_tables_as_the_clean_series(
    nested_ct: Path, tmp_path: Path
) -> None:
    clean = _export(DEMO / "ct", DEMO / "plan.json", tmp_path / "clean")
    nested = _export(nested_ct, DEMO / "plan.json", tmp_path / "nested")
    assert clean.code == 0 and nested.code == 0, nested.stderr
    for name in ("force.csv", "profile.csv"):
        assert (tmp_path / "nested" / name).read_bytes() == (tmp_path / "clean" / name).read_bytes()


def test_nested_sequences_rehearse(nested_ct: Path, tmp_path: Path) -> None:
    run = _cli(
        [
            "rehearse",
            "--dicom",
            str(nested_ct),
            "--plan",
            str(DEMO / "plan.json"),
            "--out",
            str(tmp_path / "s"),
            "--operator",
            "push:5",
            "--duration-s",
            "0.3",
        ]
    )
    assert run.code == 0, run.stderr
    rows = list(csv.DictReader(io.StringIO((tmp_path / "s" / "session.csv").read_text())))
    assert len(rows) > 10


@pytest.mark.gui
def test_nested_sequences_open_in_the_gui(nested_ct: Path, tmp_path: Path) -> None:
    shot = tmp_path / "gui.png"
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "ctdrill.app.cli",
            "gui",
            "--dicom",
            str(nested_ct),
            "--plan",
            str(DEMO / "plan.json"),
            "--screenshot",
            str(shot),
            "--quit-after-s",
            "20",
        ],
        capture_output=True,
        text=True,
        timeout=120,
        env={**os.environ, "QT_QPA_PLATFORM": os.environ.get("QT_QPA_PLATFORM", "xcb")},
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "Traceback" not in proc.stderr and "RecursionError" not in proc.stderr
    assert shot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
