"""``ctdrill suggest`` on disk: outputs, the no-feasible case, trajectories, input errors."""

from __future__ import annotations

import csv
import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from ctdrill.app.cli import main
from ctdrill.imaging.phantom.writer import write_series
from ctdrill.imaging.plan.landmarks import PointLandmark
from ctdrill.imaging.plan.load import load_plan
from ctdrill.imaging.plan.write import plan_to_markups, save_plan
from tests.app.search import columns


@pytest.fixture(scope="module")
def case(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("columns")
    vol = columns.columns_volume()
    write_series(root / "ct", np.asarray(vol.hu), vol.affine_lps, series_uid=vol.info.series_uid)
    save_plan(columns.columns_plan(), root / "plan.json")
    guard = PointLandmark(name="guard", point_lps=np.array([0.0, 0.0, -10.5]), margin_mm=8.0)
    save_plan(columns.columns_plan(landmarks=(guard,)), root / "guarded.json")
    return root


@pytest.fixture(scope="module", autouse=True)
def kernels() -> None:
    """The compiled kernels, as `make warmup` leaves them (compiled here if the cache is cold)."""
    from ctdrill import jit
    from ctdrill.app.search.warmup import search_kernels

    jit.warm_up(search_kernels())


def _run(case: Path, out: Path, *extra: str) -> int:
    return main(
        [
            "suggest",
            "--dicom",
            str(case / "ct"),
            "--plan",
            str(case / "plan.json"),
            "--out",
            str(out),
            *extra,
        ]
    )


def test_suggest_writes_the_ranked_table_and_the_best_plan(
    case: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    assert _run(case, out, "--count", "60") == 0
    text = capsys.readouterr().out
    assert f"wrote {out / 'candidates.csv'}" in text and "best: candidate" in text
    assert "planned axis (candidate 0): rank" in text
    assert "ctdrill warmup" not in text  # the kernels are compiled for the tests
    rows = list(csv.DictReader((out / "candidates.csv").open(encoding="utf-8")))
    assert len(rows) == 60 and rows[0]["feasible"] == "true"
    best = load_plan(out / "best.plan.json")
    assert best.entry_lps.tolist() == [float(rows[0][f"entry_{a}_mm"]) for a in "xyz"]
    summary = json.loads((out / "suggest.json").read_text(encoding="utf-8"))
    assert summary["count"] == 60 and summary["best_candidate"] == int(rows[0]["candidate"])
    # A second run replaces the folder (it holds only ctdrill's names) and gives the same table.
    before = (out / "candidates.csv").read_bytes()
    assert _run(case, out, "--count", "60") == 0
    assert (out / "candidates.csv").read_bytes() == before


def test_the_numpy_path_says_so_and_gives_the_same_table(
    case: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    from ctdrill.app.search.warmup import search_kernels

    assert _run(case, tmp_path / "fast", "--count", "30") == 0
    assert "ctdrill warmup" not in capsys.readouterr().out
    for kernel in search_kernels():
        monkeypatch.setattr(kernel, "_ready", False)
    assert _run(case, tmp_path / "slow", "--count", "30") == 0
    assert "run 'ctdrill warmup' once" in capsys.readouterr().out
    fast = (tmp_path / "fast" / "candidates.csv").read_bytes()
    assert (tmp_path / "slow" / "candidates.csv").read_bytes() == fast


def test_warmup_without_numba_is_one_error_line(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("CTDRILL_NO_JIT", "1")
    assert main(["warmup"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: numba is not available") and err.count("\n") == 1


def test_no_feasible_candidate_exits_0_without_a_best_plan(
    case: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    code = main(
        [
            "suggest",
            "--dicom",
            str(case / "ct"),
            "--plan",
            str(case / "guarded.json"),
            "--out",
            str(out),
            "--count",
            "20",
        ]
    )
    assert code == 0
    text = capsys.readouterr().out
    assert "note: no feasible candidate: none of the 20 axes reaches the planned depth" in text
    assert not (out / "best.plan.json").exists()
    assert (out / "candidates.csv").is_file()
    assert json.loads((out / "suggest.json").read_text(encoding="utf-8"))["best_candidate"] is None


def test_trajectory_picks_one_of_several(case: Path, tmp_path: Path) -> None:
    plan = columns.columns_plan()
    other = replace(plan, name="second", entry_lps=np.array([1.0, 0.0, 0.0]),
                    target_lps=np.array([1.0, 0.0, -10.0]))  # fmt: skip
    doc = plan_to_markups(plan)
    doc["markups"].insert(1, plan_to_markups(other)["markups"][0])
    path = tmp_path / "two.mrk.json"
    path.write_text(json.dumps(doc), encoding="utf-8")
    out = tmp_path / "out"
    code = main(
        [
            "suggest",
            "--dicom",
            str(case / "ct"),
            "--plan",
            str(path),
            "--out",
            str(out),
            "--count",
            "5",
            "--trajectory",
            "2",
        ]
    )
    assert code == 0
    rows = list(csv.DictReader((out / "candidates.csv").open(encoding="utf-8")))
    zero = next(r for r in rows if r["candidate"] == "0")
    assert [float(zero[f"entry_{a}_mm"]) for a in "xyz"] == [1.0, 0.0, 0.0]


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--radius-mm", "-1"], "error: --radius-mm must be between 0 and 20 mm"),
        (["--cone-deg", "nan"], "error: --cone-deg must be between 0 and 45 degrees"),
        (["--count", "0"], "error: --count must be a whole number from 1 to 100000"),
        (["--trajectory", "2"], "error: --trajectory 2: the plan files hold 1 trajectories"),
        (["--weights", "1,x,1"], "error: ctdrill suggest: argument --weights"),
        (["--weights", "1,-1,1"], "error: --weights: crest weight must be a number from 0"),
        (["--seed", "-3"], "error: --seed must be a whole number from 0"),
    ],
)
def test_bad_settings_are_one_error_line(
    case: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], extra: list[str], message: str
) -> None:
    try:
        code = _run(case, tmp_path / "out", *extra)
    except SystemExit as exc:  # argparse's own errors
        code = int(exc.code or 0)
    assert code == 2
    err = capsys.readouterr().err
    assert err.startswith(message) and err.count("\n") == 1, err
    assert not (tmp_path / "out").exists()


def test_a_folder_of_other_files_is_refused_untouched(
    case: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("mine", encoding="utf-8")
    assert _run(case, out, "--count", "3") == 2
    err = capsys.readouterr().err
    assert err.startswith("error: --out") and "notes.txt" in err
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt"]


def test_a_missing_series_is_one_error_line(
    tmp_path: Path, case: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code = main(
        [
            "suggest",
            "--dicom",
            str(tmp_path / "none"),
            "--plan",
            str(case / "plan.json"),
            "--out",
            str(tmp_path / "out"),
        ]
    )
    assert code == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and err.count("\n") == 1
