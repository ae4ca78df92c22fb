"""Every command on a blind trial: nothing a trainee opens names the class (docs/exercises.md,
"Blind trials and the other commands"; the owner: ctdrill.app.exercise.blind)."""

from __future__ import annotations

import argparse
import json
import re
from pathlib import Path

import pytest

from ctdrill.app.cli import COMMANDS, build_parser, main
from ctdrill.app.exercise.blind import BlindTrialError, blind_guard
from ctdrill.app.exercise.bone_quality import WrittenTrial, write_bone_quality
from ctdrill.app.exercise.trials import BLIND_HIDDEN_KEYS

#: What would name a trial's class: the class as a word, Misch, the classes' words, the hidden
#: fields (HU grading, force band) as keys or CSV columns. A hex hash holding ``d3`` names none.
CLASS_TEXT = re.compile(
    r"\bD[1-5]\b|misch|dense cortical|porous cortical|fine trabecular|"
    + "|".join(rf"\b{k}\b" for k in sorted(BLIND_HIDDEN_KEYS)),
    re.IGNORECASE,
)
DEMO_PLAN = Path(__file__).resolve().parents[2] / "assets" / "demo" / "plan.json"
#: Commands a trial may be run with as they are (blind), the rest of those reading a plan are
#: refused.
RUN_BLIND = {"rehearse", "gui"}


@pytest.fixture(scope="module")
def trial(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, list[WrittenTrial]]:
    root = tmp_path_factory.mktemp("blind")
    written = write_bone_quality(
        root / "trials", trials=2, seed=11, spacing_mm=1.0, key_path=root / "key.json"
    )
    return root / "trials" / "trial-01", root / "key.json", written


def _plan_commands() -> dict[str, argparse.ArgumentParser]:
    """Every subcommand whose parser reads plans (``--plan`` or ``plans``)."""
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    out = {}
    for name in COMMANDS:
        p = sub.choices.get(name)
        if p is None or name == "exercise":  # exercise's --plan names real sites to write
            continue
        if any(a.dest in {"plan", "plans"} for a in p._actions):
            out[name] = p
    return out


def _argv(name: str, p: argparse.ArgumentParser, *, ct: Path, plan: Path, out: Path) -> list[str]:
    """A command line that parses: the CT and plan given, every other required option filled."""
    argv = [name]
    for a in p._actions:
        if a.dest == "dicom" and a.option_strings:
            argv += ["--ct", str(ct)]
        elif a.dest == "plan":
            argv += ["--plan", str(plan)]
        elif a.dest == "plans":
            argv += [str(plan)]
        elif a.dest == "out" and (a.required or not a.option_strings):
            argv += ([a.option_strings[0]] if a.option_strings else []) + [str(out)]
        elif a.required and a.option_strings:
            value = next(iter(a.choices)) if a.choices else "1"
            argv += [a.option_strings[0], str(value)]
    return argv


def _files_text(folder: Path) -> str:
    if not folder.exists():
        return ""
    if folder.is_file():
        return folder.read_bytes().decode("latin-1")
    return "\n".join(
        f.read_bytes().decode("latin-1") for f in sorted(folder.rglob("*")) if f.is_file()
    )


def test_the_sweep_finds_the_commands_that_read_plans() -> None:
    assert {"export", "report", "panorama", "suggest", "teleop", "rehearse", "gui", "plan"} <= set(
        _plan_commands()
    )


