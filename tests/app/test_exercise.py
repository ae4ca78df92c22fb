"""``ctdrill exercise bone-quality``: blind trials, their sealed key, blind sessions, answers."""

from __future__ import annotations

import json
import re
import shutil
import sqlite3
from pathlib import Path

import pydicom
import pytest

from ctdrill.app.cli import main
from ctdrill.app.exercise.bone_quality import TRIAL_CLASSES, WrittenTrial, write_bone_quality
from ctdrill.app.exercise.seal import TOKEN_ALPHABET, SealError, seal, trial_binding, unseal
from ctdrill.app.exercise.trials import BLIND_HIDDEN_KEYS, TRIAL_CARD
from ctdrill.app.rehearse import rehearse

#: What would name a trial's class to a trainee.
CLASS_WORDS = re.compile(r"\bD[1-5]\b|misch", re.IGNORECASE)
PHILIPS = "dcmqa_ct_Philips_phantom_notilt_5mm"


@pytest.fixture(scope="module")
def exercise(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[WrittenTrial]]:
    root = tmp_path_factory.mktemp("exercise")
    trials = write_bone_quality(
        root / "trials", trials=4, seed=5, spacing_mm=1.0, key_path=root / "key.json"
    )
    return root, trials


@pytest.fixture(scope="module")
def blind_session(exercise: tuple[Path, list[WrittenTrial]]) -> Path:
    root, _ = exercise
    trial = root / "trials" / "trial-01"
    out = root / "sessions" / "trial-01"
    rehearse(
        dicom=trial / "ct",
        plan=trial / "plan.json",
        out=out,
        operator="push:12",
        duration_s=1.5,
    )
    return out


def _dicom_text(path: Path) -> str:
    """Every header value of a DICOM file as text (not the pixels)."""
    ds = pydicom.dcmread(path, stop_before_pixels=True)
    return "\n".join(f"{el.keyword}={el.value}" for el in ds.iterall())


def test_trials_are_balanced_and_name_no_class(exercise: tuple[Path, list[WrittenTrial]]) -> None:
    root, trials = exercise
    assert [t.name for t in trials] == ["trial-01", "trial-02", "trial-03", "trial-04"]
    assert sorted(t.misch for t in trials) == list(TRIAL_CLASSES)  # each class once
    for path in sorted((root / "trials").rglob("*")):
        rel = str(path.relative_to(root / "trials"))
        assert not CLASS_WORDS.search(rel), rel
        if path.suffix == ".json":
            assert not CLASS_WORDS.search(path.read_text()), rel
        elif path.suffix == ".dcm":
            assert not CLASS_WORDS.search(_dicom_text(path)), rel
    for path in sorted((root / "trials").rglob("*.json")):  # not even inside a hash
        assert not re.search(r"d[1-5]", path.read_text(), re.IGNORECASE), path
    key = json.loads((root / "key.json").read_text())
    assert [(t["trial"], t["misch"]) for t in key["trials"]] == [(t.name, t.misch) for t in trials]


def test_each_trial_card_opens_to_its_own_class_only(
    exercise: tuple[Path, list[WrittenTrial]],
) -> None:
    root, trials = exercise
    cards = [json.loads((root / "trials" / t.name / TRIAL_CARD).read_text()) for t in trials]
    for t, card in zip(trials, cards, strict=True):
        assert set(card["key"]) <= set(TOKEN_ALPHABET) and "d" not in TOKEN_ALPHABET
        binding = trial_binding(card["exercise_id"], card["trial"], card["plan_sha256"])
        assert unseal(card["key"], binding=binding) == t.misch
        other = cards[(trials.index(t) + 1) % len(cards)]
        with pytest.raises(SealError):  # another trial's key does not open here
            unseal(other["key"], binding=binding)
        edited = card["key"][:-1] + ("0" if card["key"][-1] != "0" else "1")
        with pytest.raises(SealError):
            unseal(edited, binding=binding)


