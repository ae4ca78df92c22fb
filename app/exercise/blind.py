"""What every command may do with a blind trial: the one owner of the policy (docs/exercises.md,
"Blind trials and the other commands").

A command reads a blind trial when one of its plans is a trial's plan (a ``trial.json``
beside the file, or inside a plan folder) or its CT is a trial's CT (the ``ct/`` folder of a
trial, or a series whose header says ``ctdrill exercise``). Nothing a trainee opens may name
the trial's class, so :func:`blind_guard` decides, for every command, before it reads
anything:

- ``rehearse`` and ``gui`` run the trial's own plan blind (the rehearsal's summary without
  :data:`~ctdrill.app.exercise.trials.BLIND_HIDDEN_KEYS`, the window's blind mode);
- ``inspect`` describes a trial's CT (geometry, the HU range of the whole volume: no class);
- ``exercise`` writes trials and ``assess`` reads sessions, not plans;
- every other use is refused with one line (:class:`BlindTrialError`) that says what the trainee
  does with a trial and how the instructor runs the command: with the instructor's key file
  (``ctdrill exercise --key FILE``) as ``--key FILE``, which must be that exercise's key and
  name the class the trial's sealed key opens to (:func:`check_instructor_key`).

The Python API (:mod:`ctdrill.api`) and the batch's rows ask the same function.
"""

from __future__ import annotations

import argparse
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path

from ctdrill.app.exercise.seal import SealError, unseal
from ctdrill.app.exercise.trials import (
    KEY_FORMAT,
    TRIAL_CARD,
    TrialCard,
    TrialError,
    card_from_json,
    exercise_digest,
)
from ctdrill.safeio import load_json

#: Commands that run on a trial's own plan as they are, blind (what they write names no class).
BLIND_RUNS = frozenset({"rehearse", "gui"})
#: Commands allowed on a trial's CT: what they print names no class.
OPEN_ON_CT = frozenset({"inspect"})
#: Commands that read no plan or CT of a trial (they write trials, or read sessions).
NOT_TRIAL_READERS = frozenset({"exercise", "assess", "class", "phantom", "warmup"})
#: The DICOM model name of a trial's CT (``ctdrill exercise`` writes it).
EXERCISE_CT_MODEL = "ctdrill exercise"


class BlindTrialError(TrialError):
    """A command refused on a blind trial (one line: what to do instead)."""


def plan_trial(path: Path) -> TrialCard | None:
    """The card of the trial ``path`` belongs to: a plan file with ``trial.json`` beside it,
    or a plan folder holding one; None otherwise."""
    path = Path(path)
    for card_path in (path / TRIAL_CARD, path.parent / TRIAL_CARD):
        if card_path.is_file() and (card_path.parent == path or path.is_file()):
            doc = load_json(card_path, what="trial card", error=TrialError)
            return card_from_json(doc, where=str(card_path))
    return None


def ct_trial(path: Path) -> tuple[bool, TrialCard | None]:
    """Whether ``path`` is (or holds) a trial's CT, and the trial's card when there is one.

    A trial's CT is its ``ct/`` folder (or a file in it) beside a ``trial.json``, a folder
    holding trials (the series loaders search folders), or a DICOM series whose header's model
    name is :data:`EXERCISE_CT_MODEL` (a trial's CT copied elsewhere). The card is given when
    one trial's card is found (a folder of several trials has none)."""
    path = Path(path)
    folder = path if path.is_dir() else path.parent
    cards = [c for c in (folder / TRIAL_CARD, folder.parent / TRIAL_CARD) if c.is_file()]
    dicoms: list[Path] = [path] if path.is_file() else []
    if path.is_dir():
        found_cards, found_dicoms = _walk(path)
        cards += [c for c in found_cards if c not in cards]
        dicoms += found_dicoms
    if len(cards) == 1:
        doc = load_json(cards[0], what="trial card", error=TrialError)
        return True, card_from_json(doc, where=str(cards[0]))
    if cards:
        return True, None
    return any(_exercise_header(f) for f in dicoms[:_HEADERS_READ]), None


#: How deep and how many entries :func:`ct_trial` looks under a CT folder, and how many DICOM
#: headers it reads (one per folder holding ``.dcm`` files).
_WALK_DEPTH = 4
_WALK_ENTRIES = 20_000
_HEADERS_READ = 8


