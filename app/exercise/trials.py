"""A blind trial's card (``trial.json``, ``ctdrill-trial/1``) and what a blind session hides.

``ctdrill exercise`` writes each trial as a folder: ``ct/`` (the site's CT), ``plan.json`` and
``trial.json``, the card::

    {"format": "ctdrill-trial/1", "exercise": "bone-quality", "exercise_id": "...",
     "trial": "trial-01", "trials": 8, "calibration": "bone-illustrative",
     "plan_sha256": "...", "key": "<sealed>", "task": "..."}

``plan_sha256`` is the hash ``ctdrill rehearse`` records of the plan it drills
(:func:`session_plan_hash`); ``key`` is the trial's class sealed to the exercise id, the trial's
name and that hash (:mod:`ctdrill.app.exercise.seal`). A rehearsal of a plan whose folder holds
a card (:func:`find_trial`) is a blind session: its ``summary.json`` carries the card as
``exercise`` and loses every field that would give the bone away (:func:`blind_summary`), and
``ctdrill assess --answer`` opens the key from there (:func:`trial_key`).
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ctdrill.app.errors import AppInputError
from ctdrill.app.exercise.seal import TOKEN_ALPHABET, trial_binding, unseal
from ctdrill.safeio import load_json

TRIAL_FORMAT = "ctdrill-trial/1"
#: The instructor's key file's format (``ctdrill exercise --key``).
KEY_FORMAT = "ctdrill-exercise-key/1"
#: A trial card's file name, next to the trial's plan.
TRIAL_CARD = "trial.json"
#: The card's keys, in the order written.
CARD_KEYS = (
    "format",
    "exercise",
    "exercise_id",
    "trial",
    "trials",
    "calibration",
    "plan_sha256",
    "key",
    "task",
)
#: Summary keys a blind session never writes: the bone's HU and class along the path, and the
#: model's predictions for the push (the time to the stop, the force a push must beat).
BLIND_HIDDEN_KEYS = frozenset(
    {
        "hu_grading",
        "misch",
        "misch_share",
        "mean_hu",
        "hu_mean",
        "force_band",
        "force_band_note",
        "push_n",
        "model_time_to_stop_s",
        "time_to_stop_agrees",
        "time_to_stop_note",
        "push_too_weak_at_mm",
        "push_too_weak_s0_n",
    }
)


def exercise_digest(params: Sequence[Any]) -> tuple[str, bytes]:
    """An exercise's id and digest from its parameters (``[exercise, trials, seed,
    calibration, spacing_mm, [site plans]]``): the id is 12 symbols of the seal's alphabet (no
    ``d``); the instructor's key holds the parameters, so it proves it is that exercise's."""
    digest = hashlib.sha256(json.dumps(list(params)).encode()).digest()
    bits = int.from_bytes(digest, "big")
    return "".join(TOKEN_ALPHABET[(bits >> (5 * k)) & 31] for k in range(12)), digest


class TrialError(AppInputError):
    """A trial card that cannot be used (the message names the file and what to do)."""


@dataclass(frozen=True)
class TrialCard:
    """A blind trial's card (module docstring)."""

    exercise: str
    exercise_id: str
    trial: str
    trials: int
    calibration: str
    plan_sha256: str
    key: str
    task: str

    def to_json(self) -> dict[str, Any]:
        """The card as ``trial.json`` holds it."""
        return {
            "format": TRIAL_FORMAT,
            "exercise": self.exercise,
            "exercise_id": self.exercise_id,
            "trial": self.trial,
            "trials": self.trials,
            "calibration": self.calibration,
            "plan_sha256": self.plan_sha256,
            "key": self.key,
            "task": self.task,
        }

    @property
    def binding(self) -> str:
        """What the sealed key is bound to."""
        return trial_binding(self.exercise_id, self.trial, self.plan_sha256)


def card_from_json(doc: object, *, where: str) -> TrialCard:
    """A card from its JSON (``trial.json``, or a blind summary's ``exercise``).

    Raises
    ------
    TrialError
        Not a ``ctdrill-trial/1`` card, a key missing or of the wrong type.
    """
    if not isinstance(doc, Mapping) or doc.get("format") != TRIAL_FORMAT:
        raise TrialError(f"{where}: not a trial card ({TRIAL_FORMAT}); use the trial as written")
    for name in CARD_KEYS[1:]:
        want: type = int if name == "trials" else str
        value = doc.get(name)
        if not isinstance(value, want) or isinstance(value, bool):
            raise TrialError(f"{where}: {name} is missing or not a {want.__name__}")
    return TrialCard(**{k: doc[k] for k in CARD_KEYS[1:]})


