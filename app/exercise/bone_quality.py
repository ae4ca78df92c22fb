"""``ctdrill exercise bone-quality``: blind trials of Misch class D1-D4 (docs/exercises.md).

Each trial is a folder ``trial-01``, ``trial-02`` ... holding a site to drill: ``ct/`` (a CT
series), ``plan.json`` (ctdrill-plan/1, the exercise's calibration pinned in it) and
``trial.json`` (the card, :mod:`ctdrill.app.exercise.trials`, with the class sealed). A site is
either the shipped phantom generator's mandible of one class
(:func:`ctdrill.imaging.phantom.mandible.make_mandible_phantom`, with its own noise and seed)
or a region of a real CT around a given plan, whose class is that of the bone the plan drills
(:func:`site_class`). The classes are balanced (each of D1-D4 as often as the count allows,
real sites first) and shuffled with the seed; the same seed writes the same bytes.

Nothing a trainee opens names the class: the folders and files are numbered, the DICOM
headers say ``ctdrill exercise`` and the trial's number (no class, no generator parameters),
the UIDs are hashes, the plan and the card hold no class and the key is sealed. The
instructor's plain key is written only where ``--key FILE`` says, outside the trials.
"""

from __future__ import annotations

import hashlib
import json
import re
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from ctdrill.app.batch.manifest import hashed_path
from ctdrill.app.errors import AppInputError
from ctdrill.app.exercise.seal import seal, trial_binding
from ctdrill.app.exercise.trials import (
    KEY_FORMAT,
    TRIAL_CARD,
    TrialCard,
    exercise_digest,
    is_inside,
    session_plan_hash,
)
from ctdrill.app.records import atomic_output_dir, atomic_write_bytes, write_file

#: The exercise's name (the ``mode`` of its sessions in the record).
BONE_QUALITY = "bone-quality"
#: The classes a trial can be (D5 is no bone to drill for an implant).
TRIAL_CLASSES = ("D1", "D2", "D3", "D4")
#: Most trials one exercise writes.
MAX_TRIALS = 99
#: Phantom voxel spacing, mm (the phantom's own default).
DEFAULT_SPACING_MM = 0.4
#: Each phantom trial's noise is drawn uniformly from this range, HU: the trials of one
#: class differ, and no file is the same as another's.
NOISE_RANGE_HU = (10.0, 30.0)
#: A real site's region: this much around the plan's entry, target and landmarks, mm.
REGION_PAD_MM = 12.0
#: What the trainee is asked (the card's ``task``).
TASK = (
    "Drill this site without looking at the bone (ctdrill rehearse, or the window's "
    "bone-quality exercise), then name its bone class: ctdrill assess SESSION --answer CLASS "
    "--db FILE --trainee ID."
)
_CT_NAME = re.compile(r"CT\d{5}\.dcm")
_CLASS_TEXT = re.compile(r"d[1-5]", re.IGNORECASE)
#: Most series UIDs drawn for one trial (each passes with probability ~0.09).
_MAX_UID_DRAWS = 200


class ExerciseInputError(AppInputError):
    """Bad exercise option (the message names it)."""


@dataclass(frozen=True)
class RealSite:
    """A real CT and the plan of a site on it."""

    ct: Path
    plan: Path


@dataclass(frozen=True)
class WrittenTrial:
    """One trial written: its folder name, class (the key), source and card."""

    name: str
    misch: str
    source: str
    card: TrialCard


class _OwnedNames:
    """The names an exercise's folder holds (``ct/CT00000.dcm`` ... , ``plan.json``,
    ``trial.json``): an existing exercise may be replaced by a new one."""

    def __contains__(self, name: object) -> bool:
        return isinstance(name, str) and (
            name in {"plan.json", TRIAL_CARD} or _CT_NAME.fullmatch(name) is not None
        )

    def __iter__(self) -> Iterator[str]:
        return iter(("plan.json", TRIAL_CARD))

    def __len__(self) -> int:
        return 2


def trial_name(k: int) -> str:
    """``trial-01`` for ``k`` = 1."""
    return f"trial-{k:02d}"