def test_seal_round_trips_and_binds() -> None:
    for label in ("D1", "D4", "x"):
        token = seal(label, binding="a", nonce=bytes(range(15)))
        assert unseal(token, binding="a") == label
        with pytest.raises(SealError):
            unseal(token, binding="b")
    with pytest.raises(SealError):
        unseal("not a token", binding="a")


def test_the_same_seed_writes_the_same_trials(tmp_path: Path) -> None:
    a = write_bone_quality(tmp_path / "a", trials=2, seed=9, spacing_mm=1.0)
    b = write_bone_quality(tmp_path / "b", trials=2, seed=9, spacing_mm=1.0)
    assert [(t.misch, t.card) for t in a] == [(t.misch, t.card) for t in b]
    for name in ("trial-01/plan.json", "trial-02/ct/CT00003.dcm"):
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes()


def test_a_blind_session_hides_the_bone_and_carries_the_card(
    blind_session: Path, exercise: tuple[Path, list[WrittenTrial]]
) -> None:
    text = (blind_session / "summary.json").read_text()
    summary = json.loads(text)
    assert summary["exercise"]["trial"] == "trial-01"
    assert not CLASS_WORDS.search(text)

    def keys(value: object) -> set[str]:
        if isinstance(value, dict):
            return set(value) | {k for v in value.values() for k in keys(v)}
        if isinstance(value, list):
            return {k for v in value for k in keys(v)}
        return set()

    assert not keys(summary) & BLIND_HIDDEN_KEYS


