"""ctdrill export end to end: the demo phantom, a real series, refusals, privacy, several plans."""

from __future__ import annotations

import contextlib
import csv
import io
import json
import struct
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pydicom
import pytest

from ctdrill.app.cli import main
from ctdrill.app.export import FORCE_COLUMNS, PROFILE_COLUMNS, misch_class
from ctdrill.imaging import load_series
from ctdrill.imaging.plan.load import load_plan
from ctdrill.imaging.plan.types import series_uid_hash
from ctdrill.imaging.plan.write import save_plan
from tests.conftest import ASSETS

DEMO = ASSETS / "demo"
PHILIPS = "dcmqa_ct_Philips_phantom_notilt_5mm"
GE_HEAD = "dcmqa_ct_GE_head_gantrytilt_varspacing"


def _run(argv: list[str]) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(argv)
        except SystemExit as exc:  # argparse usage errors
            code = int(exc.code or 0)
    return code, out.getvalue(), err.getvalue()


def _rows(path: Path) -> tuple[list[str], list[dict[str, str]]]:
    with path.open(newline="", encoding="utf-8") as fh:
        reader = csv.DictReader(fh)
        rows = list(reader)
        return list(reader.fieldnames or []), rows


def _png_size(path: Path) -> tuple[int, int]:
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    assert data[12:16] == b"IHDR"
    width, height = struct.unpack(">II", data[16:24])
    return width, height


def _identifiers(dicom_dir: Path) -> list[str]:
    """PatientName and PatientID of the first DICOM file under ``dicom_dir``."""
    for path in sorted(dicom_dir.rglob("*")):
        if path.suffix in (".txt", ".json", ".md") or not path.is_file():
            continue
        ds = pydicom.dcmread(path, stop_before_pixels=True, force=True)
        if "PatientName" in ds:
            values = [str(ds.PatientName), str(ds.PatientID)]
            return [v for v in values if len(v) >= 3]
    raise AssertionError(f"no DICOM file with a PatientName under {dicom_dir}")


def _assert_private(out: Path, identifiers: list[str]) -> None:
    files = [p for p in out.rglob("*") if p.is_file()]
    assert files
    for path in files:
        data = path.read_bytes()
        for ident in identifiers:
            assert ident.encode() not in data, f"{ident!r} leaked into {path.name}"
            assert ident.replace("^", " ").encode() not in data