def _check(trials: int, seed: int, spacing_mm: float, calibration: str) -> None:
    if not 1 <= trials <= MAX_TRIALS:
        raise ExerciseInputError(f"--trials {trials}: give 1 to {MAX_TRIALS} trials")
    if seed < 0:
        raise ExerciseInputError(f"--seed {seed}: give a whole number >= 0")
    if not (np.isfinite(spacing_mm) and 0.2 <= spacing_mm <= 1.0):
        raise ExerciseInputError(f"--spacing-mm {spacing_mm}: give 0.2 to 1.0 mm")
    from ctdrill.model import load_calibration
    from ctdrill.model.calibration import CalibrationError

    try:
        load_calibration(calibration)
    except CalibrationError as exc:
        raise ExerciseInputError(f"--calibration {calibration!r}: {exc}") from exc


def site_class(depth_mm: np.ndarray, hu_mean: np.ndarray, stop_depth_mm: float) -> str | None:
    """The Misch class of the bone a path drills: of the median lip-mean HU over its
    trabecular depths (bone, not cortical) down to the stop, or over its bone depths when
    none is trabecular; None when the path drills no bone.

    Parameters
    ----------
    depth_mm, hu_mean : (D,) the path's depth grid, mm, and lip-mean HU.
    stop_depth_mm : where the drill stops, mm.
    """
    from ctdrill.imaging.misch import is_bone, is_cortical, misch_class

    keep = np.asarray(depth_mm) <= stop_depth_mm + 1e-9
    hu = np.asarray(hu_mean, dtype=float)[keep]
    bone = is_bone(hu)
    trabecular = bone & ~is_cortical(hu)
    pick = hu[trabecular] if trabecular.any() else hu[bone]
    if pick.size == 0:
        return None
    return str(misch_class(float(np.median(pick))))


@dataclass(frozen=True, eq=False)
class _Site:
    """A site ready to write: HU, affine, the plan document and the class."""

    hu: np.ndarray
    affine_lps: np.ndarray
    plan: dict[str, Any]
    misch: str
    source: str


def _phantom_site(misch: str, *, spacing_mm: float, noise_hu: float, seed: int) -> _Site:
    from ctdrill.imaging.phantom.mandible import make_mandible_phantom

    ph = make_mandible_phantom(misch=misch, spacing_mm=spacing_mm, noise_hu=noise_hu, seed=seed)
    return _Site(ph.hu, ph.affine_lps, dict(ph.plan), misch, "phantom")


def _real_site(site: RealSite) -> _Site:
    """A region of a real CT around the site's plan, and the class of the bone it drills."""
    from ctdrill.engine.path import plan_path
    from ctdrill.engine.plans import plan_calibration
    from ctdrill.imaging import load_ct
    from ctdrill.imaging.plan.load import load_one_plan
    from ctdrill.imaging.plan.write import plan_to_dict

    volume = load_ct(site.ct)
    plan = load_one_plan([site.plan])
    drilled = plan if plan.earlier_drills else plan.drilled(0)
    path = plan_path(volume, drilled, plan_calibration(drilled))
    misch = site_class(path.depth_mm, path.profile.hu_mean, path.stop_depth_mm)
    if misch not in TRIAL_CLASSES:
        raise ExerciseInputError(
            f"--plan {site.plan}: the bone it drills is {misch or 'no bone'}, not one of "
            f"{', '.join(TRIAL_CLASSES)}; give a site in bone"
        )
    if not getattr(volume, "regular", True) or volume.valid is not None:
        raise ExerciseInputError(
            f"--ct {site.ct}: a series with padding or uneven slices; a trial's region needs a "
            "regular series"
        )
    try:
        doc = plan_to_dict(plan)
    except ValueError as exc:
        raise ExerciseInputError(
            f"--plan {site.plan}: {exc}; a real site's plan needs canal or point landmarks"
        ) from exc
    if any(lm.get("kind") == "mask" for lm in doc.get("landmarks", [])):
        raise ExerciseInputError(
            f"--plan {site.plan}: a mask landmark; a real site's plan needs canal or point "
            "landmarks (the region's CT holds no segmentation)"
        )
    far = plan.point_at_depth_lps(plan.planned_depth_mm + REGION_PAD_MM)
    pts = [plan.entry_lps, far] + [np.asarray(p) for p in _landmark_points(doc)]
    hu, affine = _crop(volume.hu, volume.affine_lps, np.asarray(pts, dtype=float))
    doc.pop("name", None)
    # the CT's folder is often named after the patient: the key names it by a hash
    return _Site(hu, affine, doc, misch, f"real CT {hashed_path(site.ct)}")


