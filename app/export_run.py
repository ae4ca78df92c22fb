"""``ctdrill export`` end to end: load the CT once, every plan, compute, then write.

All inputs are read and every path computed before the first file is written, so bad input
(one bad plan among many, a refused path) leaves the output folder untouched.
"""

from __future__ import annotations

import os
import re
import stat
from collections import Counter
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from ctdrill.app.errors import AppInputError
from ctdrill.app.export import DEFAULT_RATE_HZ, ExportInputError, ExportJob, write_exports
from ctdrill.app.export_band import hu_uncertainty_option
from ctdrill.app.grey_option import GreyMapSpec, hu_uncertainty, map_volume
from ctdrill.app.sequence_export import sequence_files, sequence_jobs
from ctdrill.engine.path import plan_path
from ctdrill.engine.plans import plan_calibration_key, with_set_warnings
from ctdrill.engine.sequence import SequenceResult, plan_sequence
from ctdrill.imaging import load_ct
from ctdrill.imaging.plan.types import Plan, load_plan_set, plan_warnings
from ctdrill.imaging.volume import CTVolume
from ctdrill.model.band import HuUncertainty
from ctdrill.model.calibration import Calibration, load_calibration

#: DICOM attributes written only with ``--include-phi`` (keyword -> summary key).
PHI_KEYWORDS = {
    "PatientName": "patient_name",
    "PatientID": "patient_id",
    "PatientBirthDate": "patient_birth_date",
    "PatientSex": "patient_sex",
    "InstitutionName": "institution_name",
    "StudyDate": "study_date",
    "AccessionNumber": "accession_number",
}


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


def _regular(path: Path) -> bool:
    try:
        return stat.S_ISREG(os.stat(path).st_mode)
    except OSError:
        return False


def read_patient_fields(dicom: Path, series_uid: str) -> dict[str, str]:
    """Patient identifiers of the series (for ``--include-phi`` only), as strings."""
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
    """Everything ``ctdrill export`` computes before writing (``ctdrill report`` draws it).

    Attributes
    ----------
    volume : the CT as loaded (grey-mapped when a map was given).
    plans : every trajectory, in order (feed overridden when asked).
    jobs : one per trajectory, or per drill of a sequence, in order.
    sequences : the drill sequences with their output subfolders.
    patient : the identifiers (``include_phi`` only), else None.
    hu_uncertainty : ``--hu-sigma`` and the grey map's uncertainty, or None.
    grey_to_hu : the grey map applied (its JSON), or None.
    """

    volume: CTVolume
    plans: tuple[Plan, ...]
    jobs: tuple[ExportJob, ...]
    sequences: tuple[tuple[SequenceResult, str], ...]
    patient: dict[str, str] | None
    hu_uncertainty: HuUncertainty | None
    grey_to_hu: dict[str, Any] | None


def prepare_case(
    dicom: Path,
    plan_paths: Sequence[Path],
    *,
    calibration: str | None = None,
    feed_mm_s: float | None = None,
    rate_hz: float = DEFAULT_RATE_HZ,
    include_phi: bool = False,
    series_uid: str | None = None,
    progress: Callable[[int, int, str], None] | None = None,
    interpolate_gaps: bool = False,
    hu_sigma: float | None = None,
    grey: GreyMapSpec | None = None,
) -> PreparedCase:
    """Read every input and compute every trajectory of ``plan_paths`` on the CT in
    ``dicom`` (parameters as :func:`export_case`); nothing is written.

    Raises
    ------
    AppInputError, ImagingInputError, ModelInputError
        Bad input (one line naming the file or field).
    """
    if feed_mm_s is not None and not feed_mm_s > 0.0:
        raise ExportInputError(f"--feed-mm-s must be a positive number, got {feed_mm_s!r}")
    if not rate_hz > 0.0:
        raise ExportInputError(f"--rate-hz must be a positive number, got {rate_hz!r}")
    manual_hu = hu_uncertainty_option(hu_sigma)
    plans = list(with_set_warnings(load_plan_set(plan_paths)))
    per_file = Counter(plan.source for plan in plans)
    volume, grey_map = map_volume(load_ct(dicom, series_uid=series_uid), grey)
    hu_unc = hu_uncertainty(grey_map, manual_hu)
    cache: dict[str, Calibration] = {}
    override = load_calibration(calibration) if calibration is not None else None
    jobs: list[ExportJob] = []
    sequences: list[tuple[SequenceResult, str]] = []
    seen: dict[str, tuple[str, str]] = {}
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
        if feed_mm_s is not None:
            plan = replace(plan, feed_mm_s=feed_mm_s)  # the path's feed warnings see it
            plans[n] = plan
        sub = "" if len(plans) == 1 else _subdir(_stem(plan, per_file[plan.source]))
        if sub in seen:
            first, source = seen[sub]
            raise AppInputError(
                f"--plan: trajectories {first!r} ({Path(source).name}) and {plan.name!r} "
                f"({Path(plan.source).name}) would both write the output folder {sub!r}; "
                "rename one so their outputs do not overwrite each other"
            )
        seen[sub] = (plan.name, plan.source)
        if len(plan.drills) > 1:  # a drill sequence: OUT[/plan]/drill_k/ + summary.json
            seq = plan_sequence(volume, plan, cal, interpolate_gaps=interpolate_gaps)
            sequences.append((seq, sub))
            jobs.extend(sequence_jobs(seq, sub))
            continue
        result = plan_path(volume, plan, cal, interpolate_gaps=interpolate_gaps)
        jobs.append(ExportJob(result=result, subdir=sub))
    patient = None
    if include_phi:
        patient = (
            read_patient_fields(dicom, volume.info.series_uid)
            if volume.info.source_format == "DICOM"
            else {"description": volume.info.series_description}  # NIfTI descrip, NRRD content
        )
    return PreparedCase(
        volume=volume,
        plans=tuple(plans),
        jobs=tuple(jobs),
        sequences=tuple(sequences),
        patient=patient,
        hu_uncertainty=hu_unc,
        grey_to_hu=None if grey_map is None else grey_map.to_json(),
    )


