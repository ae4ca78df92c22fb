"""ctdrill's stable Python API, for notebooks, scripts and outside checks.

A thin, explicit facade over the rooms (``docs/api.md``): these names and signatures are kept;
what is behind them may move. Importing it loads nothing heavy (each function imports its
work, the types load on first use)::

    from ctdrill import api

    volume = api.load_series("assets/demo/ct")
    plan = api.load_plan("assets/demo/plan.json")
    path = api.plan_path(volume, plan)  # the plan's calibration set unless given
    print(path.stop_depth_mm, path.stop_reason, path.profile.s0_n.max())
    batch = api.evaluate_batch(volume, plan, entries_lps, targets_lps)  # (N, 3) each
    done = api.export_case("assets/demo/ct", ["assets/demo/plan.json"], "out")
    print(done.summaries[0].outcome.stop_depth_mm)

Names: :func:`load_series`, :func:`load_plan`, :func:`plan_path`, :func:`implant_outcome`,
:func:`implant_facts`, :func:`evaluate_batch`, :func:`export_case`, :func:`summarize`,
:func:`read_summary`; the values they return (:class:`CTVolume`, :class:`Plan`,
:class:`PathResult`, :class:`ImplantOutcome`, :class:`ImplantFacts`, :class:`BatchResult`,
:class:`CaseExport`) and the summary types (:class:`TrajectorySummary`,
:class:`SequenceSummary`), :class:`ExportSettings`. Bad input raises the rooms' input errors
(``ValueError`` subclasses whose message names the file or field).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ctdrill.lazy import attach

if TYPE_CHECKING:
    import numpy as np

    from ctdrill.engine.batch import BatchResult
    from ctdrill.engine.implant import ImplantOutcome
    from ctdrill.engine.implant_facts import ImplantFacts
    from ctdrill.engine.path import PathResult
    from ctdrill.engine.settings import ExportSettings
    from ctdrill.engine.summary import SequenceSummary, TrajectorySummary
    from ctdrill.imaging.plan.types import Plan
    from ctdrill.imaging.volume import CTVolume
    from ctdrill.model.calibration import Calibration

#: public type -> the module that defines it (imported on first use)
_EXPORTS: dict[str, str] = {
    "BatchResult": "ctdrill.engine.batch",
    "CTVolume": "ctdrill.imaging.volume",
    "ExportSettings": "ctdrill.engine.settings",
    "ImplantFacts": "ctdrill.engine.implant_facts",
    "ImplantOutcome": "ctdrill.engine.implant",
    "PathResult": "ctdrill.engine.path",
    "Plan": "ctdrill.imaging.plan.types",
    "SequenceSummary": "ctdrill.engine.summary",
    "TrajectorySummary": "ctdrill.engine.summary",
}

__getattr__, __dir__ = attach(__name__, _EXPORTS)

StrPath = str | os.PathLike[str]

__all__ = [
    "BatchResult",
    "CTVolume",
    "CaseExport",
    "ExportSettings",
    "ImplantFacts",
    "ImplantOutcome",
    "PathResult",
    "Plan",
    "SequenceSummary",
    "TrajectorySummary",
    "evaluate_batch",
    "export_case",
    "implant_facts",
    "implant_outcome",
    "load_ct",
    "load_plan",
    "load_series",
    "open_window",
    "plan_path",
    "read_summary",
    "summarize",
]


def _guard(*, plans: Sequence[Path] = (), ct: Path | None = None) -> None:
    """A blind trial's plan or CT is refused here as by the CLI (docs/exercises.md)."""
    from ctdrill.app.exercise.blind import blind_guard

    blind_guard("api", plans=plans, ct=ct, keyed=False)


def load_series(path: StrPath, *, series_uid: str | None = None) -> CTVolume:
    """The CT series in the folder ``path`` (DICOM) as a volume in LPS mm.

    ``series_uid``: the SeriesInstanceUID (or its hash prefix, as ``inspect`` prints it) when
    the folder holds several; default the largest CT series. ``.hu`` is (slices, rows, cols),
    ``.affine_lps`` maps (i, j, k, 1) to LPS mm, ``.warnings`` says what to know.
    """
    from ctdrill.imaging.dicom.series import load_series as load

    _guard(ct=Path(path))
    return load(Path(path), series_uid=series_uid)