def _walk(root: Path) -> tuple[list[Path], list[Path]]:
    """The trial cards under ``root`` and the first ``.dcm`` file of each folder (bounded)."""
    cards: list[Path] = []
    dicoms: list[Path] = []
    seen = 0
    stack = [(root, 0)]
    while stack and seen < _WALK_ENTRIES:
        folder, depth = stack.pop()
        try:
            entries = sorted(folder.iterdir())
        except OSError:
            continue
        seen += len(entries)
        first_dcm = next((e for e in entries if e.suffix.lower() == ".dcm"), None)
        if first_dcm is not None:
            dicoms.append(first_dcm)
        for e in entries:
            if e.name == TRIAL_CARD and e.is_file():
                cards.append(e)
            elif depth < _WALK_DEPTH and e.is_dir() and not e.is_symlink():
                stack.append((e, depth + 1))
    return cards, dicoms


def _exercise_header(first: Path) -> bool:
    """True if the DICOM file ``first`` says it was written by ``ctdrill exercise``."""
    if first.suffix.lower() != ".dcm" or not first.is_file():
        return False
    from ctdrill.imaging.dicom.fastheader import HeaderCorruptError, read_fast_header

    try:  # most files: without pydicom (0.2 s of a window's start-up to import)
        fast = read_fast_header(first)
    except (HeaderCorruptError, OSError):
        fast = None
    if fast is not None:
        return str(fast.tags.get("ManufacturerModelName", "")) == EXERCISE_CT_MODEL
    try:
        import pydicom

        ds = pydicom.dcmread(
            first, stop_before_pixels=True, specific_tags=["ManufacturerModelName"]
        )
    except Exception:  # not DICOM, unreadable: the command's own loader says why
        return False
    return str(ds.get("ManufacturerModelName", "")) == EXERCISE_CT_MODEL


def check_instructor_key(card: TrialCard, key_path: Path) -> None:
    """Accept ``key_path`` as the instructor's key of ``card``'s trial.

    It must be a :data:`KEY_FORMAT` file of the card's exercise whose parameters (with the
    seed, which no trial's file holds) hash to the card's exercise id, list the trial with the
    card's plan hash, and name the class the card's sealed key opens to.

    Raises
    ------
    BlindTrialError
        Any of these does not hold (the message names the key file, never a class).
    """
    doc = load_json(Path(key_path), what="instructor's key", error=BlindTrialError)
    bad = BlindTrialError(
        f"--key {key_path}: not the instructor's key of trial {card.trial!r} (exercise "
        f"{card.exercise_id}); give the file ctdrill exercise --key wrote for it"
    )
    if not isinstance(doc, Mapping) or doc.get("format") != KEY_FORMAT:
        raise bad
    params = doc.get("params")
    if doc.get("exercise_id") != card.exercise_id or not isinstance(params, list):
        raise bad
    if exercise_digest(params)[0] != card.exercise_id:  # the seed: in no trial's files
        raise bad
    entries = doc.get("trials")
    entry = next(
        (
            e
            for e in (entries if isinstance(entries, list) else [])
            if isinstance(e, Mapping) and e.get("trial") == card.trial
        ),
        None,
    )
    if entry is None or entry.get("plan_sha256") != card.plan_sha256:
        raise bad
    try:
        truth = unseal(card.key, binding=card.binding)
    except SealError as exc:
        raise BlindTrialError(f"{card.trial}: {exc}") from exc
    if entry.get("misch") != truth:
        raise bad


def refusal(
    command: str, where: str, card: TrialCard | None, *, keyed: bool = True
) -> BlindTrialError:
    """The one line a command refused on a blind trial prints (it names no class); ``keyed``:
    the command takes ``--key``."""
    name = "ctdrill.api" if command == "api" else f"ctdrill {command}"
    which = f"trial {card.trial!r} of exercise {card.exercise}" if card else "a trial's CT"
    runs = f"ctdrill {command}" if keyed else "ctdrill export"
    how = (
        f"the instructor runs {runs} on it with --key FILE, the key ctdrill exercise --key wrote"
        if card is not None
        else f"the instructor runs {runs} on it from its trial folder with --key FILE"
    )
    return BlindTrialError(
        f"{where}: a blind trial ({which}, written by ctdrill exercise): {name} "
        "would show what gives its bone away; a trainee drills the trial's plan.json with "
        "ctdrill rehearse or the window and names the bone with ctdrill assess --answer; "
        f"{how}"
    )


