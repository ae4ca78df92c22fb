"""No absolute path, nor a patient-named folder, reaches an output or a record.

The demo case is copied into a folder whose absolute path holds a patient-like name (clinical
exports are often filed so), and every command that writes something runs on it in-process:
every byte it writes (CSV, JSON, PNG, PDF streams inflated, SQLite, NumPy archives inflated) and
every line it prints must be free of that folder's absolute path and of the name. Paths are
shown relative to the output (or the manifest), or as a hash, as ``ctdrill batch`` does.
"""

from __future__ import annotations

import contextlib
import io
import json
import re
import shutil
import zipfile
import zlib
from pathlib import Path

import pydicom
import pytest

from tests.model.synth import write_campaign
from tests.robustness.make_corpus import ROOT
from tests.robustness.outcomes import CliRun, run_cli_in_process

DEMO = ROOT / "assets" / "demo"
#: A folder named as a clinic files a patient: name components and the birth date.
PATIENT = "Doe^Jane 1950-01-01"
TOKENS = ("Doe^Jane", "1950-01-01")
#: The DICOM form of the birth date the series carries (written only with --include-phi).
BIRTH_DICOM = "19500101"


def _inflated(blob: bytes) -> bytes:
    """``blob`` plus the inflated content of its zlib streams (PDF FlateDecode, PNG zTXt/iTXt),
    a PDF's text as a reader extracts it (glyph codes are not the characters), and the members
    of a zip archive (``.npz``)."""
    parts = [blob]
    if blob[:5] == b"%PDF-":
        import pypdf

        reader = pypdf.PdfReader(io.BytesIO(blob))
        parts += [page.extract_text().encode() for page in reader.pages]
        parts.append(repr(reader.metadata).encode())
    if blob[:4] == b"PK\x03\x04":
        with zipfile.ZipFile(io.BytesIO(blob)) as archive:
            parts += [archive.read(name) for name in archive.namelist()]
    for match in re.finditer(rb"stream\r?\n", blob):
        with contextlib.suppress(zlib.error):
            parts.append(zlib.decompressobj().decompress(blob[match.end() :]))
    return b"\n".join(parts)


class Case:
    """The demo's CT and plan inside the patient-named folder, and the leak scan."""

    def __init__(self, base: Path) -> None:
        self.home = base / PATIENT
        self.home.mkdir(parents=True)
        (self.home / f"{PATIENT} CBCT").mkdir()
        for source in sorted((DEMO / "ct").iterdir()):  # the series names the patient too
            ds = pydicom.dcmread(source)
            ds.PatientName = TOKENS[0]
            ds.PatientBirthDate = BIRTH_DICOM
            ds.save_as(self.home / f"{PATIENT} CBCT" / source.name)
        shutil.copy(DEMO / "plan.json", self.home / "plan.json")
        self.ct = str(self.home / f"{PATIENT} CBCT")
        self.plan = str(self.home / "plan.json")
        self.needles = sorted(
            {
                str(self.home),
                str(self.home.resolve()),
                str(base),
                str(base.resolve()),
                *TOKENS,
                BIRTH_DICOM,
            }
        )

    def leaks(self, blob: bytes) -> list[str]:
        data = _inflated(blob)
        return [n for n in self.needles if n.encode() in data]

    def run(self, args: list[str], printed: dict[str, str]) -> CliRun:
        """Run ``ctdrill ARGS`` in-process; its lines that leak go into ``printed``.

        A line may echo a path the user typed (``wrote OUT/force.csv``): the terminal is the
        user's own; any other occurrence (a resolved path, a path read from a file) leaks."""
        result = run_cli_in_process(args)
        assert result.code == 0, (args, result.stderr)
        typed = sorted((a.split(":", 1)[-1] for a in args if "/" in a), key=len, reverse=True)
        for line in (result.stdout + result.stderr).splitlines():
            for arg in typed:
                line = line.replace(arg, "ARG")
            if self.leaks(line.encode()):
                printed.setdefault(" ".join(args[:2]), line)
        return result

    def files_leaking(self, out: Path) -> dict[str, list[str]]:
        root = out if out.is_dir() else out.parent
        found = {}
        for path in sorted([out] if out.is_file() else out.rglob("*")):
            if path.is_file() and (hits := self.leaks(path.read_bytes())):
                found[str(path.relative_to(root))] = hits
        return found