def load_ct(path: StrPath, *, series_uid: str | None = None) -> CTVolume:
    """The CT at ``path``, whatever it is (``--ct``): a DICOM folder or file, NIfTI
    (``.nii``, ``.nii.gz``), NRRD (``.nrrd``, ``.nhdr``) or MetaImage (``.mha``, ``.mhd``),
    told by content; a volume in LPS mm as :func:`load_series` returns
    (``.info.source_format`` says which; docs/volumes.md)."""
    from ctdrill.imaging.volumes.load import load_ct as load

    _guard(ct=Path(path))
    return load(Path(path), series_uid=series_uid)


def load_plan(path: StrPath) -> Plan:
    """The one trajectory of a plan file (``ctdrill-plan/1`` or a 3D Slicer ``.mrk.json``),
    in LPS; a file holding several trajectories is refused (pick one with ``load_plans`` of
    :mod:`ctdrill.imaging`)."""
    from ctdrill.imaging.plan.load import load_plan as load

    _guard(plans=[Path(path)])
    return load(Path(path))


def _calibration(plan: Plan, calibration: Calibration | str | None) -> Calibration:
    from ctdrill.engine.plans import plan_calibration
    from ctdrill.model.calibration import load_calibration

    if calibration is None:
        return plan_calibration(plan)
    if isinstance(calibration, str):
        return load_calibration(calibration)
    return calibration


def plan_path(
    volume: CTVolume,
    plan: Plan,
    calibration: Calibration | str | None = None,
    *,
    depth_step_mm: float | None = None,
    interpolate_gaps: bool = False,
) -> PathResult:
    """One trajectory through the CT: the lip's HU, the force profile, the clearance to every
    landmark, the max safe depth and the stop (``ctdrill export`` computes the same).

    A single-drill plan with an implant is drilled as the export drills it
    (``plan.drilled(0)``: to the implant's apex plus the drill's tip length), and the result's
    ``implant`` holds :func:`implant_outcome`. A plan with a drill sequence gives its final
    drill alone as given (the export's ``drill_k`` folders cut around the earlier holes).

    ``calibration``: a set, a set's name or JSON path; default the plan's own.
    ``depth_step_mm``: the profile's step (default 0.05 mm). ``interpolate_gaps``:
    interpolate across slice gaps the drill crosses instead of refusing.
    """
    from ctdrill.engine.grid import DEFAULT_DEPTH_STEP_MM
    from ctdrill.engine.path import plan_path as path

    step = DEFAULT_DEPTH_STEP_MM if depth_step_mm is None else depth_step_mm
    return path(
        volume,
        plan if plan.earlier_drills else plan.drilled(0),
        _calibration(plan, calibration),
        depth_step_mm=step,
        interpolate_gaps=interpolate_gaps,
    )


def implant_outcome(volume: CTVolume, plan: Plan) -> ImplantOutcome | None:
    """The implant of ``plan`` on ``volume``, as every output reports it: ``.clearance_mm``
    (signed distance from the implant body to the binding landmark, < 0 inside),
    ``.binding_name``/``.binding_margin_mm``, ``.walls`` (the thinnest bone walls,
    ``.walls.min_mm``, ``.buccal_mm``, ``.lingual_mm``, ``.perforation``), ``.accuracy_mm``
    (what the CT's sampling lets a clearance claim) and ``.warnings`` (each a ``LoadWarning``,
    ``.code`` and ``.message``: ``implant_violates_margin``, ``plan_violates_margin``,
    ``thin_wall``, ``cortical_perforation``, ``bone_walls_unknown``); None when the plan places no
    implant."""
    from ctdrill.engine.implant import implant_outcome as outcome

    return outcome(volume, plan)


def implant_facts(volume: CTVolume, plan: Plan) -> ImplantFacts | None:
    """The clinical values of ``plan``'s implant (the report's implant page): ``.site_text``,
    ``.drills`` (each with its ``drilled_depth_mm``), ``.angulation_deg`` (to the patient's
    vertical), ``.nerve``/``.nerve_mm`` (the implant body's clearance to the nearest canal),
    ``.min_wall_mm``/``.buccal_mm``/``.lingual_mm``, ``.crest_depth_mm``,
    ``.canal_depth_mm`` and ``.bone_height_mm`` (crest to canal along the axis),
    ``.accuracy_mm``; None when the plan places no implant."""
    from ctdrill.engine.implant_facts import implant_facts as facts

    return facts(volume, plan)