def _landmark_points(doc: dict[str, Any]) -> list[list[float]]:
    out: list[list[float]] = []
    for lm in doc.get("landmarks", []):
        out += lm.get("points_mm", [])
        if "point_mm" in lm:
            out.append(lm["point_mm"])
    return out


def _crop(hu: np.ndarray, affine: np.ndarray, pts_lps: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The voxels of ``hu`` within :data:`REGION_PAD_MM` of the points' box, and its affine."""
    inv = np.linalg.inv(affine)
    ijk = (inv[:3, :3] @ pts_lps.T).T + inv[:3, 3]
    pad = REGION_PAD_MM / np.linalg.norm(affine[:3, :3], axis=0)
    lo = np.floor(ijk.min(axis=0) - pad).astype(int)
    hi = np.ceil(ijk.max(axis=0) + pad).astype(int) + 1
    shape_ijk = np.array([hu.shape[2], hu.shape[1], hu.shape[0]])
    lo = np.clip(lo, 0, shape_ijk - 2)
    hi = np.clip(hi, lo + 2, shape_ijk)
    region = np.ascontiguousarray(hu[lo[2] : hi[2], lo[1] : hi[1], lo[0] : hi[0]])
    out = affine.copy()
    out[:3, 3] = affine[:3, :3] @ lo + affine[:3, 3]
    return region, out


def reads_as_class(text: str) -> bool:
    """True if ``text`` holds a class's name in any case (``d3`` inside a hash reads as one
    to a search that ignores case)."""
    return _CLASS_TEXT.search(text) is not None


def _write_site(folder: Path, site: _Site, *, exercise_id: str, name: str) -> str:
    """The site's ``ct/`` (blind headers) and ``plan.json``; returns the plan's hash as
    ``ctdrill rehearse`` records it. The series' UID is drawn (from the exercise id, the
    trial and a counter) until neither the hash a plan and ``ctdrill inspect`` show of it nor
    the plan's hash reads as a class (:func:`reads_as_class`)."""
    from pydicom.uid import generate_uid

    from ctdrill.imaging.phantom.writer import write_series
    from ctdrill.imaging.plan.types import SERIES_HASH_KEY, series_uid_hash

    ent = ["ctdrill-exercise", exercise_id, name]
    for k in range(_MAX_UID_DRAWS):
        series_uid = str(generate_uid(entropy_srcs=[*ent, "series", str(k)]))
        plan = {**site.plan, SERIES_HASH_KEY: series_uid_hash(series_uid)}
        write_file(folder / "plan.json", json.dumps(plan, indent=2) + "\n")
        plan_sha = session_plan_hash([folder / "plan.json"])
        if not reads_as_class(series_uid_hash(series_uid) + plan_sha):
            break
        (folder / "plan.json").unlink()
    else:  # pragma: no cover - (0.91 ** 200): never in practice
        raise ExerciseInputError(f"{name}: no series UID whose hashes read as no class")
    hu = np.clip(np.rint(site.hu), -1024, 3071)
    spacing = np.linalg.norm(site.affine_lps[:3, :3], axis=0)
    write_series(
        folder / "ct",
        hu,
        site.affine_lps,
        unsigned=True,
        bits_stored=12,
        rescale_intercept=-1024.0,
        rescale_type="HU",
        series_uid=series_uid,
        study_uid=str(generate_uid(entropy_srcs=[*ent, "study"])),
        frame_of_reference_uid=str(generate_uid(entropy_srcs=[*ent, "for"])),
        patient_name=f"EXERCISE^{name.upper()}",
        patient_id=f"EXERCISE-{exercise_id}-{name}",
        series_description=f"ctdrill exercise, {name}",
        slice_thickness_mm=float(spacing[2]),
        name_prefix="CT",
        extra={
            "Manufacturer": "ctdrill",
            "ManufacturerModelName": "ctdrill exercise",
            "StudyDescription": "ctdrill exercise",
            "BodyPartExamined": "JAW",
            "PatientSex": "O",
            "WindowCenter": "500",
            "WindowWidth": "3000",
        },
    )
    return plan_sha


def write_bone_quality(
    out: Path,
    *,
    trials: int,
    seed: int,
    calibration: str = "bone-illustrative",
    spacing_mm: float = DEFAULT_SPACING_MM,
    sites: Sequence[RealSite] = (),
    key_path: Path | None = None,
) -> list[WrittenTrial]:
    """Write the exercise's trials into ``out`` (replaced whole; module docstring).

    Parameters
    ----------
    out : the exercise's folder (``trial-01`` ...).
    trials : how many trials (1..:data:`MAX_TRIALS`).
    seed : the exercise's seed (classes, their order, the phantoms' noise).
    calibration : the calibration set pinned in every trial's plan.
    spacing_mm : the phantoms' voxel spacing, mm.
    sites : real CT sites; each is one trial (the rest are phantoms), at most ``trials``.
    key_path : where to write the instructor's plain key (outside ``out``), or None.

    Returns
    -------
    The trials in order, with their classes (the key).
    """
    _check(trials, seed, spacing_mm, calibration)
    if len(sites) > trials:
        raise ExerciseInputError(
            f"--plan: {len(sites)} real sites for {trials} trials; give --trials {len(sites)} "
            "or more"
        )
    if key_path is not None and is_inside(key_path, out):
        raise ExerciseInputError(
            f"--key {key_path}: inside the trials' folder {out}, where a trainee would read it; "
            "keep the key elsewhere"
        )
    # the sites' plans by the hash of their paths: the key names no folder (a patient's)
    sites_shown = [hashed_path(s.plan) for s in sites]
    params = [BONE_QUALITY, trials, seed, calibration, spacing_mm, sites_shown]
    exercise_id, digest = exercise_digest(params)
    rng = np.random.default_rng([seed, trials])
    real = [_real_site(s) for s in sites]
    counts = {c: sum(s.misch == c for s in real) for c in TRIAL_CLASSES}
    phantom_classes: list[str] = []
    for _ in range(trials - len(real)):  # balance: the class seen least so far next
        c = min(TRIAL_CLASSES, key=lambda name: (counts[name], TRIAL_CLASSES.index(name)))
        counts[c] += 1
        phantom_classes.append(c)
    sources: list[str | _Site] = [*real, *phantom_classes]
    order = [int(v) for v in rng.permutation(len(sources))]
    noises = rng.uniform(*NOISE_RANGE_HU, size=len(sources))
    written: list[WrittenTrial] = []
    with atomic_output_dir(out, owned_names=_OwnedNames()) as stage:
        for k, src_index in enumerate(order, start=1):
            name = trial_name(k)
            source = sources[src_index]
            if isinstance(source, str):
                site = _phantom_site(
                    source,
                    spacing_mm=spacing_mm,
                    noise_hu=round(float(noises[k - 1]), 1),
                    seed=int.from_bytes(digest[:4], "big") + k,
                )
            else:
                site = source
            site = replace(site, plan={**site.plan, "calibration": calibration})
            folder = stage / name
            folder.mkdir()
            plan_sha = _write_site(folder, site, exercise_id=exercise_id, name=name)
            nonce = hashlib.sha256(digest + name.encode()).digest()[:15]
            key = seal(site.misch, binding=trial_binding(exercise_id, name, plan_sha), nonce=nonce)
            card = TrialCard(
                BONE_QUALITY, exercise_id, name, trials, calibration, plan_sha, key, TASK
            )
            write_file(folder / TRIAL_CARD, json.dumps(card.to_json(), indent=2) + "\n")
            written.append(WrittenTrial(name, site.misch, site.source, card))
    if key_path is not None:
        text = key_json(written, params=params)
        atomic_write_bytes(key_path, text.encode("utf-8"), what="--key")
    return written


def key_json(trials: Sequence[WrittenTrial], *, params: Sequence[Any] = ()) -> str:
    """The instructor's plain key: each trial's class and source, and the exercise's
    parameters (``params``: they hash to its id, :func:`exercise_digest`; the seed is in no
    trial's files, so a key that holds them is the instructor's)."""
    doc = {
        "format": KEY_FORMAT,
        "exercise": BONE_QUALITY,
        "exercise_id": trials[0].card.exercise_id if trials else None,
        "trials": [
            {
                "trial": t.name,
                "misch": t.misch,
                "source": t.source,
                "plan_sha256": t.card.plan_sha256,
            }
            for t in trials
        ],
        "params": list(params),
    }
    return json.dumps(doc, indent=2) + "\n"