@pytest.mark.parametrize("what", ["plan", "ct", "folder"])
def test_every_plan_command_refuses_a_trial_in_one_line_naming_no_class(
    trial: tuple[Path, Path, list[WrittenTrial]],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    what: str,
) -> None:
    folder, _, _ = trial
    ct = folder / "ct"
    # the trial's plan; the trial's CT with another plan; the trial's folder as the plan
    plan = {"plan": folder / "plan.json", "ct": DEMO_PLAN, "folder": folder}[what]
    for name, p in _plan_commands().items():
        if name in RUN_BLIND and what == "plan":
            continue  # run blind: below
        if what == "ct" and not any(a.dest == "dicom" for a in p._actions):
            continue  # reads no CT: the demo plan alone is no trial
        out = tmp_path / f"{name}-{what}-out"
        capsys.readouterr()
        code = main(_argv(name, p, ct=ct, plan=plan, out=out))
        cap = capsys.readouterr()
        lines = cap.err.splitlines()
        assert code == 2, (name, cap.err)
        assert len(lines) == 1 and lines[0].startswith("error: "), (name, cap.err)
        assert "blind trial" in lines[0] and "--key" in lines[0], (name, lines[0])
        assert cap.out == ""
        assert not out.exists() and not out.with_suffix(".json").exists(), name
        assert not CLASS_TEXT.search(cap.err), (name, cap.err)


def test_two_plans_one_of_them_a_trial_are_refused_even_for_the_blind_runs(
    trial: tuple[Path, Path, list[WrittenTrial]], tmp_path: Path
) -> None:
    folder, _, _ = trial
    for name in RUN_BLIND:
        with pytest.raises(BlindTrialError, match="blind trial"):
            blind_guard(name, plans=[folder / "plan.json", DEMO_PLAN], ct=folder / "ct")
    # the trial's own plan alone runs blind
    card = blind_guard("rehearse", plans=[folder / "plan.json"], ct=folder / "ct")
    assert card is not None and card.trial == "trial-01"
    assert blind_guard("export", plans=[DEMO_PLAN], ct=tmp_path) is None


def test_a_trials_ct_copied_elsewhere_is_known_by_its_header(
    trial: tuple[Path, Path, list[WrittenTrial]], tmp_path: Path
) -> None:
    import shutil

    folder, _, _ = trial
    copy = tmp_path / "scan"
    shutil.copytree(folder / "ct", copy)
    with pytest.raises(BlindTrialError, match="a trial's CT"):
        blind_guard("export", plans=[DEMO_PLAN], ct=copy)
    with pytest.raises(BlindTrialError):
        blind_guard("export", plans=[DEMO_PLAN], ct=copy / "CT00000.dcm")
    nested = tmp_path / "deeper" / "scan"
    shutil.copytree(folder / "ct", nested)
    with pytest.raises(BlindTrialError, match="a trial's CT"):
        blind_guard("export", plans=[DEMO_PLAN], ct=tmp_path / "deeper")  # loaders search


def test_a_folder_holding_trials_is_a_trials_ct(
    trial: tuple[Path, Path, list[WrittenTrial]], capsys: pytest.CaptureFixture[str]
) -> None:
    folder, key, _ = trial
    for ct in (folder, folder.parent):  # the trial's folder, the exercise's: loaders search
        with pytest.raises(BlindTrialError, match="blind trial"):
            blind_guard("export", plans=[DEMO_PLAN], ct=ct)
    blind_guard("export", plans=[DEMO_PLAN], ct=folder, key=key)  # one trial: the key opens
    with pytest.raises(BlindTrialError):  # several: from its own folder
        blind_guard("export", plans=[DEMO_PLAN], ct=folder.parent, key=key)


