"""No patient identifier reaches any output unless ``--include-phi`` asks for it.

The demo phantom is rewritten with known identifiers (name, ID, birth date, accession number,
institution, referring physician) into a folder named after the patient, as clinical exports
often are; ``inspect --json``, ``export`` and ``rehearse`` must not print or write any of them
(nor the folder name). ``export --include-phi`` is the positive control: the scan finds them.
"""

from __future__ import annotations

from pathlib import Path

import pydicom
import pytest

from tests.robustness.make_corpus import PHI, ROOT
from tests.robustness.outcomes import run_cli_in_process

DEMO = ROOT / "assets" / "demo"
PATIENT_FOLDER = "Quarantotto_Ermenegilda"
#: A SeriesInstanceUID as a site would mint it (root, scanner, date): never in an output
#: without --include-phi.
SERIES_UID = "1.2.826.0.1.3680043.8.498.19540817.73395121"


def phi_tokens() -> list[str]:
    """Every identifier, its name components and the birth date in ISO form."""
    tokens = set(PHI.values())
    for key in ("PatientName", "ReferringPhysicianName"):
        tokens.update(PHI[key].split("^"))
    birth = PHI["PatientBirthDate"]
    tokens.add(f"{birth[:4]}-{birth[4:6]}-{birth[6:]}")
    tokens.add(PATIENT_FOLDER)
    tokens.add(SERIES_UID)
    return sorted(tokens)


def leaks(blob: bytes) -> list[str]:
    """The identifiers found in ``blob`` (bytes of any output, case-insensitive)."""
    low = blob.lower()
    return [t for t in phi_tokens() if t.lower().encode() in low]


@pytest.fixture(scope="module")
def series_with_phi(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("phi") / PATIENT_FOLDER
    folder.mkdir()
    for source in sorted((DEMO / "ct").iterdir()):
        ds = pydicom.dcmread(source)
        for keyword, value in PHI.items():
            setattr(ds, keyword, value)
        # free text that often holds a name, and a UID that identifies the scan world-wide
        ds.StudyDescription = "Implant planning Quarantotto"
        ds.SeriesDescription = "CBCT Ermenegilda mandible"
        ds.SeriesInstanceUID = SERIES_UID
        ds.save_as(folder / source.name)
    ds = pydicom.dcmread(next(folder.iterdir()))
    assert str(ds.PatientName) == PHI["PatientName"]  # the input really carries them
    return folder


def files_leaking(out: Path) -> dict[str, list[str]]:
    """Output files (relative name -> identifiers found), only those that leak."""
    found = {}
    for path in sorted(out.rglob("*")):
        if path.is_file() and (hits := leaks(path.read_bytes())):
            found[path.name] = hits
    return found


def test_inspect_json_prints_no_identifier(series_with_phi: Path) -> None:
    run = run_cli_in_process(["inspect", str(series_with_phi), "--json"])
    assert run.code == 0, run.stderr
    assert not leaks((run.stdout + run.stderr).encode())
    plain = run_cli_in_process(["inspect", str(series_with_phi)])
    assert plain.code == 0 and not leaks((plain.stdout + plain.stderr).encode())


def test_export_writes_no_identifier(series_with_phi: Path, tmp_path: Path) -> None:
    out = tmp_path / "export"
    args = ["export", "--dicom", str(series_with_phi), "--plan", str(DEMO / "plan.json")]
    run = run_cli_in_process([*args, "--out", str(out)])
    assert run.code == 0, run.stderr
    assert {"force.csv", "profile.csv", "summary.json", "force.png"} <= {
        p.name for p in out.iterdir()
    }
    assert files_leaking(out) == {}
    assert not leaks((run.stdout + run.stderr).encode())
    # positive control: asked for, the identifiers are there and the scan sees them
    with_phi = tmp_path / "with_phi"
    run = run_cli_in_process([*args, "--out", str(with_phi), "--include-phi"])
    assert run.code == 0, run.stderr
    found = files_leaking(with_phi)
    assert "summary.json" in found
    assert PHI["PatientID"] in found["summary.json"] and SERIES_UID in found["summary.json"]


def test_inspect_include_phi_is_the_positive_control(series_with_phi: Path) -> None:
    run = run_cli_in_process(["inspect", str(series_with_phi), "--json", "--include-phi"])
    assert run.code == 0, run.stderr
    found = leaks(run.stdout.encode())
    assert {SERIES_UID, "Quarantotto", "Ermenegilda"} <= set(found)


def test_rehearse_writes_no_identifier(series_with_phi: Path, tmp_path: Path) -> None:
    out = tmp_path / "rehearse"
    run = run_cli_in_process(
        [
            "rehearse",
            "--dicom",
            str(series_with_phi),
            "--plan",
            str(DEMO / "plan.json"),
            "--out",
            str(out),
            "--operator",
            "push:10",
            "--duration-s",
            "0.2",
        ]
    )
    assert run.code == 0, run.stderr
    assert {"session.csv", "summary.json"} <= {p.name for p in out.iterdir()}
    assert files_leaking(out) == {}
    assert not leaks((run.stdout + run.stderr).encode())


def test_batch_tables_carry_no_absolute_path_nor_the_patients_folder(
    series_with_phi: Path, tmp_path: Path
) -> None:
    """A manifest naming the series and a plan by absolute paths inside a folder named after
    the patient (and a row whose error names a missing file there): ``status.csv``,
    ``trajectories.csv`` and ``batch.json`` show paths relative to the manifest or hashed."""
    plan_dir = series_with_phi.parent / f"{PATIENT_FOLDER}_plans"
    plan_dir.mkdir(exist_ok=True)
    plan = plan_dir / "plan.json"
    plan.write_bytes((DEMO / "plan.json").read_bytes())
    cohort = tmp_path / "cohort"
    cohort.mkdir()
    (cohort / "local.json").write_bytes((DEMO / "plan.json").read_bytes())
    manifest = cohort / "manifest.csv"
    manifest.write_text(
        "id,dicom,plan\n"
        f"a,{series_with_phi},{plan}\n"
        f"b,{series_with_phi},{plan_dir / 'missing.json'}\n"
        f"c,{series_with_phi},local.json\n",
        encoding="utf-8",
    )
    out = tmp_path / "out"
    calibration = plan_dir / "cal.json"
    calibration.write_bytes(
        (ROOT / "assets" / "calibration" / "bone-illustrative.json").read_bytes()
    )
    fast = ["--no-plot", "--rate-hz", "100", "--calibration", str(calibration)]
    run = run_cli_in_process(["batch", str(manifest), "--out", str(out), *fast])
    assert run.code == 4, run  # row b fails: its plan is missing
    roots = {str(series_with_phi.parent), str(tmp_path), str(ROOT)}
    for name in ("status.csv", "trajectories.csv", "batch.json"):
        text = (out / name).read_text(encoding="utf-8")
        assert not leaks(text.encode()), (name, leaks(text.encode()))
        assert not [r for r in roots if r in text], (name, text)
    status = (out / "status.csv").read_text(encoding="utf-8")
    assert "local.json" in status and "sha256:" in status  # inside: relative; outside: hashed
    rows = status.splitlines()
    hashed = rows[2].split(",")[3]
    assert hashed.startswith("sha256:") and f"{hashed}: plan file not found" in rows[2]
