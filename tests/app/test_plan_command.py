"""``ctdrill plan`` and ``--plan`` repeated: a Slicer case saved one markup per file."""

from __future__ import annotations

import contextlib
import io
import json
from dataclasses import replace
from pathlib import Path

import numpy as np

from ctdrill.app.cli import main
from ctdrill.imaging.plan.load import load_plan, load_plan_set
from ctdrill.imaging.plan.write import save_plan
from tests.conftest import ASSETS
from tests.imaging.slicer_files import slicer_save, validate_markups

DEMO = ASSETS / "demo"


def _run(argv: list[str]) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(argv)
        except SystemExit as exc:
            code = int(exc.code or 0)
    return code, out.getvalue(), err.getvalue()


def _slicer_case(tmp_path: Path) -> Path:
    """The demo plan after a 3D Slicer load and save: one markup per file in a folder."""
    demo = load_plan(DEMO / "plan.json")
    demo = replace(demo, drill=replace(demo.drill, diameter_mm=3.5), margin_mm=2.5, name="implant")
    mrk = tmp_path / "ctdrill.mrk.json"
    save_plan(demo, mrk)
    case = tmp_path / "case"
    case.mkdir()
    slicer_save(mrk, case)
    return case


def test_plan_merges_a_slicer_case_and_converts_both_ways(tmp_path: Path) -> None:
    case = _slicer_case(tmp_path)
    out_json = tmp_path / "merged.json"
    code, stdout, err = _run(["plan", str(case), "--out", str(out_json)])
    assert code == 0, err
    assert stdout.startswith(f"wrote {out_json} (ctdrill-plan/1): trajectory 'implant'")
    doc = json.loads(out_json.read_text())
    assert doc["format"] == "ctdrill-plan/1" and doc["drill"]["diameter_mm"] == 3.5
    assert doc["margin_mm"] == 2.5
    back = tmp_path / "back.mrk.json"
    code, _, err = _run(["plan", str(out_json), "--out", str(back)])
    assert code == 0, err
    validate_markups(json.loads(back.read_text()))
    (a,) = load_plan_set([case])
    b = load_plan(back)
    assert (a.drill, a.margin_mm, a.name) == (b.drill, b.margin_mm, b.name)
    assert [lm.name for lm in a.landmarks] == [lm.name for lm in b.landmarks]
    # --out OUT as the README writes it: a stem, written as OUT.json (OUT.mrk: markups)
    code, stdout, err = _run(["plan", str(case), "--out", str(tmp_path / "stem")])
    assert code == 0, err
    assert stdout.startswith(f"wrote {tmp_path / 'stem.json'} (ctdrill-plan/1)")
    assert json.loads((tmp_path / "stem.json").read_text()) == doc
    code, stdout, err = _run(["plan", str(case), "--out", str(tmp_path / "stem.mrk")])
    assert code == 0 and "(3D Slicer markups)" in stdout
    validate_markups(json.loads((tmp_path / "stem.mrk.json").read_text()))


def test_plan_refusals(tmp_path: Path) -> None:
    case = _slicer_case(tmp_path)
    code, _, err = _run(["plan", str(case), "--out", str(tmp_path / "x.txt")])
    assert code == 2 and err.startswith("error: --out") and err.count("\n") == 1
    code, _, err = _run(["plan", str(case), "--out", str(tmp_path / "no" / "x.json")])
    assert code == 2 and "does not exist" in err
    canal_only = [p for p in case.iterdir() if p.name != "implant.mrk.json"]
    code, _, err = _run(["plan", *map(str, canal_only), "--out", str(tmp_path / "x.json")])
    assert code == 2 and "no trajectory" in err and err.count("\n") == 1


def test_export_with_repeated_plan_matches_the_single_file(tmp_path: Path) -> None:
    case = _slicer_case(tmp_path)
    files = sorted(case.iterdir())
    merged = tmp_path / "merged.json"
    assert _run(["plan", str(case), "--out", str(merged)])[0] == 0
    outs = []
    for i, args in enumerate([[str(f) for f in files], [str(merged)]]):
        out = tmp_path / f"out{i}"
        argv = ["export", "--dicom", str(DEMO / "ct"), "--out", str(out), "--rate-hz", "100"]
        for a in args:
            argv += ["--plan", a]
        code, _, err = _run(argv)
        assert code == 0, err
        outs.append(json.loads((out / "summary.json").read_text()))
    for key in ("stop_depth_mm", "max_safe_depth_mm", "min_clearance_mm", "planned_depth_mm"):
        assert outs[0][key] == outs[1][key]
    # The 2.5 mm margin and 3.5 mm drill survived the Slicer save: with the defaults (2.0 mm
    # each) the demo stops at 10.8 mm; 0.5 mm more margin alone moves the stop up 0.5 mm.
    assert outs[0]["stop_reason"] == "margin"
    assert outs[0]["stop_depth_mm"] < 10.8 - 0.5