@pytest.fixture
def case(tmp_path: Path) -> Case:
    return Case(tmp_path)


def test_no_output_of_any_command_names_the_patients_folder(case: Case) -> None:
    # outputs outside the patient's folder: a path relative to them would name it
    out = case.home.parent / "out"
    common = ["--ct", case.ct, "--plan", case.plan]
    # inputs named by path beside the CT: a calibration set and an implant library
    calibration = case.home / f"{PATIENT} bone.json"
    shutil.copy(ROOT / "assets" / "calibration" / "bone-illustrative.json", calibration)
    implants = case.home / "my-implants.json"
    shutil.copy(ROOT / "assets" / "implants" / "generic.json", implants)
    key = case.home / "instructor.key"
    runs = {
        "export": ["export", *common, "--out", str(out / "export")],
        "export-cal": [
            "export",
            *common,
            "--out",
            str(out / "export-cal"),
            "--calibration",
            str(calibration),
        ],
        "panorama": ["panorama", *common, "--out", str(out / "panorama")],
        "suggest": [
            "suggest",
            *common,
            "--out",
            str(out / "suggest"),
            "--count",
            "16",
            "--implants",
            str(implants),
        ],
        "plan": ["plan", case.plan, "--out", str(out / "plan" / "merged.json")],
        "plan-mrk": ["plan", case.plan, "--out", str(out / "plan" / "merged.mrk.json")],
        "plan-implant": [
            "plan",
            case.plan,
            "--out",
            str(out / "plan" / "implant.json"),
            "--implant",
            "parallel 3.3 x 8",
            "--implants",
            str(implants),
        ],
        "teleop": [
            "teleop",
            *common,
            "--out",
            str(out / "teleop"),
            "--operator",
            "push:10",
            "--duration-s",
            "0.05",
        ],
        "bone-quality": [
            "exercise",
            "bone-quality",
            "--out",
            str(out / "trials"),
            "--trials",
            "1",
            "--seed",
            "1",
        ],
        "bone-quality-ct": [
            "exercise",
            "bone-quality",
            "--out",
            str(out / "trials-ct"),
            "--trials",
            "2",
            "--seed",
            "1",
            "--ct",
            case.ct,
            "--plan",
            case.plan,
            "--key",
            str(key),
        ],
    }
    script = case.home / "hand.csv"
    script.write_text("time_s,force_n\n0,8\n0.3,8\n", encoding="utf-8")
    for name, operator in (("push", "push:10"), ("script", f"script:{script}")):
        runs[f"rehearse-{name}"] = [
            "rehearse",
            *common,
            "--out",
            str(out / f"rehearse-{name}"),
            "--operator",
            operator,
            "--duration-s",
            "0.3",
        ]
    (out / "plan").mkdir(parents=True)
    (out / "cal").mkdir()
    runs["teleop-script"] = [
        "teleop",
        *common,
        "--out",
        str(out / "teleop-script"),
        "--operator",
        f"script:{script}",
        "--duration-s",
        "0.05",
    ]
    runs["phantom"] = ["phantom", str(out / "phantom"), "--spacing-mm", "0.8"]
    runs["demo"] = ["demo", "--out", str(out / "demo")]
    printed: dict[str, str] = {}
    inputs = set(case.home.parent.rglob("*"))
    for args in runs.values():
        case.run(args, printed)
    db = case.home / "record.sqlite"
    sessions = [str(out / "rehearse-push"), str(out / "rehearse-script")]
    station = case.home / "station.sqlite"  # a second station's record, merged
    case.run(["assess", sessions[0], "--db", str(db), "--trainee", "ann"], printed)
    case.run(["assess", sessions[1], "--db", str(station), "--trainee", "ann"], printed)
    case.run(["assess", "--db", str(db), "--merge", str(station)], printed)
    case.run(["assess", "--db", str(db), "--trainee", "ann", "--out", str(out / "assess")], printed)
    klass = case.home / "class.json"
    klass.write_text(
        json.dumps(
            {
                "format": "ctdrill-class/1",
                "name": "implantology",
                "roster": {"trainees": ["ann"], "experts": []},
                "exercises": [
                    {
                        "name": "guarded demo",
                        "case": case.plan,
                        "mode": "guarded",
                        "pass_mark": 60,
                        "attempts": 3,
                    }
                ],
            }
        ),
        encoding="utf-8",
    )
    inputs.add(klass)
    case.run(
        ["class", "report", "--db", str(db), "--class", str(klass), "--out", str(out / "class")],
        printed,
    )
    manifest = write_campaign(case.home / "campaign", hus=(-700.0, -500.0), feeds=(0.25, 0.5))
    inputs |= set(manifest.parent.rglob("*"))
    calibrate = ["calibrate", str(manifest), "--rpm", "900", "--blades", "2", "--ke", "0.25"]
    case.run(
        [*calibrate, "--out", str(out / "cal" / "cal.json"), "--depth-window-mm", "1", "3"], printed
    )
    inspect = case.run(["inspect", case.ct, "--json"], printed)
    json.loads(inspect.stdout)
    # every file any command wrote (records, keys, journals included), the inputs excepted
    written = [p for p in sorted(case.home.parent.rglob("*")) if p.is_file() and p not in inputs]
    assert len(written) > 50 and key in written and db in written
    leaking = {
        str(p.relative_to(case.home.parent)): hits
        for p in written
        if (hits := case.leaks(p.read_bytes()))
    }
    assert leaking == {}
    assert printed == {}, "\n".join(f"{k}: {v}" for k, v in printed.items())


