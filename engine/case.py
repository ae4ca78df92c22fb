"""A case: one CT and every trajectory of its plans, read and computed before anything is
written (``ctdrill export``, ``report`` and ``batch`` write it; ``ctdrill.api`` returns it).

All inputs are read and every path computed first, so bad input (one bad plan among many, a
refused path) leaves an output folder untouched.
"""

from __future__ import annotations

import os
import re
import stat
from collections import Counter
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

from ctdrill import jit
from ctdrill.engine.errors import ExportInputError
from ctdrill.engine.grey import hu_sigma_uncertainty, hu_uncertainty, map_volume
from ctdrill.engine.path import PathResult, plan_path
from ctdrill.engine.plans import plan_calibration_key, with_set_warnings
from ctdrill.engine.record import from_json
from ctdrill.engine.sequence import SequenceResult, drill_folder, plan_sequence
from ctdrill.engine.settings import DEFAULTS, ExportSettings
from ctdrill.engine.summarize import CaseContext
from ctdrill.engine.summary import GreyMapInfo
from ctdrill.engine.verdict import PlanVerdict, plan_verdict
from ctdrill.imaging import load_ct
from ctdrill.imaging.dicom.grey import GreyToHu
from ctdrill.imaging.plan.load import load_plan_set
from ctdrill.imaging.plan.types import Plan
from ctdrill.imaging.resolution import volume_clearance_accuracy_mm
from ctdrill.imaging.volume import CTVolume
from ctdrill.model.calibration import Calibration, load_calibration

#: DICOM attributes written only with ``include_phi`` (keyword -> summary key).
PHI_KEYWORDS = {
    "PatientName": "patient_name",
    "PatientID": "patient_id",
    "PatientBirthDate": "patient_birth_date",
    "PatientSex": "patient_sex",
    "InstitutionName": "institution_name",
    "StudyDate": "study_date",
    "AccessionNumber": "accession_number",
}

Progress = Callable[[int, int, str], None]


class DuplicateTrajectoryError(ExportInputError):
    """Two trajectories whose outputs would overwrite each other."""


@dataclass(frozen=True)
class ExportJob:
    """One trajectory's (or one drill's) path, the subfolder its files go into, and the
    trajectory's verdict (:class:`~ctdrill.engine.verdict.PlanVerdict`: the warnings every
    output lists), or None for one drill of a sequence (its own path's warnings)."""

    result: PathResult
    subdir: str
    verdict: PlanVerdict | None = None


def _subdir(name: str) -> str:
    safe = re.sub(r"[^A-Za-z0-9._-]+", "_", name).strip("._")
    return safe or "plan"


def _stem(plan: Plan, n_in_file: int) -> str:
    """Output folder name: the plan file's stem (plus the trajectory name if it holds several)."""
    name = Path(plan.source).name
    for suffix in (".mrk.json", ".json"):
        if name.lower().endswith(suffix):
            name = name[: -len(suffix)]
            break
    return name if n_in_file == 1 else f"{name}-{plan.name}"


def _join(subdir: str, name: str) -> str:
    return f"{subdir}/{name}" if subdir else name


def sequence_jobs(seq: SequenceResult, subdir: str) -> list[ExportJob]:
    """One job per drill, into ``subdir/drill_k`` (``drill_k`` when ``subdir`` is "")."""
    return [
        ExportJob(result=step, subdir=_join(subdir, drill_folder(k)))
        for k, step in enumerate(seq.steps)
    ]


def _regular(path: Path) -> bool:
    try:
        return stat.S_ISREG(os.stat(path).st_mode)
    except OSError:
        return False


def read_patient_fields(dicom: Path, series_uid: str) -> dict[str, str]:
    """Patient identifiers of the series (for ``include_phi`` only), as strings."""
    import pydicom

    from ctdrill.imaging.dicom.discovery import iter_files

    for path in iter_files(dicom):
        if not _regular(path):  # a pipe or device beside the series: never opened
            continue
        try:
            ds = pydicom.dcmread(
                path,
                stop_before_pixels=True,
                specific_tags=[*PHI_KEYWORDS, "SeriesInstanceUID"],
            )
        except Exception:  # any unreadable file is simply not the one we want
            continue
        if str(ds.get("SeriesInstanceUID", "")) != series_uid:
            continue
        return {key: str(ds.get(kw, "")) for kw, key in PHI_KEYWORDS.items()}
    return {}


@dataclass(frozen=True, eq=False)
class PreparedCase:
    """Everything an export computes before writing (``ctdrill report`` draws it).

    Attributes
    ----------
    volume : the CT as loaded (grey-mapped when a map was given).
    plans : every trajectory, in order (feed overridden when asked).
    jobs : one per trajectory, or per drill of a sequence, in order.
    sequences : the drill sequences with their output subfolders.
    context : what every summary shares (settings, series, patient, HU error, grey map).
    """

    volume: CTVolume
    plans: tuple[Plan, ...]
    jobs: tuple[ExportJob, ...]
    sequences: tuple[tuple[SequenceResult, str], ...]
    context: CaseContext

    @property
    def settings(self) -> ExportSettings:
        """The export's options."""
        return self.context.settings