def test_no_landmarks_warns_in_summary_and_terminal(tmp_path: Path) -> None:
    case = _slicer_case(tmp_path)
    line = case / "implant.mrk.json"
    out = tmp_path / "out"
    code, _, err = _run(
        ["export", "--dicom", str(DEMO / "ct"), "--plan", str(line), "--out", str(out)]
    )
    assert code == 0, err
    summary = json.loads((out / "summary.json").read_text())
    codes = [w["code"] for w in summary["warnings"]]
    assert codes.count("no_landmarks") == 1
    assert summary["stop_reason"] == "planned_depth"
    assert "warning: plan 'implant' has no landmark" in err
    rout = tmp_path / "rehearse"
    code, _, err = _run(
        [
            "rehearse",
            "--dicom",
            str(DEMO / "ct"),
            "--plan",
            str(line),
            "--out",
            str(rout),
            "--operator",
            "push:4",
            "--duration-s",
            "0.2",
        ]
    )
    assert code == 0, err
    rehearsed = json.loads((rout / "summary.json").read_text())["warnings"]
    assert "no_landmarks" in [w["code"] for w in rehearsed]
    assert "warning: the plan has no landmark" in err


def test_gui_takes_repeated_plans_and_names_a_missing_one(tmp_path: Path) -> None:
    case = _slicer_case(tmp_path)
    line = case / "implant.mrk.json"
    missing = tmp_path / "canal.mrk.json"
    code, _, err = _run(["gui", "--plan", str(line), "--plan", str(missing)])
    assert (
        code == 2
        and err == f"error: --plan {missing}: no such file; give a plan JSON or .mrk.json\n"
    )


def _canal_seg_nrrd(path: Path, spacing_mm: float = 0.25) -> None:
    """The demo's canal (its true centreline and radius) voxelised on a grid of its own
    (0.25 mm, offset from the CT's), saved as 3D Slicer writes a segmentation (RAS)."""
    import nrrd
    import numpy as np

    truth = json.loads((DEMO / "ground_truth.json").read_text(encoding="utf-8"))
    line = np.asarray(truth["canal"]["centerline_lps"], dtype=np.float64)
    radius = float(truth["canal"]["radius_mm"])
    lo = line.min(axis=0) - radius - 1.0 + 0.1
    n = np.ceil((line.max(axis=0) + radius + 1.0 - lo) / spacing_mm).astype(int) + 1
    i, j, k = np.meshgrid(*(np.arange(m) for m in n), indexing="ij")
    centres = lo + spacing_mm * np.stack([i, j, k], axis=-1).reshape(-1, 3)
    a, b = line[:-1], line[1:]
    best = np.full(len(centres), np.inf)
    for s in range(len(a)):
        ab = b[s] - a[s]
        t = np.clip((centres - a[s]) @ ab / (ab @ ab), 0.0, 1.0)
        best = np.minimum(best, np.linalg.norm(centres - (a[s] + t[:, None] * ab), axis=1))
    inside = (best <= radius).reshape(tuple(n)).astype(np.uint8)  # (i, j, k)
    flip = np.diag([-1.0, -1.0, 1.0])
    header = {
        "space": "right-anterior-superior",
        "space directions": flip * spacing_mm,
        "space origin": flip @ lo,
        "kinds": ["domain"] * 3,
        "encoding": "gzip",
        "Segment0_ID": "Segment_1",
        "Segment0_Name": "IAN canal",
        "Segment0_LabelValue": "1",
        "Segment0_Layer": "0",
    }
    nrrd.write(str(path), inside, header)


def test_slicer_case_with_a_segmented_canal_runs_without_edits(tmp_path: Path) -> None:
    """Done-when of issue 19: a Line saved by Slicer and a segmented canal, separate files."""
    case = _slicer_case(tmp_path)
    (case / "left mandibular canal.mrk.json").unlink()  # the canal is now a segmentation
    _canal_seg_nrrd(case / "Segmentation.seg.nrrd")
    out = tmp_path / "out"
    code, _, err = _run(
        ["export", "--dicom", str(DEMO / "ct"), "--plan", str(case), "--out", str(out)]
    )
    assert code == 0, err
    summary = json.loads((out / "summary.json").read_text())
    assert [w["code"] for w in summary["warnings"] if w["code"] == "no_landmarks"] == []
    assert summary["stop_reason"] == "margin"
    # The same case with the canal as the true tube: the voxelised canal's surface is within
    # half a voxel diagonal (0.22 mm at 0.25 mm) of the tube's, so is the stop.
    tube = tmp_path / "tube"
    (tmp_path / "t").mkdir()
    case2 = _slicer_case(tmp_path / "t")
    code, _, err = _run(
        ["export", "--dicom", str(DEMO / "ct"), "--plan", str(case2), "--out", str(tube)]
    )
    assert code == 0, err
    ref = json.loads((tube / "summary.json").read_text())["stop_depth_mm"]
    assert abs(summary["stop_depth_mm"] - ref) <= 0.25 * 3**0.5 / 2 + 0.05