def test_answers_are_recorded_with_the_truth_once(
    blind_session: Path,
    exercise: tuple[Path, list[WrittenTrial]],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    _, trials = exercise
    truth = trials[0].misch
    wrong = next(c for c in TRIAL_CLASSES if c != truth)
    db = tmp_path / "station.db"
    base = ["assess", str(blind_session), "--db", str(db), "--trainee", "ann"]
    assert main([*base, "--answer", wrong.lower()]) == 0
    assert main([*base, "--answer", truth]) == 0  # the first answer stands
    assert "the first answer stands" in capsys.readouterr().out
    with sqlite3.connect(db) as conn:
        rows = conn.execute("SELECT trial, answer, truth FROM answers").fetchall()
        assert conn.execute("SELECT COUNT(*) FROM sessions").fetchone()[0] == 1
    assert rows == [("trial-01", wrong, truth)]
    with sqlite3.connect(db) as conn:  # the record's confusion matrix per trainee
        matrix = conn.execute("SELECT trainee, truth, answer, answers FROM confusion").fetchall()
    assert matrix == [("ann", truth, wrong, 1)]
    for bad in (["--answer", "D5"], ["--answer", "D1", "D2"]):
        assert main([*base, *bad]) == 2
        err = capsys.readouterr().err
        assert err.startswith("error: --answer") and err.count("\n") == 1


def test_a_session_that_is_no_trial_or_a_borrowed_card_is_refused(
    blind_session: Path,
    exercise: tuple[Path, list[WrittenTrial]],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    root, _ = exercise
    borrowed = tmp_path / "borrowed"
    shutil.copytree(blind_session, borrowed)
    summary = json.loads((borrowed / "summary.json").read_text())
    summary["exercise"] = json.loads((root / "trials" / "trial-02" / TRIAL_CARD).read_text())
    (borrowed / "summary.json").write_text(json.dumps(summary))
    argv = ["--answer", "D2", "--db", str(tmp_path / "x.db"), "--trainee", "ann"]
    assert main(["assess", str(borrowed), *argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and err.count("\n") == 1 and "Traceback" not in err
    assert "does not belong to this trial" in err or "trial" in err
    assert not (tmp_path / "x.db").exists()  # every folder checked before the first write
    assert main(["assess", str(root / "trials" / "trial-01"), *argv]) == 2  # not a session
    capsys.readouterr()


def test_an_edited_trial_plan_is_refused(
    exercise: tuple[Path, list[WrittenTrial]], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    root, _ = exercise
    trial = tmp_path / "trial-03"
    shutil.copytree(root / "trials" / "trial-03", trial)
    plan = json.loads((trial / "plan.json").read_text())
    plan["feed_mm_s"] = 0.5
    (trial / "plan.json").write_text(json.dumps(plan))
    argv = ["rehearse", "--ct", str(trial / "ct"), "--plan", str(trial / "plan.json")]
    assert (
        main([*argv, "--out", str(tmp_path / "s"), "--operator", "push:12", "--duration-s", "1"])
        == 2
    )
    err = capsys.readouterr().err
    assert "trial-03" in err and err.count("\n") == 1
    assert not (tmp_path / "s").exists()


def test_bad_options_are_one_error_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "trials"
    base = ["exercise", "bone-quality", "--out", str(out), "--seed", "1"]
    for extra in (
        ["--trials", "0"],
        ["--trials", "2", "--key", str(out / "key.json")],
        ["--trials", "2", "--calibration", "no-such-set"],
        ["--trials", "2", "--plan", "x.json"],
    ):
        assert main([*base, *extra]) == 2
        err = capsys.readouterr().err
        assert err.startswith("error: ") and err.count("\n") == 1, err
    assert not out.exists()


def test_a_real_ct_site_is_a_trial_of_its_own_bone(shared_data: Path, tmp_path: Path) -> None:
    plan = {
        "format": "ctdrill-plan/1",
        "entry_mm": [-4.1, 19.0, 790.0],
        "target_mm": [-4.1, 19.0, 768.0],
        "drill": {"diameter_mm": 2.0, "tip_length_mm": 0.6},
        "landmarks": [{"name": "nerve", "kind": "point", "point_mm": [-4.1, 19.0, 760.0]}],
    }
    (tmp_path / "site.json").write_text(json.dumps(plan))
    trials = write_bone_quality(
        tmp_path / "trials",
        trials=2,
        seed=1,
        spacing_mm=1.0,
        sites=[_site(shared_data / PHILIPS, tmp_path / "site.json")],
    )
    real = [t for t in trials if t.source != "phantom"]
    assert len(real) == 1 and real[0].misch in TRIAL_CLASSES
    folder = tmp_path / "trials" / real[0].name
    header = _dicom_text(next((folder / "ct").iterdir()))
    original = pydicom.dcmread(
        next(p for p in (shared_data / PHILIPS).rglob("*") if p.is_file()),
        stop_before_pixels=True,
        force=True,
    )
    assert str(original.get("PatientID", "")) not in ("", None)
    assert f"PatientID={original.PatientID}" not in header and not CLASS_WORDS.search(header)
    out = tmp_path / "s"
    rehearse(
        dicom=folder / "ct", plan=folder / "plan.json", out=out, operator="push:12", duration_s=1.0
    )
    assert json.loads((out / "summary.json").read_text())["exercise"]["trial"] == real[0].name


def _site(ct: Path, plan: Path) -> object:
    from ctdrill.app.exercise.bone_quality import RealSite

    return RealSite(ct, plan)


def test_a_session_at_an_aid_level_says_so_and_no_wall_is_an_exam(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    demo = Path(__file__).resolve().parents[2] / "assets" / "demo"
    argv = ["rehearse", "--ct", str(demo / "ct"), "--plan", str(demo / "plan.json")]
    argv += ["--operator", "push:12", "--duration-s", "3"]
    assert main([*argv, "--out", str(tmp_path / "a"), "--aids", "no-gauges"]) == 0
    a = json.loads((tmp_path / "a" / "summary.json").read_text())
    assert a["mode"] == "stop-yourself:no-gauges" and a["aids"]["on"] == ["wall"]
    assert a["exam"]["enabled"] is False
    assert main([*argv, "--out", str(tmp_path / "b"), "--aids", "no-wall"]) == 0
    b = json.loads((tmp_path / "b" / "summary.json").read_text())
    assert b["mode"] == "stop-yourself:no-wall" and b["exam"]["enabled"] is True
    assert b["assessment"]["breach"] is True  # 12 N without the wall: into the margin zone
    capsys.readouterr()
    assert main([*argv, "--out", str(tmp_path / "c"), "--aids", "some"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: --aids 'some'") and err.count("\n") == 1