def check_settings(settings: ExportSettings) -> None:
    """Refuse settings no case can use (a feed or rate that is not a positive number)."""
    if settings.feed_mm_s is not None and not settings.feed_mm_s > 0.0:
        raise ExportInputError(f"--feed-mm-s must be a positive number, got {settings.feed_mm_s!r}")
    if not settings.rate_hz > 0.0:
        raise ExportInputError(f"--rate-hz must be a positive number, got {settings.rate_hz!r}")


def prepare_case(
    dicom: Path,
    plan_paths: Sequence[Path],
    settings: ExportSettings = DEFAULTS,
    *,
    progress: Progress | None = None,
) -> PreparedCase:
    """Read every input and compute every trajectory of ``plan_paths`` on the CT in
    ``dicom`` with ``settings``; nothing is written.

    One trajectory's output goes into the output folder itself; several, each into a
    subfolder named after its plan file (and trajectory); a drill sequence, one folder per
    drill (``drill_1``, ...).

    Raises
    ------
    EngineInputError, ImagingInputError, ModelInputError
        Bad input (one line naming the file or field).
    """
    check_settings(settings)
    hu_sigma_uncertainty(settings.hu_sigma)  # a bad --hu-sigma is refused before any load
    plans = list(with_set_warnings(load_plan_set(plan_paths)))
    with jit.job(len(plans)):  # one plan: numba not loaded for it (ctdrill.jit, same bits)
        return _prepare(dicom, plans, settings, progress)


def _prepare(
    dicom: Path, plans: list[Plan], settings: ExportSettings, progress: Progress | None
) -> PreparedCase:
    per_file = Counter(plan.source for plan in plans)
    volume, grey_map = map_volume(load_ct(dicom, series_uid=settings.series), settings.grey)
    cache: dict[str, Calibration] = {}
    override = None if settings.calibration is None else load_calibration(settings.calibration)
    jobs: list[ExportJob] = []
    sequences: list[tuple[SequenceResult, str]] = []
    seen: dict[str, tuple[str, str]] = {}
    gaps = settings.interpolate_gaps
    for n, plan in enumerate(plans):
        if progress is not None:
            progress(n, len(plans), plan.name)
        if override is not None:
            cal = override
        else:
            key = plan_calibration_key(plan)
            if key not in cache:
                cache[key] = load_calibration(key)
            cal = cache[key]
        if settings.feed_mm_s is not None:
            plan = replace(plan, feed_mm_s=settings.feed_mm_s)  # the path's feed warnings see it
            plans[n] = plan
        if settings.placement is not None:
            plan = replace(plan, placement=settings.placement)  # the margin budget's mode
            plans[n] = plan
        sub = "" if len(plans) == 1 else _subdir(_stem(plan, per_file[plan.source]))
        if sub in seen:
            first, source = seen[sub]
            raise DuplicateTrajectoryError(
                f"--plan: trajectories {first!r} ({Path(source).name}) and {plan.name!r} "
                f"({Path(plan.source).name}) would both write the output folder {sub!r}; "
                "rename one so their outputs do not overwrite each other"
            )
        seen[sub] = (plan.name, plan.source)
        if len(plan.drills) > 1:  # a drill sequence: OUT[/plan]/drill_k/ + summary.json
            seq = plan_sequence(volume, plan, cal, interpolate_gaps=gaps)
            sequences.append((seq, sub))
            jobs.extend(sequence_jobs(seq, sub))
            continue
        # with an implant the drill reaches the apex plus its tip (Plan.drilled)
        result = plan_path(volume, plan.drilled(0), cal, interpolate_gaps=gaps)
        jobs.append(ExportJob(result, sub, plan_verdict(volume, plan, path=result)))
    patient = None
    if settings.include_phi:
        patient = (
            read_patient_fields(dicom, volume.info.series_uid)
            if volume.info.source_format == "DICOM"
            else {"description": volume.info.series_description}  # NIfTI descrip, NRRD content
        )
    context = case_context(volume, grey_map, settings, patient=patient)
    return PreparedCase(volume, tuple(plans), tuple(jobs), tuple(sequences), context)


def case_context(
    volume: CTVolume,
    grey_map: GreyToHu | None,
    settings: ExportSettings = DEFAULTS,
    *,
    patient: Mapping[str, str] | None = None,
) -> CaseContext:
    """What every summary of a case on ``volume`` (as loaded, ``grey_map`` applied) shares:
    the export's and the rehearsal's (the same values for the same plan)."""
    return CaseContext(
        settings=settings,
        series_uid=volume.info.series_uid,
        patient=patient,
        hu_uncertainty=hu_uncertainty(grey_map, hu_sigma_uncertainty(settings.hu_sigma)),
        grey_to_hu=None if grey_map is None else from_json(GreyMapInfo, grey_map.to_json()),
        clearance_accuracy_mm=volume_clearance_accuracy_mm(volume),
    )