def session_plan_hash(plan_paths: Sequence[Path]) -> str:
    """The hash ``ctdrill rehearse`` records (``plan_sha256``) for these plan files: the one
    trajectory, drilled to its implant's apex plus the drill's tip when it has an implant."""
    from ctdrill.app.trainee.exam import plan_hash
    from ctdrill.imaging.plan.load import load_one_plan

    plan = load_one_plan(list(plan_paths))
    if not plan.earlier_drills:
        plan = plan.drilled(0)
    return plan_hash(plan)


def find_trial(plan_paths: Sequence[Path]) -> TrialCard | None:
    """The card of the trial whose plan is ``plan_paths`` (one file with a ``trial.json``
    beside it), or None for an ordinary plan."""
    if len(plan_paths) != 1:
        return None
    card_path = Path(plan_paths[0]).parent / TRIAL_CARD
    if not card_path.is_file():
        return None
    doc = load_json(card_path, what="trial card", error=TrialError)
    return card_from_json(doc, where=str(card_path))


def check_session_plan(card: TrialCard, plan_sha256: str, *, where: str) -> None:
    """Refuse a session whose plan is not the trial's (the plan was edited after the exercise
    wrote it)."""
    if card.plan_sha256 != plan_sha256:
        raise TrialError(
            f"{where}: the plan is not the one trial {card.trial!r} was written with (edited "
            "since?); drill the trial's plan.json as ctdrill exercise wrote it"
        )


def blind_summary(summary: Mapping[str, Any], card: TrialCard) -> dict[str, Any]:
    """``summary`` without :data:`BLIND_HIDDEN_KEYS` (at any depth), with the card as
    ``exercise``."""
    out = _without_hidden(summary)
    out["exercise"] = card.to_json()
    return out


def _without_hidden(value: Any) -> Any:
    if isinstance(value, Mapping):
        return {k: _without_hidden(v) for k, v in value.items() if k not in BLIND_HIDDEN_KEYS}
    if isinstance(value, list):
        return [_without_hidden(v) for v in value]
    return value


def summary_card(summary: Mapping[str, Any], *, where: str) -> TrialCard | None:
    """The card a blind session's ``summary.json`` carries (None: not a blind session)."""
    doc = summary.get("exercise")
    if doc is None:
        return None
    return card_from_json(doc, where=f"{where}: exercise")


def trial_key(summary: Mapping[str, Any], *, where: str) -> tuple[TrialCard, str]:
    """The card of a blind session and the class its sealed key holds.

    Raises
    ------
    TrialError
        Not a blind session; a session drilled on another plan than the trial's.
    SealError
        A key that does not open for this trial.
    """
    card = summary_card(summary, where=where)
    if card is None:
        raise TrialError(
            f"{where}: not a blind trial's session (its summary.json has no exercise); "
            "--answer names the bone of a trial written by ctdrill exercise"
        )
    check_session_plan(card, str(summary.get("plan_sha256")), where=where)
    return card, unseal(card.key, binding=card.binding)


def is_inside(path: Path, folder: Path) -> bool:
    """True if ``path`` is ``folder`` or lies inside it (both resolved)."""
    p, f = Path(os.path.realpath(path)), Path(os.path.realpath(folder))
    return p == f or f in p.parents


def write_session_only(out_dir: Path, files: Mapping[str, str]) -> list[Path]:
    """A blind session's export: its session files alone (``files``: name -> text, written
    under ``session/``: ``summary.json``, ``session.csv`` and what else ``ctdrill assess``
    reads), in one swap; no path export (its profile and plot name the bone)."""
    from ctdrill.app.records import OUTPUT_NAMES, atomic_output_dir, write_file

    with atomic_output_dir(out_dir, owned_names=OUTPUT_NAMES | set(files)) as stage:
        (stage / "session").mkdir()
        for name, text in files.items():
            write_file(stage / "session" / name, text)
    return [Path(out_dir) / "session" / name for name in files]