def evaluate_batch(
    volume: CTVolume,
    plan: Plan,
    entries_lps: np.ndarray,
    targets_lps: np.ndarray,
    calibration: Calibration | str | None = None,
    *,
    depth_step_mm: float | None = None,
    interpolate_gaps: bool = False,
) -> BatchResult:
    """``N`` trajectories sharing ``plan``'s drill, landmarks and margins, in one batch: row
    ``n`` of every array is :func:`plan_path` on the entry and target ``n`` ((N, 3) LPS mm),
    or the message it refuses that row with (``.refusal``)."""
    from ctdrill.engine.batch import evaluate_batch as batch
    from ctdrill.engine.grid import DEFAULT_DEPTH_STEP_MM

    step = DEFAULT_DEPTH_STEP_MM if depth_step_mm is None else depth_step_mm
    return batch(
        volume,
        plan,
        entries_lps,
        targets_lps,
        _calibration(plan, calibration),
        depth_step_mm=step,
        interpolate_gaps=interpolate_gaps,
    )


@dataclass(frozen=True, eq=False)
class CaseExport:
    """What :func:`export_case` wrote and what it says.

    Attributes
    ----------
    files : every file written.
    summaries : each trajectory's (each drill's) summary, in order: what its
        ``summary.json`` holds (written or not: several trajectories write the table).
    sequences : each drill sequence's listing, in order.
    """

    files: tuple[Path, ...]
    summaries: tuple[TrajectorySummary, ...]
    sequences: tuple[SequenceSummary, ...]


def export_case(
    dicom: StrPath,
    plans: Sequence[StrPath],
    out_dir: StrPath,
    settings: ExportSettings | None = None,
) -> CaseExport:
    """``ctdrill export``: every trajectory of the plan files ``plans`` on the CT in ``dicom``,
    written into ``out_dir`` (replaced whole), with ``settings`` (default: none given)."""
    from ctdrill.app.export_run import write_case
    from ctdrill.engine.case import prepare_case
    from ctdrill.engine.settings import DEFAULTS
    from ctdrill.engine.summarize import job_summary, sequence_summary

    _guard(plans=[Path(p) for p in plans], ct=Path(dicom))
    case = prepare_case(
        Path(dicom), [Path(p) for p in plans], DEFAULTS if settings is None else settings
    )
    done = [job_summary(job.result, case.context) for job in case.jobs]
    files = write_case(case, Path(out_dir), done=done)
    return CaseExport(
        files=tuple(files),
        summaries=tuple(d.summary for d in done),
        sequences=tuple(sequence_summary(seq, case.context) for seq, _ in case.sequences),
    )


def summarize(
    path: PathResult, settings: ExportSettings | None = None, *, series_uid: str = ""
) -> TrajectorySummary:
    """The summary ``ctdrill export`` writes of ``path`` with ``settings`` (its series named
    by ``series_uid``, written hashed)."""
    from ctdrill.engine.settings import DEFAULTS
    from ctdrill.engine.summarize import CaseContext, job_summary

    context = CaseContext(DEFAULTS if settings is None else settings, series_uid=series_uid)
    return job_summary(path, context).summary


def read_summary(source: StrPath | dict[str, Any]) -> TrajectorySummary | SequenceSummary:
    """A written ``summary.json`` (its path, or the parsed document) as its summary."""
    import json

    from ctdrill.engine.summary import read_summary as read

    doc = source if isinstance(source, dict) else json.loads(Path(source).read_text("utf-8"))
    return read(doc)


def open_window(
    dicom: StrPath,
    plans: Sequence[StrPath | Plan] = (),
    implants: StrPath | Sequence[Any] | None = None,
    *,
    settings: Any = None,
) -> Any:
    """The desktop window, shown, with the CT ``dicom`` (any :func:`load_ct` source) loaded
    and its first computation finished, for scripts that drive it with real Qt events
    (docs/gui.md: the views' object names, ``pixel_to_lps``/``lps_to_pixel``, the force
    plot's ``stopDepthMm``). ``plans``: plan files or :class:`Plan` values; ``implants``: an
    implant library file or specs (None: the shipped library); ``settings``: a ``QSettings`` the
    window keeps its settings in (None: the user's). Needs a Qt platform (a display
    or Xvfb) and creates the ``QApplication`` if there is none."""
    from ctdrill.app.gui.api import open_window as open_

    return open_(dicom, plans, implants, settings=settings)