def export_case(
    dicom: Path,
    plan_paths: Sequence[Path],
    out_dir: Path,
    *,
    calibration: str | None = None,
    feed_mm_s: float | None = None,
    rate_hz: float = DEFAULT_RATE_HZ,
    include_phi: bool = False,
    series_uid: str | None = None,
    progress: Callable[[int, int, str], None] | None = None,
    extra_files: Mapping[str, bytes | str] | None = None,
    warn: Callable[[str, str], None] | None = None,
    interpolate_gaps: bool = False,
    plot: bool = True,
    per_trajectory: bool = False,
    hu_sigma: float | None = None,
    grey: GreyMapSpec | None = None,
) -> list[Path]:
    """Export every trajectory of ``plan_paths`` on the CT in ``dicom``.

    One trajectory writes its files into ``out_dir``; several write one table,
    ``out_dir/trajectories.csv`` (one row per trajectory, or per drill of a sequence), and,
    with ``per_trajectory``, each one's files into ``out_dir/<plan name>/``. A plan with a
    drill sequence writes one folder per drill, ``drill_1/``, ``drill_2/`` ..., beside its
    ``summary.json`` listing them (:mod:`ctdrill.app.sequence_export`).

    Parameters
    ----------
    calibration : overrides every plan's calibration (a set name or a JSON path).
    feed_mm_s : overrides every plan's feed, mm/s.
    rate_hz : force.csv sample rate, Hz.
    include_phi : add the patient identifiers to summary.json.
    series_uid : SeriesInstanceUID to load (default: the largest CT series).
    extra_files : more files (relative path -> content) written in the same atomic swap.
    warn : called with (code, message), once the files are written, for what the terminal
        must show (``no_landmarks``).
    interpolate_gaps : interpolate across slice gaps the drill crosses instead of refusing
        (each summary then says so).
    plot : write ``force.png`` (False: ``--no-plot``, for screening).
    per_trajectory : with several trajectories, also write each one's files.
    hu_sigma : SD of the series' HU (``--hu-sigma``), entered into every force band.
    grey : a grey-to-HU map (``--grey-to-hu``/``--grey-ref``) applied to the series as loaded;
        recorded in every summary, its uncertainty entered into the force band.

    Returns
    -------
    The written files.
    """
    case = prepare_case(
        dicom,
        plan_paths,
        calibration=calibration,
        feed_mm_s=feed_mm_s,
        rate_hz=rate_hz,
        include_phi=include_phi,
        series_uid=series_uid,
        progress=progress,
        interpolate_gaps=interpolate_gaps,
        hu_sigma=hu_sigma,
        grey=grey,
    )
    series_uid_loaded = case.volume.info.series_uid
    several = len(case.plans) > 1
    extra_files = dict(extra_files or {})
    files = not several or per_trajectory  # several: the table, files only if asked
    for seq, sub in case.sequences if files else ():
        extra_files |= sequence_files(
            seq,
            sub,
            feed_mm_s=feed_mm_s,
            rate_hz=rate_hz,
            series_uid=series_uid_loaded,
            patient=case.patient,
            include_phi=include_phi,
            hu_uncertainty=case.hu_uncertainty,
            grey_to_hu=case.grey_to_hu,
        )
    written = write_exports(
        case.jobs,
        out_dir,
        feed_mm_s=feed_mm_s,
        rate_hz=rate_hz,
        series_uid=series_uid_loaded,
        patient=case.patient,
        progress=progress,
        extra_files=extra_files,
        include_phi=include_phi,
        plot=plot,
        files=files,
        table=several,
        hu_uncertainty=case.hu_uncertainty,
        grey_to_hu=case.grey_to_hu,
    )
    if warn is not None:
        for plan in case.plans:
            for code, message in plan_warnings(plan):
                if code == "no_landmarks":
                    warn(code, message)
    return written