def test_plan_keeps_every_trajectory_the_arch_and_the_implants(tmp_path: Path) -> None:
    demo = load_plan(DEMO / "plan.json")
    assert demo.arch_lps is not None and demo.implant is not None
    second = replace(
        demo,
        name="second",
        entry_lps=demo.entry_lps + np.array([0.0, 8.0, 0.0]),
        target_lps=demo.target_lps + np.array([0.0, 8.0, 0.0]),
        implant=None,
    )
    first = replace(demo, name="first")
    mrk = tmp_path / "two.mrk.json"
    from ctdrill.imaging.plan.write import write_plans

    write_plans([first, second], mrk)
    out_json = tmp_path / "two.json"
    code, stdout, err = _run(["plan", str(mrk), "--out", str(out_json)])
    assert code == 0, err
    assert stdout == (
        f"wrote {out_json} (ctdrill-plan/1): 2 trajectories ('first', 'second'), 1 landmarks, "
        "the dental arch, 1 implant\n"
    )
    doc = json.loads(out_json.read_text())
    assert [t["name"] for t in doc["trajectories"]] == ["first", "second"]
    assert doc["trajectories"][0]["implant"] == demo.implant.to_json()
    assert doc["arch_mm"] == demo.arch_lps.tolist()
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(doc | {"arch_mm": [[0, 0, 0], [0, 0, 0]]}))
    code, _, err = _run(["plan", str(bad), "--out", str(tmp_path / "x.json")])
    assert (
        code == 2 and err.startswith("error: bad.json: arch_mm[1] repeats") and err.count("\n") == 1
    )


def test_plan_places_a_library_implant_or_one_of_the_users_file(tmp_path: Path) -> None:
    out = tmp_path / "p.json"
    code, _, err = _run(
        ["plan", str(DEMO / "plan.json"), "--out", str(out), "--implant", "parallel 3.3 x 8"]
    )
    assert code == 0, err
    assert json.loads(out.read_text())["implant"] == {
        "name": "parallel 3.3 x 8",
        "diameter_mm": 3.3,
        "length_mm": 8.0,
        "apex_diameter_mm": 3.3,
        "apex": "flat",
        "drills": [  # its generic drilling protocol travels with it
            {"diameter_mm": 2.0, "tip_length_mm": 0.6},
            {"diameter_mm": 2.7, "tip_length_mm": 0.8},
        ],
    }
    mine = tmp_path / "mine.json"
    item = {"name": "ours", "diameter_mm": 4.5, "length_mm": 9, "apex_diameter_mm": 3.5}
    mine.write_text(json.dumps({"format": "ctdrill-implants/1", "implants": [item]}))
    argv = ["plan", str(DEMO / "plan.json"), "--out", str(out), "--implants", str(mine)]
    code, _, err = _run([*argv, "--implant", "ours"])
    assert code == 2 and err == "error: mine.json: implants[0].apex is missing; add it\n"
    mine.write_text(
        json.dumps({"format": "ctdrill-implants/1", "implants": [item | {"apex": "round"}]})
    )
    code, _, err = _run([*argv, "--implant", "ours"])
    assert code == 0, err
    assert load_plan(out).implant is not None and load_plan(out).implant.length_mm == 9.0  # type: ignore[union-attr]
    code, _, err = _run([*argv, "--implant", "nope"])
    assert code == 2 and err.startswith("error: --implant 'nope': no implant of that name")
    assert "'ours'" in err and err.count("\n") == 1
    code, _, err = _run(argv)
    assert code == 2 and err.startswith("error: --implants: give --implant NAME too")


def test_plan_reports_implants_too_close_and_above_the_entry(tmp_path: Path) -> None:
    demo = load_plan(DEMO / "plan.json")
    shift = np.array([0.0, 5.0, 0.0])
    near = replace(
        demo, name="near", entry_lps=demo.entry_lps + shift, target_lps=demo.target_lps + shift
    )
    from ctdrill.imaging.plan.implants import ImplantSpec
    from ctdrill.imaging.plan.write import write_plans

    long = ImplantSpec("long", 4.1, 13.0, 2.9, "round")  # 1 mm longer than the planned depth
    src = tmp_path / "two.json"
    write_plans([replace(demo, name="site", implant=long), near], src)
    code, _, err = _run(["plan", str(src), "--out", str(tmp_path / "out.json")])
    assert code == 0, err
    lines = err.splitlines()
    close = [ln for ln in lines if "are 0.90 mm apart" in ln]
    assert close == [
        "warning: implants of 'site' and 'near' are 0.90 mm apart, less than the 3 mm kept "
        "between implants (gap between their platform-wide bodies); move one of them"
    ]
    above = [ln for ln in lines if "above the entry point" in ln]
    assert len(above) == 1 and "plan 'site': implant 'long' (13 mm)" in above[0]
    assert "1.00 mm above the entry point" in above[0]