def test_the_scan_finds_what_include_phi_writes(case: Case) -> None:
    """The positive control: asked for, the patient's name is in the export and found."""
    out = case.home / "phi"
    args = ["export", "--ct", case.ct, "--plan", case.plan, "--out", str(out), "--include-phi"]
    case.run(args, {})
    assert TOKENS[0] in case.files_leaking(out)["summary.json"]


def test_the_report_names_no_patients_folder(case: Case) -> None:
    """The PDF's text, streams and metadata; ``--include-phi`` is the positive control."""
    pdf = case.home / "report.pdf"
    printed: dict[str, str] = {}
    args = ["report", "--ct", case.ct, "--plan", case.plan]
    case.run([*args, "--out", str(pdf), "--include-phi"], printed)
    assert {TOKENS[0], BIRTH_DICOM} <= set(case.files_leaking(pdf)["report.pdf"])
    case.run([*args, "--out", str(pdf)], printed)
    assert printed == {}, "\n".join(f"{k}: {v}" for k, v in printed.items())
    assert case.files_leaking(pdf) == {}


def test_relative_paths_typed_from_above_the_patients_folder(
    case: Case, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Paths typed relative to the working folder (``Doe^Jane .../plan.json``) are not copied
    into the outputs either: they name the patient's folder too."""
    monkeypatch.chdir(case.home.parent)
    script = case.home / "hand.csv"
    script.write_text("time_s,force_n\n0,8\n0.3,8\n", encoding="utf-8")
    ct, plan = f"{PATIENT}/{PATIENT} CBCT", f"{PATIENT}/plan.json"
    common = ["--ct", ct, "--plan", plan]
    printed: dict[str, str] = {}
    hand = ["--operator", f"script:{PATIENT}/hand.csv", "--duration-s", "0.2"]
    case.run(["export", *common, "--out", "out/export"], printed)
    case.run(["rehearse", *common, "--out", "out/rehearse", *hand], printed)
    case.run(["teleop", *common, "--out", "out/teleop", *hand[:2], "--duration-s", "0.05"], printed)
    key = ["--key", "out/instructor.key"]
    bone = ["exercise", "bone-quality", "--out", "out/trials", "--trials", "1", "--seed", "2"]
    case.run([*bone, *common, *key], printed)
    case.run(["assess", "out/rehearse", "--db", "out/record.sqlite", "--trainee", "bo"], printed)
    written = [p for p in sorted(Path("out").rglob("*")) if p.is_file()]
    assert len(written) > 10
    assert {str(p): hits for p in written if (hits := case.leaks(p.read_bytes()))} == {}
    assert printed == {}
