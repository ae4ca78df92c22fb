"""The class file (``ctdrill-class/1``, JSON): who is in the class and what they practise.

::

    {"format": "ctdrill-class/1", "name": "implantology 2027",
     "roster": {"trainees": ["ann", "bo", "Zoë"], "experts": ["dr-lee"]},
     "exercises": [
       {"name": "feel the bone", "generator": "bone-quality", "mode": "bone-quality",
        "calibration": "bone-illustrative", "pass_mark": 75, "attempts": 2},
       {"name": "stop without gauges", "case": "cases/demo-plan.json", "mode": "stop-yourself",
        "aid_level": "no-gauges", "pass_mark": 65, "attempts": 5},
       {"name": "exam", "case": {"plan_sha256": "..."}, "mode": "exam", "pass_mark": 60,
        "attempts": 3}]}

* ``roster``: the trainees and the experts, by the id their sessions are stored under
  (compared as the record compares ids); or a list of ids (trainees) and
  ``{"id": ..., "role": "trainee" | "expert"}``. Experts are named here, nowhere else; an id
  may not be both.
* an exercise: ``name`` (unique), ``mode`` (:data:`MODES`), ``case`` (a plan file, relative to
  the class file, ``{"ct": ..., "plan": ...}`` or ``{"plan_sha256": ...}``: sessions on that
  plan; absent: any plan) or
  ``generator`` (``bone-quality``: the blind trials of ``ctdrill exercise``), ``aid_level``
  (the stop-yourself exercise's level, :data:`ctdrill.app.exercise.aids.AID_LEVELS`; required
  for that mode, absent otherwise), ``calibration`` (sessions with that calibration set;
  absent: any), ``pass_mark`` (0-100: the score that passes, or for ``bone-quality`` the share
  of trials named right, %), ``attempts`` (how many attempts count, 1-1000). ``attempts_allowed``
  and ``aids`` are accepted for ``attempts`` and ``aid_level``.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ctdrill.app.errors import AppInputError
from ctdrill.safeio import load_json

CLASS_FORMAT = "ctdrill-class/1"
#: Exercise modes: the rehearsal's own two, the blind trials and the aid-fading levels.
MODES = ("guarded", "exam", "bone-quality", "stop-yourself")
#: Generators an exercise may name.
GENERATORS = ("bone-quality",)
MAX_ATTEMPTS = 1000
MAX_EXERCISES = 100
MAX_ROSTER = 1000
_TOP_KEYS = {"format", "name", "roster", "exercises"}
_EXERCISE_KEYS = {
    "name",
    "mode",
    "case",
    "generator",
    "aid_level",
    "calibration",
    "pass_mark",
    "attempts",
}
_SHA = re.compile(r"[0-9a-f]{64}")


class ClassFileError(AppInputError):
    """A class file that cannot be used (the message names the field and what to do)."""


@dataclass(frozen=True)
class ClassExercise:
    """One exercise of the class (module docstring)."""

    name: str
    mode: str
    plan_sha256: str | None
    generator: str | None
    aid_level: str | None
    calibration: str | None
    pass_mark: float
    attempts: int

    @property
    def session_mode(self) -> str:
        """The ``mode`` its sessions carry (a stop-yourself level's: ``stop-yourself:LEVEL``)."""
        return self.mode if self.aid_level is None else f"{self.mode}:{self.aid_level}"


@dataclass(frozen=True)
class ClassFile:
    """The class: its name, roster and exercises."""

    name: str
    trainees: tuple[str, ...]
    experts: tuple[str, ...]
    exercises: tuple[ClassExercise, ...]


def _ids(path: Path, roster: dict[str, Any], key: str) -> tuple[str, ...]:
    from ctdrill.app.trainee.record import RecordError, check_trainee

    raw = roster.get(key, [])
    if not isinstance(raw, list) or len(raw) > MAX_ROSTER:
        raise ClassFileError(f"{path}: roster.{key} must be a list of at most {MAX_ROSTER} ids")
    out: list[str] = []
    for i, item in enumerate(raw):
        if not isinstance(item, str):
            raise ClassFileError(f"{path}: roster.{key}[{i}] must be a trainee id (a string)")
        try:
            tid = check_trainee(item)
        except RecordError as exc:
            raise ClassFileError(f"{path}: roster.{key}[{i}]: {exc}") from exc
        if tid in out:
            raise ClassFileError(f"{path}: roster.{key}[{i}] {item!r} is listed twice")
        out.append(tid)
    return tuple(out)


#: Other names a class file may give an exercise's keys.
_ALIASES = {"attempts_allowed": "attempts", "aids": "aid_level", "calibration_set": "calibration"}


def _exercise(path: Path, i: int, raw: object) -> ClassExercise:
    from ctdrill.app.exercise.aids import aid_level

    where = f"{path}: exercises[{i}]"
    if not isinstance(raw, dict):
        raise ClassFileError(f"{where} must be an object")
    for alias, key in _ALIASES.items():
        if alias in raw:
            if key in raw:
                raise ClassFileError(f"{where}: give {key} once (not also as {alias})")
            raw = {**{k: v for k, v in raw.items() if k != alias}, key: raw[alias]}
    extra = sorted(set(raw) - _EXERCISE_KEYS)
    if extra:
        raise ClassFileError(
            f"{where}: unknown key {extra[0]!r}; use {', '.join(sorted(_EXERCISE_KEYS))}"
        )
    name = raw.get("name")
    if not isinstance(name, str) or not name.strip() or len(name) > 100:
        raise ClassFileError(f"{where}.name: give the exercise a name (1-100 characters)")
    mode = raw.get("mode")
    if mode not in MODES:
        raise ClassFileError(f"{where}.mode {mode!r}: use one of {', '.join(MODES)}")
    level = raw.get("aid_level")
    if mode == "stop-yourself":
        if not isinstance(level, str):
            raise ClassFileError(f"{where}.aid_level: the stop-yourself exercise needs a level")
        try:
            aid_level(level)
        except AppInputError as exc:
            raise ClassFileError(f"{where}.aid_level: {exc}") from exc
    elif level is not None:
        raise ClassFileError(f"{where}.aid_level: only the stop-yourself exercise has levels")
    generator = raw.get("generator")
    if generator is not None and generator not in GENERATORS:
        raise ClassFileError(f"{where}.generator {generator!r}: use {', '.join(GENERATORS)}")
    if (generator is None) != (mode != "bone-quality"):
        raise ClassFileError(
            f"{where}: the bone-quality mode goes with generator 'bone-quality' (and only it)"
        )
    case = raw.get("case")
    if case is not None and generator is not None:
        raise ClassFileError(f"{where}: give a case or a generator, not both")
    plan_sha = _case(path, where, case)
    calibration = raw.get("calibration")
    if calibration is not None and (not isinstance(calibration, str) or not calibration):
        raise ClassFileError(f"{where}.calibration: a calibration set's name")
    mark = raw.get("pass_mark")
    if (
        not isinstance(mark, int | float)
        or isinstance(mark, bool)
        or not (math.isfinite(mark) and 0 <= mark <= 100)
    ):
        raise ClassFileError(f"{where}.pass_mark: a number 0-100")
    attempts = raw.get("attempts")
    if (
        not isinstance(attempts, int)
        or isinstance(attempts, bool)
        or not (1 <= attempts <= MAX_ATTEMPTS)
    ):
        raise ClassFileError(f"{where}.attempts: a whole number 1-{MAX_ATTEMPTS}")
    return ClassExercise(name, mode, plan_sha, generator, level, calibration, float(mark), attempts)


def _case(path: Path, where: str, case: object) -> str | None:
    """The plan hash of the exercise's case (None: any plan)."""
    if case is None:
        return None
    if isinstance(case, dict) and "plan" in case and set(case) <= {"plan", "ct"}:
        case = case["plan"]  # {"ct": ..., "plan": ...}: the plan names the case
    if isinstance(case, dict):
        sha = case.get("plan_sha256")
        if set(case) != {"plan_sha256"} or not isinstance(sha, str) or not _SHA.fullmatch(sha):
            raise ClassFileError(
                f'{where}.case: a plan file, or {{"plan_sha256": <64 hex digits>}}'
            )
        return sha
    if not isinstance(case, str) or not case:
        raise ClassFileError(f"{where}.case: a plan file (relative to the class file)")
    from ctdrill.app.exercise.trials import session_plan_hash

    plan = (path.parent / case) if not Path(case).is_absolute() else Path(case)
    if not plan.is_file():
        raise ClassFileError(f"{where}.case: no plan file {plan}")
    try:
        return session_plan_hash([plan])
    except AppInputError as exc:
        raise ClassFileError(f"{where}.case: {exc}") from exc


def load_class(path: Path) -> ClassFile:
    """Read and check a class file.

    Raises
    ------
    ClassFileError
        Not a ``ctdrill-class/1`` file, or a field that is missing or wrong (named).
    """
    doc = load_json(path, what="class file", error=ClassFileError)
    if not isinstance(doc, dict) or doc.get("format") != CLASS_FORMAT:
        raise ClassFileError(f'{path}: not a class file ("format": "{CLASS_FORMAT}")')
    extra = sorted(set(doc) - _TOP_KEYS)
    if extra:
        raise ClassFileError(
            f"{path}: unknown key {extra[0]!r}; use {', '.join(sorted(_TOP_KEYS))}"
        )
    name = doc.get("name", path.stem)
    if not isinstance(name, str):
        raise ClassFileError(f"{path}: name must be a string")
    roster = _roster(path, doc.get("roster"))
    trainees = _ids(path, roster, "trainees")
    experts = _ids(path, roster, "experts")
    if not trainees:
        raise ClassFileError(f"{path}: roster.trainees is empty; name the class's trainees")
    both = sorted(set(trainees) & set(experts))
    if both:
        raise ClassFileError(f"{path}: {both[0]!r} is both a trainee and an expert")
    raw = doc.get("exercises")
    if not isinstance(raw, list) or not 1 <= len(raw) <= MAX_EXERCISES:
        raise ClassFileError(f"{path}: exercises must list 1-{MAX_EXERCISES} exercises")
    exercises = tuple(_exercise(path, i, e) for i, e in enumerate(raw))
    names = [e.name for e in exercises]
    dup = next((n for n in names if names.count(n) > 1), None)
    if dup is not None:
        raise ClassFileError(f"{path}: two exercises are named {dup!r}; name each once")
    return ClassFile(name, trainees, experts, exercises)


def _roster(path: Path, raw: object) -> dict[str, Any]:
    """``{"trainees": [...], "experts": [...]}``, or a list of ids (trainees) and
    ``{"id": ..., "role": "trainee" | "expert"}`` entries, as the first form."""
    if isinstance(raw, dict) and not set(raw) - {"trainees", "experts"}:
        return raw
    if not isinstance(raw, list):
        raise ClassFileError(
            f'{path}: roster must be {{"trainees": [...], "experts": [...]}} or a list of '
            '{"id": ..., "role": ...}'
        )
    out: dict[str, list[object]] = {"trainees": [], "experts": []}
    for i, item in enumerate(raw):
        if isinstance(item, str):
            out["trainees"].append(item)
            continue
        role = item.get("role", "trainee") if isinstance(item, dict) else None
        if not isinstance(item, dict) or role not in ("trainee", "expert"):
            raise ClassFileError(
                f'{path}: roster[{i}] must be an id or {{"id": ..., "role": "trainee" or "expert"}}'
            )
        out[f"{role}s"].append(item.get("id"))
    return out