@pytest.fixture(scope="module")
def demo_export(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("demo") / "out"
    code, stdout, err = _run(
        [
            "export",
            "--dicom",
            str(DEMO / "ct"),
            "--plan",
            str(DEMO / "plan.json"),
            "--out",
            str(out),
        ]
    )
    assert (code, err) == (0, "")
    wrote = [line for line in stdout.splitlines() if line.startswith("wrote ")]
    assert sorted(line.split()[-1] for line in wrote) == sorted(
        str(out / n) for n in ("force.csv", "profile.csv", "summary.json", "force.png")
    )
    # then the stop, why, and every warning of summary.json, on the terminal
    s = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    rest = stdout.splitlines()[len(wrote) :]
    # the drill is drilled to the implant's apex (12 mm) plus its tip (0.6 mm); clearances
    # printed with one decimal, what 0.4 mm voxels support (+-0.2 mm)
    assert s["clearance_accuracy_mm"] == 0.2
    assert rest[0] == (
        f"plan: stop at {s['stop_depth_mm']:.3f} mm (margin: 'left mandibular canal', margin "
        f"2 mm) of 12.600 mm planned; clearance along the planned path "
        f"{s['plan_clearance_mm']:.1f} mm"
    )
    # the implant body against the canal and in its bone
    walls = s["bone_walls"]
    assert rest[1] == (
        f"plan: implant 'tapered 4.1 x 11.5' clearance {s['implant_clearance_mm']:.1f} mm to "
        f"'left mandibular canal' (margin 2 mm); thinnest bone wall {walls['min_mm']:.1f} mm "
        f"(buccal {walls['buccal_mm']:.1f}, lingual {walls['lingual_mm']:.1f} mm); +-0.2 mm on "
        "this CT"
    )
    # which calibration set, and how it was obtained (the illustrative set has no method)
    assert rest[2] == f"calibration bone-illustrative (illustrative): {s['calibration_source']}"
    assert s["calibration_method"] == "not stated by the set (see its source)"
    assert rest[3] == s["force_band_note"] and s["force_band"] is None  # no covariance: no band
    assert rest[4:] == [f"warning [{w['code']}]: {w['message']}" for w in s["warnings"]]
    return out


def test_demo_summary_matches_the_phantom_truth(demo_export: Path) -> None:
    truth = json.loads((DEMO / "ground_truth.json").read_text(encoding="utf-8"))
    s = json.loads((demo_export / "summary.json").read_text(encoding="utf-8"))
    for key in (
        "planned_depth_mm",
        "stop_depth_mm",
        "stop_reason",
        "max_safe_depth_mm",
        "min_clearance_mm",
        "calibration",
        "warnings",
        "binding_landmark",
        "plan_clearance_mm",
        "extrapolation",
        "hu_grading",
    ):
        assert key in s
    assert s["planned_depth_mm"] == pytest.approx(12.6)  # the apex (the target) + the tip
    assert s["stop_reason"] == "margin"
    assert s["max_safe_depth_mm"] == pytest.approx(truth["max_safe_depth_mm"], abs=1e-3)
    assert s["stop_depth_mm"] <= truth["max_safe_depth_mm"]
    assert s["min_clearance_mm"] == pytest.approx(2.0, abs=1e-3)
    assert s["binding_landmark"]["name"] == "left mandibular canal"
    assert s["binding_landmark"]["margin_mm"] == 2.0
    # the demo plan goes 1.8 mm deeper than the margin allows: it says so (canal at 14 mm,
    # radius 1.2, the drill's tip 0.6 mm beyond the implant's apex at 12 mm: 0.2 mm of
    # clearance along the planned path), and its implant's apex is 0.8 mm from the canal
    assert s["plan_clearance_mm"] == pytest.approx(0.2, abs=1e-3)
    assert s["implant_clearance_mm"] == pytest.approx(0.8, abs=1e-3)
    codes = [w["code"] for w in s["warnings"]]
    assert codes.count("plan_violates_margin") == 2  # the drill's, the implant body's
    assert "implant_violates_margin" in codes
    assert "margin_below_clinical" not in codes and "plan_other_series" not in codes
    assert s["calibration"] == "bone-illustrative" and s["calibration_illustrative"] is True
    assert "calibration_illustrative" in [w["code"] for w in s["warnings"]]
    grading = s["hu_grading"]
    assert sum(grading["misch_share"].values()) == pytest.approx(1.0)
    assert len(grading["segments"]) == 10
    assert grading["segments"][-1]["to_mm"] == pytest.approx(s["stop_depth_mm"], abs=1e-4)
    # below the cortical shell the path runs in D2 trabecular bone (1050 HU)
    assert grading["segments"][-1]["misch"] == "D2"
    assert grading["segments"][-1]["mean_hu"] == pytest.approx(1050.0, abs=15.0)


def test_demo_tables_open_as_csv_and_agree(demo_export: Path) -> None:
    cols, force = _rows(demo_export / "force.csv")
    assert cols[:5] == ["time_s", "depth_mm", "hu", "s_t", "force_n"]
    assert tuple(cols) == FORCE_COLUMNS
    t = np.array([float(r["time_s"]) for r in force])
    x = np.array([float(r["depth_mm"]) for r in force])
    f = np.array([float(r["force_n"]) for r in force])
    np.testing.assert_allclose(np.diff(t), 1e-3, atol=1e-9)  # 1000 Hz default
    np.testing.assert_allclose(x, 0.4 * t, atol=1e-6)  # the plan's feed
    s = json.loads((demo_export / "summary.json").read_text(encoding="utf-8"))
    assert x[-1] <= s["stop_depth_mm"] + 1e-6 and x[-1] > s["stop_depth_mm"] - 0.4e-3
    assert {r["calibration"] for r in force} == {"bone-illustrative"}
    assert np.all(np.isfinite(f)) and f.max() == pytest.approx(s["peak_force_n"], abs=1e-5)
    pcols, prof = _rows(demo_export / "profile.csv")
    assert tuple(pcols) == (*PROFILE_COLUMNS, "mean_force_n", "mean_force_lo_n", "mean_force_hi_n")
    depth = np.array([float(r["depth_mm"]) for r in prof])
    s0 = np.array([float(r["s0_n"]) for r in prof])
    s1 = np.array([float(r["s1_n"]) for r in prof])
    s2 = np.array([float(r["s2_n"]) for r in prof])
    hu = np.array([float(r["hu"]) for r in prof])
    assert depth[-1] == pytest.approx(12.6)  # the drilled depth: the apex + the tip
    assert [r["misch"] for r in prof] == misch_class(hu).tolist()
    # force.csv is Eq. 19 evaluated on profile.csv: S0 (1 + Ke v) + S1 sin(2 pi 30 t) + ...
    want = (
        np.interp(x, depth, s0) * (1 + 0.25 * 0.4)
        + np.interp(x, depth, s1) * np.sin(2 * np.pi * 30.0 * t)
        + np.interp(x, depth, s2) * np.sin(2 * np.pi * 60.0 * t)
    )
    np.testing.assert_allclose(f, want, atol=2e-4)  # 5-decimal CSV rounding
    # mean_force_n is always written: S0 (1 + Ke v), also without a covariance (no band)
    mean = np.array([float(r["mean_force_n"]) for r in prof])
    np.testing.assert_allclose(mean, s0 * (1 + 0.25 * 0.4), atol=2e-5)
    assert {(r["mean_force_lo_n"], r["mean_force_hi_n"]) for r in prof} == {("", "")}
    clearance = np.array([float(r["clearance_mm"]) for r in prof])
    assert np.all(np.diff(clearance) <= 1e-9)


def test_demo_plot_is_a_png(demo_export: Path) -> None:
    assert _png_size(demo_export / "force.png") == (1200, 1000)


def test_no_patient_identifiers_unless_asked(demo_export: Path, tmp_path: Path) -> None:
    idents = _identifiers(DEMO / "ct")
    assert "PHANTOM^MANDIBLE" in idents
    _assert_private(demo_export, idents)
    out = tmp_path / "phi"
    code, _, err = _run(
        [
            "export",
            "--dicom",
            str(DEMO / "ct"),
            "--plan",
            str(DEMO / "plan.json"),
            "--out",
            str(out),
            "--include-phi",
            "--rate-hz",
            "100",
        ]
    )
    assert (code, err) == (0, "")
    patient = json.loads((out / "summary.json").read_text(encoding="utf-8"))["patient"]
    assert patient["patient_name"] == "PHANTOM^MANDIBLE"
    for name in ("force.csv", "profile.csv", "force.png"):
        for ident in idents:
            assert ident.encode() not in (out / name).read_bytes()


def test_real_series_export_and_privacy(shared_data: Path, tmp_path: Path) -> None:
    dicom = shared_data / PHILIPS
    plan: dict[str, Any] = {
        "format": "ctdrill-plan/1",
        "coordinate_system": "RAS",  # LPS (0, 170, 766.21) -> (0, 215, 766.21)
        "entry_mm": [0.0, -170.0, 766.21],
        "target_mm": [0.0, -215.0, 766.21],
        "feed_mm_s": 1.0,
        "landmarks": [
            {
                "name": "canal",
                "kind": "canal",
                "points_mm": [[20.0, -205.0, 766.21], [-20.0, -205.0, 766.21]],
                "radius_mm": 1.2,
            }
        ],
    }
    plan_path = tmp_path / "real.json"
    plan_path.write_text(json.dumps(plan), encoding="utf-8")
    out = tmp_path / "out"
    code, _, err = _run(
        ["export", "--dicom", str(dicom), "--plan", str(plan_path), "--out", str(out)]
    )
    assert (code, err) == (0, "")
    s = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    # canal 35 mm deep across the axis: 35 - 1.2 - 2.0
    assert s["stop_reason"] == "margin"
    assert s["stop_depth_mm"] == pytest.approx(31.8, abs=1e-3)
    # the UID's SHA-256 (as plans record it), never the UID itself without --include-phi
    uid = load_series(dicom).info.series_uid
    assert uid.startswith("1.3.46.670589.33.1.")
    assert s["series_uid"] == s["series_uid_sha256"] == series_uid_hash(uid)
    assert s["include_phi"] is False
    assert uid.encode() not in b"".join(p.read_bytes() for p in out.iterdir())
    _, force = _rows(out / "force.csv")
    f = np.array([float(r["force_n"]) for r in force])
    assert f.max() > 1.0  # the phantom's shell (~700 HU) is cut
    _assert_private(out, _identifiers(dicom))


def test_ge_head_is_refused_across_its_irregular_slices(shared_data: Path, tmp_path: Path) -> None:
    # Index (256, 256, 10) -> (256, 256, 17) crosses the 4 mm -> 1.08 mm -> 7 mm steps.
    plan = {
        "format": "ctdrill-plan/1",
        "entry_mm": [0.0, -5.0, 8.373],
        "target_mm": [0.0, -5.0, 37.913],
    }
    plan_path = tmp_path / "ge.json"
    plan_path.write_text(json.dumps(plan), encoding="utf-8")
    out = tmp_path / "out"
    code, stdout, err = _run(
        [
            "export",
            "--dicom",
            str(shared_data / GE_HEAD),
            "--plan",
            str(plan_path),
            "--out",
            str(out),
        ]
    )
    assert code == 2 and stdout == ""
    assert err.count("\n") == 1 and err.startswith("error: plan 'ge': ")
    # 13 steps of 7 mm after 4 mm ones: wider than 1.5 nominal steps, gaps for the drill
    assert "slice gaps, the first: a slice gap of 6.999 mm between the slices at" in err
    assert "--interpolate-gaps" in err
    assert not out.exists()


@pytest.mark.parametrize(
    ("extra", "fragment"),
    [
        (["--rate-hz", "0"], "--rate-hz must be a positive number"),
        (["--feed-mm-s", "-1"], "--feed-mm-s must be a positive number"),
        (["--calibration", "no-such-set"], "no-such-set"),
    ],
)
def test_bad_options_exit_2_with_one_error_line(
    tmp_path: Path, extra: list[str], fragment: str
) -> None:
    out = tmp_path / "out"
    argv = ["export", "--dicom", str(DEMO / "ct"), "--plan", str(DEMO / "plan.json")]
    code, stdout, err = _run([*argv, "--out", str(out), *extra])
    assert code == 2 and stdout == ""
    assert err.startswith("error: ") and err.count("\n") == 1 and fragment in err
    assert "Traceback" not in err
    assert not out.exists()


def test_bad_plan_and_missing_inputs_exit_2(tmp_path: Path) -> None:
    bad = tmp_path / "bad.json"
    doc = json.loads((DEMO / "plan.json").read_text(encoding="utf-8"))
    doc["drill"]["diameter_mm"] = -2
    bad.write_text(json.dumps(doc), encoding="utf-8")
    out = tmp_path / "out"
    cases = [
        (["--dicom", str(DEMO / "ct"), "--plan", str(bad)], "bad.json: drill.diameter_mm"),
        (["--dicom", str(DEMO / "ct"), "--plan", str(tmp_path / "none.json")], "not found"),
        (["--dicom", str(tmp_path / "nodir"), "--plan", str(DEMO / "plan.json")], "nodir"),
        (["--plan", str(DEMO / "plan.json")], "--dicom"),
    ]
    for args, fragment in cases:
        code, _, err = _run(["export", *args, "--out", str(out)])
        assert code == 2, args
        assert err.startswith("error: ") and err.count("\n") == 1 and fragment in err, err
        assert not out.exists()


def test_several_plans_one_load_subfolders_and_progress(tmp_path: Path) -> None:
    plans = tmp_path / "plans"
    plans.mkdir()
    demo = load_plan(DEMO / "plan.json")
    # Two trajectories (the folder's files merge: the same trajectory twice would be one).
    save_plan(replace(demo, name="implant a"), plans / "a.json")
    save_plan(replace(demo, name="implant b"), plans / "b.mrk.json")
    out = tmp_path / "out"
    code, stdout, err = _run(
        [
            "export",
            "--dicom",
            str(DEMO / "ct"),
            "--plan",
            str(plans),
            "--out",
            str(out),
            "--rate-hz",
            "100",
            "--per-trajectory",
        ]
    )
    assert code == 0, err
    assert "export [" in stdout and "2/2" in stdout  # one line per step: not a terminal
    assert "export [" not in err  # stderr is kept for error and warning lines
    _, table = _rows(out / "trajectories.csv")
    for stem, row in zip(("a", "b"), table, strict=True):
        s = json.loads((out / stem / "summary.json").read_text(encoding="utf-8"))
        assert s["plan_file"] == {"a": "a.json", "b": "b.mrk.json"}[stem]
        assert s["stop_depth_mm"] == pytest.approx(10.8, abs=1e-3)
        assert s["plot"] is True
        assert _png_size(out / stem / "force.png") == (1200, 1000)
        assert row["folder"] == stem and row["trajectory"] == s["plan"]
        assert float(row["stop_depth_mm"]) == s["stop_depth_mm"]
        assert float(row["peak_force_n"]) == s["peak_force_n"]
    assert len([line for line in stdout.splitlines() if line.startswith("wrote ")]) == 9
    stops = [line for line in stdout.splitlines() if ": stop at " in line]
    assert len(stops) == 2 and all("(margin: 'left mandibular canal'" in x for x in stops)
    assert not [p for p in tmp_path.iterdir() if "staging" in p.name]


def test_several_trajectories_write_one_table(tmp_path: Path) -> None:
    """Many trajectories: one row each in trajectories.csv, no folder per trajectory; the
    row's numbers are the summary's (compared with a --per-trajectory export)."""
    plans = tmp_path / "plans"
    plans.mkdir()
    demo = load_plan(DEMO / "plan.json")
    names = []
    for k in range(4):
        shift = np.array([0.4 * k, -0.3 * k, 0.0])
        name = f"cand {k}"
        names.append(name)
        save_plan(
            replace(
                demo,
                name=name,
                entry_lps=demo.entry_lps + shift,
                target_lps=demo.target_lps + shift,
            ),
            plans / f"c{k}.json",
        )
    out = tmp_path / "out"
    base = ["export", "--dicom", str(DEMO / "ct"), "--plan", str(plans), "--rate-hz", "200"]
    code, stdout, err = _run([*base, "--out", str(out), "--no-plot"])
    assert code == 0, err
    assert sorted(p.name for p in out.iterdir()) == ["trajectories.csv"]
    header, rows = _rows(out / "trajectories.csv")
    from ctdrill.app.export_table import TABLE_COLUMNS

    assert tuple(header) == TABLE_COLUMNS
    assert [r["trajectory"] for r in rows] == names
    assert all(r["folder"] == "" for r in rows)
    stops = [line for line in stdout.splitlines() if ": stop at " in line]
    assert len(stops) == 4 and stops[0].startswith("cand 0: stop at 10.799 mm (margin: ")
    full = tmp_path / "full"
    code, stdout_full, err = _run([*base, "--out", str(full), "--per-trajectory", "--no-plot"])
    assert code == 0, err
    # the terminal says the same from the table as from the summaries
    assert stops == [line for line in stdout_full.splitlines() if ": stop at " in line]
    _, rows_full = _rows(full / "trajectories.csv")
    for row, row_full in zip(rows, rows_full, strict=True):
        s = json.loads((full / row_full["folder"] / "summary.json").read_text(encoding="utf-8"))
        assert s["plot"] is False
        assert not (full / row_full["folder"] / "force.png").exists()
        assert {k: v for k, v in row.items() if k != "folder"} == {
            k: v for k, v in row_full.items() if k != "folder"
        }
        assert row["stop_reason"] == s["stop_reason"]
        assert row["max_safe_depth_capped"] == str(s["max_safe_depth_capped"]).lower()
        assert row["binding_landmark"] == s["binding_landmark"]["name"]
        assert float(row["min_clearance_mm"]) == s["min_clearance_mm"]
        assert float(row["entry_x_mm"]) == s["entry_lps"][0]
        shares = [float(row[f"misch_{c}_share"]) for c in ("D1", "D2", "D3", "D4", "D5")]
        assert sum(shares) == pytest.approx(1.0, abs=1e-5)
        assert row["warnings"] == ";".join(w["code"] for w in s["warnings"])


def test_no_plot_single_trajectory(tmp_path: Path) -> None:
    out = tmp_path / "out"
    code, _, err = _run(
        [
            "export",
            "--dicom",
            str(DEMO / "ct"),
            "--plan",
            str(DEMO / "plan.json"),
            "--out",
            str(out),
            "--no-plot",
        ]
    )
    assert code == 0, err
    assert sorted(p.name for p in out.iterdir()) == ["force.csv", "profile.csv", "summary.json"]
    assert json.loads((out / "summary.json").read_text(encoding="utf-8"))["plot"] is False


def test_one_refused_plan_writes_nothing(tmp_path: Path) -> None:
    outside = tmp_path / "outside.json"
    doc = json.loads((DEMO / "plan.json").read_text(encoding="utf-8"))
    doc["entry_mm"] = [200.0, 10.0, -29.0]
    doc["target_mm"] = [200.0, 10.0, -41.0]
    outside.write_text(json.dumps(doc), encoding="utf-8")
    out = tmp_path / "out"
    argv = ["export", "--dicom", str(DEMO / "ct"), "--plan", str(DEMO / "plan.json")]
    code, _, err = _run([*argv, str(outside), "--out", str(out)])
    assert code == 2 and "lies outside the CT volume" in err
    assert not out.exists()
    assert list(tmp_path.iterdir()) == [outside]


def test_edge_cases_no_landmark_and_a_stop_at_the_entry(tmp_path: Path) -> None:
    from ctdrill.app.export import write_exports
    from ctdrill.engine.case import ExportJob
    from ctdrill.engine.path import plan_path
    from ctdrill.engine.settings import ExportSettings
    from ctdrill.engine.summarize import CaseContext
    from ctdrill.imaging.plan.landmarks import PointLandmark
    from ctdrill.imaging.plan.types import Plan
    from ctdrill.imaging.volume import CTVolume, SeriesInfo
    from ctdrill.model.calibration import load_calibration

    hu = np.full((40, 8, 8), 1000, dtype=np.int16)
    hu[:10] = -1000
    affine = np.diag([0.5, 0.5, 0.5, 1.0])
    volume = CTVolume(hu=hu, affine_lps=affine, valid=None, info=SeriesInfo(series_uid="9.9"))
    cal = load_calibration("pine-wood-paper")
    free = Plan(entry_lps=[1.75, 1.75, 2.0], target_lps=[1.75, 1.75, 12.0], name="free")
    blocked = Plan(
        entry_lps=[1.75, 1.75, 2.0],
        target_lps=[1.75, 1.75, 12.0],
        landmarks=(PointLandmark("tooth", [1.75, 1.75, 3.0]),),  # 1 mm ahead: margin 2 mm
        name="blocked",
    )
    jobs = [ExportJob(plan_path(volume, p, cal), p.name) for p in (free, blocked)]
    context = CaseContext(ExportSettings(feed_mm_s=2.0, rate_hz=100.0), series_uid="9.9")
    written = write_exports(jobs, tmp_path / "out", context)
    assert len(written) == 8
    s_free = json.loads((tmp_path / "out" / "free" / "summary.json").read_text(encoding="utf-8"))
    assert s_free["stop_reason"] == "planned_depth" and s_free["stop_depth_mm"] == 10.0
    assert s_free["min_clearance_mm"] is None and s_free["binding_landmark"] is None
    assert s_free["max_safe_depth_mm"] == 20.0 and s_free["max_safe_depth_capped"] is True
    assert s_free["calibration_illustrative"] is False
    _, rows = _rows(tmp_path / "out" / "free" / "force.csv")
    assert len(rows) == 501 and float(rows[-1]["depth_mm"]) == pytest.approx(10.0)
    assert {r["clearance_mm"] for r in rows} == {"inf"}
    s_blk = json.loads((tmp_path / "out" / "blocked" / "summary.json").read_text(encoding="utf-8"))
    assert s_blk["stop_reason"] == "margin" and s_blk["stop_depth_mm"] == 0.0
    assert s_blk["max_safe_depth_capped"] is False
    assert s_blk["min_clearance_mm"] == pytest.approx(1.0)
    assert s_blk["hu_grading"]["segments"][0]["mean_hu"] is None
    _, rows = _rows(tmp_path / "out" / "blocked" / "force.csv")
    assert len(rows) == 1 and float(rows[0]["force_n"]) == 0.0
    assert _png_size(tmp_path / "out" / "blocked" / "force.png") == (1200, 1000)


@pytest.mark.parametrize(
    ("relpath", "fragment"),
    [
        ("single_slice_ct/dicompyler_core/ct.0.dcm", "a single slice is not a volume"),
        ("single_slice_ct/pydicom_data_repo/eCT_Supplemental.dcm", "not Hounsfield units"),
    ],
)
def test_real_files_that_cannot_carry_a_force_map_are_refused(
    shared_data: Path, tmp_path: Path, relpath: str, fragment: str
) -> None:
    out = tmp_path / "out"
    argv = ["export", "--dicom", str(shared_data / relpath), "--plan", str(DEMO / "plan.json")]
    code, stdout, err = _run([*argv, "--out", str(out)])
    assert code == 2 and stdout == ""
    assert err.startswith("error: series ") and err.count("\n") == 1 and fragment in err
    assert not out.exists()