def test_the_instructors_key_runs_the_command_and_a_forged_one_does_not(
    trial: tuple[Path, Path, list[WrittenTrial]],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    folder, key, written = trial
    plan = [folder / "plan.json"]
    assert blind_guard("export", plans=plan, ct=folder / "ct", key=key) is not None
    doc = json.loads(key.read_text())
    cases = {
        "other class": lambda d: d["trials"][0].update(
            misch=next(c for c in ("D1", "D2", "D3", "D4") if c != written[0].misch)
        ),
        "other exercise": lambda d: d.update(exercise_id="x" * 12),
        "other plan": lambda d: d["trials"][0].update(plan_sha256="0" * 64),
        "no trial": lambda d: d.update(trials=[]),
        "other format": lambda d: d.update(format="ctdrill-plan/1"),
        # the exercise's id, trials and classes copied from the cards and a guessed seed
        "guessed seed": lambda d: d["params"].__setitem__(2, d["params"][2] + 1),
        "no parameters": lambda d: d.pop("params"),
    }
    for what, edit in cases.items():
        forged = json.loads(json.dumps(doc))
        edit(forged)
        path = tmp_path / f"{what}.json"
        path.write_text(json.dumps(forged))
        with pytest.raises(BlindTrialError, match="not the instructor's key") as err:
            blind_guard("export", plans=plan, ct=folder / "ct", key=path)
        assert not CLASS_TEXT.search(str(err.value)), what
    # the command line: the instructor's export writes the bone as any export does
    out = tmp_path / "instructor"
    argv = ["export", "--ct", str(folder / "ct"), "--plan", str(plan[0]), "--out", str(out)]
    assert main([*argv, "--key", str(key), "--no-plot"]) == 0
    assert (out / "profile.csv").is_file()
    capsys.readouterr()
    assert main([*argv, "--key", str(tmp_path / "other class.json")]) == 2
    assert len(capsys.readouterr().err.splitlines()) == 1


def test_inspect_on_a_trials_ct_prints_no_class(
    trial: tuple[Path, Path, list[WrittenTrial]], capsys: pytest.CaptureFixture[str]
) -> None:
    folder, _, _ = trial
    for extra in ([], ["--json"], ["--include-phi"]):
        capsys.readouterr()
        assert main(["inspect", str(folder / "ct"), *extra]) == 0
        cap = capsys.readouterr()
        assert "HU" in cap.out or "hu_max" in cap.out
        assert not CLASS_TEXT.search(cap.out + cap.err), extra


def test_the_python_api_and_the_batch_refuse_a_trial(
    trial: tuple[Path, Path, list[WrittenTrial]],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    from ctdrill import api

    folder, _, _ = trial
    with pytest.raises(BlindTrialError, match=r"ctdrill\.api"):
        api.load_plan(folder / "plan.json")
    with pytest.raises(BlindTrialError):
        api.load_ct(folder / "ct")
    with pytest.raises(BlindTrialError):
        api.export_case(folder / "ct", [DEMO_PLAN], tmp_path / "api-out")
    assert not (tmp_path / "api-out").exists()
    manifest = tmp_path / "manifest.csv"
    manifest.write_text(f"id,dicom,plan\nt1,{folder / 'ct'},{folder / 'plan.json'}\n")
    out = tmp_path / "batch"
    assert main(["batch", str(manifest), "--out", str(out), "--workers", "1", "--no-plot"]) == 4
    cap = capsys.readouterr()
    status = (out / "status.csv").read_text()
    assert "blind trial" in status
    assert not (out / "rows" / "t1").exists()
    assert not CLASS_TEXT.search(cap.out + cap.err + status)
    table = (out / "trajectories.csv").read_text().splitlines()
    assert len(table) == 1  # the columns' names only: no trajectory's values


def test_a_blind_session_and_its_assessment_name_no_class(
    trial: tuple[Path, Path, list[WrittenTrial]],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    folder, _, _ = trial
    session = tmp_path / "s1"
    argv = ["rehearse", "--ct", str(folder / "ct"), "--plan", str(folder / "plan.json")]
    argv += ["--out", str(session), "--operator", "push:12", "--duration-s", "1.5"]
    assert main(argv) == 0
    report = tmp_path / "assess"
    db = tmp_path / "record.db"
    assert main(["assess", str(session), "--db", str(db), "--trainee", "ann"]) == 0
    assert main(["assess", "--db", str(db), "--trainee", "ann", "--out", str(report)]) == 0
    cap = capsys.readouterr()
    text = cap.out + cap.err + _files_text(session) + _files_text(report)
    assert (report / "learning_curve.csv").is_file()
    assert not CLASS_TEXT.search(text), CLASS_TEXT.search(text)