def blind_guard(
    command: str,
    *,
    plans: Iterable[Path] = (),
    ct: Path | None = None,
    key: Path | None = None,
    keyed: bool = True,
) -> TrialCard | None:
    """May ``command`` run on these inputs? (module docstring: the policy).

    Parameters
    ----------
    command : the ``ctdrill`` subcommand (or ``api`` for :mod:`ctdrill.api`, ``batch``).
    plans : the plan files or folders it reads.
    ct : the CT it reads, or None.
    key : the instructor's key file (``--key``), or None.
    keyed : the command takes ``--key`` (the refusal says how the instructor runs it).

    Returns
    -------
    The trial's card when the command runs on a trial (blind, or for the instructor), None
    when no trial is involved.

    Raises
    ------
    BlindTrialError
        Refused: one line, naming the input, what a trainee does with a trial and how the
        instructor runs the command.
    """
    if command in NOT_TRIAL_READERS:
        return None
    plan_list: Sequence[Path] = [Path(p) for p in plans]
    found = [(p, plan_trial(p)) for p in plan_list]
    trial_plans = [(p, c) for p, c in found if c is not None]
    is_trial_ct, ct_card = ct_trial(ct) if ct is not None else (False, None)
    if not trial_plans and not is_trial_ct:
        return None
    card = trial_plans[0][1] if trial_plans else ct_card
    where = str(trial_plans[0][0] if trial_plans else ct)
    if key is not None and card is not None:
        if any(c != card for _, c in trial_plans) or (ct_card is not None and ct_card != card):
            raise BlindTrialError(
                f"{where}: plans or a CT of several trials; --key opens one trial at a time"
            )
        check_instructor_key(card, key)
        return card
    if command in OPEN_ON_CT and not trial_plans:
        return card
    own_plan = (
        len(plan_list) == 1
        and len(trial_plans) == 1
        and plan_list[0].is_file()
        and (ct_card is None or ct_card == card)
    )
    if command in BLIND_RUNS and own_plan:
        return card
    raise refusal(command, where, card, keyed=keyed)


def guard_args(args: argparse.Namespace) -> TrialCard | None:
    """:func:`blind_guard` for a parsed ``ctdrill`` command line (its ``--plan``, ``plans``,
    ``--ct`` and ``--key``)."""
    command = str(getattr(args, "command", ""))
    if command in NOT_TRIAL_READERS:
        return None
    plans = list(getattr(args, "plan", None) or ()) + list(getattr(args, "plans", None) or ())
    ct = getattr(args, "dicom", None) or getattr(args, "ct", None)
    return blind_guard(
        command,
        plans=plans,
        ct=ct if isinstance(ct, Path) else None,
        key=getattr(args, "key", None),
        keyed=hasattr(args, "key"),
    )


def window_trial(plans: Sequence[Path], ct: Path | None) -> TrialCard | None:
    """The trial the window shows blind: that of its plan when the plan is a trial's own plan
    alone, else that of its CT when the CT is a trial's (a plan opened on a trial's CT does not
    show the bone either); None: no trial."""
    plan_list = [Path(p) for p in plans]
    card = plan_trial(plan_list[0]) if len(plan_list) == 1 and plan_list[0].is_file() else None
    if card is None and ct is not None and str(ct):
        card = ct_trial(Path(ct))[1]
    return card


def check_window_ct(ct: Path, blind: TrialCard | None) -> None:
    """Refuse opening ``ct`` in the window unless it is no trial's CT, or the window is blind
    on the same trial (a trial's CT copied elsewhere: any blind trial).

    Raises
    ------
    BlindTrialError
        A trial's CT in a window that would show it (the refusal line).
    """
    is_trial_ct, card = ct_trial(Path(ct))
    if not is_trial_ct or (blind is not None and (card is None or card == blind)):
        return
    raise refusal("gui", str(ct), card)
