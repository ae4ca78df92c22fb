"""Grades and confusion matrices of a class: pure functions of the record's rows.

An **attempt** at an exercise:

* ``bone-quality``: one exercise's set of blind trials (its ``exercise_id``) a trainee answered;
  its score is the share of those trials whose class the trainee named right, %;
* every other mode: one session whose ``mode`` is the exercise's (a stop-yourself level's is
  ``stop-yourself:LEVEL``), on the exercise's case (plan hash) and calibration when it names
  them; its score is the session's.

A trainee's attempts are taken in time order; the first ``attempts`` (the class file's
allowance) are graded: ``best`` and ``last`` are the best and the last of those scores, and
``passed`` says the best reached the pass mark. Later attempts are counted
(``over_allowance``) and not graded. Sessions that ended on a fault of the device or its link
(not the trainee's) are no attempt (``faulted``).
"""

from __future__ import annotations

from collections.abc import Collection, Mapping, Sequence
from typing import Any

from ctdrill.app.classroom.class_file import ClassExercise, ClassFile
from ctdrill.app.exercise.bone_quality import BONE_QUALITY, TRIAL_CLASSES
from ctdrill.app.trainee.answers import confusion

#: ``grades.csv``'s columns.
GRADE_COLUMNS = (
    "trainee",
    "exercise",
    "mode",
    "attempts",
    "attempts_allowed",
    "over_allowance",
    "faulted",
    "best",
    "last",
    "pass_mark",
    "passed",
)
#: ``confusion.csv``'s columns: per (scope, trainee, truth), how often each class was named.
CONFUSION_COLUMNS = (
    "exercise",
    "scope",
    "trainee",
    "truth",
    *(f"answered_{c}" for c in TRIAL_CLASSES),
    "trials",
    "correct",
    "correct_pct",
)


def session_mode(row: Mapping[str, Any], blind: Collection[str] = ()) -> str:
    """The session's mode: ``bone-quality`` for a blind trial's (its hash in ``blind``: the
    answered sessions), else the record's ``mode`` where it has one, else ``exam`` or
    ``guarded``."""
    if row.get("session_hash") in blind:
        return BONE_QUALITY
    mode = row.get("mode")
    if isinstance(mode, str) and mode:
        return mode
    return "exam" if row.get("exam") else "guarded"


def device_faulted(row: Mapping[str, Any]) -> bool:
    """The session ended on a fault the device or its link caused, not the trainee (the
    record's ``device_fault``, :mod:`ctdrill.app.trainee.kinds`)."""
    return bool(row.get("device_fault"))


def _matches(ex: ClassExercise, row: Mapping[str, Any], blind: Collection[str]) -> bool:
    if session_mode(row, blind) != ex.session_mode:
        return False
    if ex.plan_sha256 is not None and row.get("plan_hash") != ex.plan_sha256:
        return False
    return ex.calibration is None or row.get("calibration") == ex.calibration


def attempts_of(
    ex: ClassExercise,
    trainee: str,
    sessions: Sequence[Mapping[str, Any]],
    answers: Sequence[Mapping[str, Any]],
) -> tuple[list[float], int]:
    """``(scores of the trainee's attempts in time order, sessions left out as faulted)``."""
    if ex.mode == BONE_QUALITY:
        by_set: dict[str, list[bool]] = {}
        for a in answers:
            if a["trainee"] == trainee and a["exercise"] == BONE_QUALITY:
                by_set.setdefault(str(a["exercise_id"]), []).append(a["answer"] == a["truth"])
        return [round(100.0 * sum(v) / len(v), 1) for v in by_set.values()], 0
    blind = {str(a["session_hash"]) for a in answers}
    mine = [s for s in sessions if s["trainee"] == trainee and _matches(ex, s, blind)]
    faulted = [s for s in mine if device_faulted(s)]
    return [float(s["score"]) for s in mine if not device_faulted(s)], len(faulted)


def grade_rows(
    cls: ClassFile,
    sessions: Sequence[Mapping[str, Any]],
    answers: Sequence[Mapping[str, Any]],
) -> list[dict[str, Any]]:
    """One row per trainee and exercise (:data:`GRADE_COLUMNS`), in roster and class-file
    order; ``best``, ``last`` None without an attempt."""
    rows = []
    for trainee in cls.trainees:
        for ex in cls.exercises:
            scores, faulted = attempts_of(ex, trainee, sessions, answers)
            graded = scores[: ex.attempts]
            best = max(graded) if graded else None
            rows.append(
                {
                    "trainee": trainee,
                    "exercise": ex.name,
                    "mode": ex.session_mode,
                    "attempts": len(scores),
                    "attempts_allowed": ex.attempts,
                    "over_allowance": max(0, len(scores) - ex.attempts),
                    "faulted": faulted,
                    "best": best,
                    "last": graded[-1] if graded else None,
                    "pass_mark": ex.pass_mark,
                    "passed": best is not None and best >= ex.pass_mark,
                }
            )
    return rows


def confusion_rows(cls: ClassFile, answers: Sequence[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """The bone-quality exercises' confusion matrices (:data:`CONFUSION_COLUMNS`): per trainee
    of the roster, then for the class (its trainees together, scope ``class``), one row per
    true class."""
    rows: list[dict[str, Any]] = []
    mine = [a for a in answers if a["exercise"] == BONE_QUALITY and a["trainee"] in cls.trainees]
    for ex in cls.exercises:
        if ex.mode != BONE_QUALITY:
            continue
        scopes: list[tuple[str, str | None, list[Mapping[str, Any]]]] = [
            ("trainee", t, [a for a in mine if a["trainee"] == t]) for t in cls.trainees
        ]
        scopes.append(("class", None, mine))
        for scope, trainee, group in scopes:
            counts = confusion(group)
            for truth in TRIAL_CLASSES:
                named = {c: counts[(truth, c)] for c in TRIAL_CLASSES}
                trials = sum(named.values())
                rows.append(
                    {
                        "exercise": ex.name,
                        "scope": scope,
                        "trainee": trainee,
                        "truth": truth,
                        **{f"answered_{c}": n for c, n in named.items()},
                        "trials": trials,
                        "correct": named[truth],
                        "correct_pct": round(100.0 * named[truth] / trials, 1) if trials else None,
                    }
                )
    return rows


def class_confusion(
    cls: ClassFile, answers: Sequence[Mapping[str, Any]]
) -> dict[tuple[str, str], int]:
    """The class's confusion counts (its trainees' bone-quality answers together)."""
    return confusion(
        [a for a in answers if a["exercise"] == BONE_QUALITY and a["trainee"] in cls.trainees]
    )


def learning_curves(
    cls: ClassFile,
    sessions: Sequence[Mapping[str, Any]],
    answers: Sequence[Mapping[str, Any]],
) -> dict[str, dict[str, list[float]]]:
    """Exercise name -> trainee -> the scores of every attempt in time order."""
    return {
        ex.name: {t: attempts_of(ex, t, sessions, answers)[0] for t in cls.trainees}
        for ex in cls.exercises
    }
