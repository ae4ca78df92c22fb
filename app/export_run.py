"""``ctdrill export`` end to end: compute the case (the engine), then write its files.

All inputs are read and every path computed before the first file is written
(:func:`ctdrill.engine.case.prepare_case`), so bad input (one bad plan among many, a refused
path) leaves the output folder untouched.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

from ctdrill import jit
from ctdrill.app.export import write_exports
from ctdrill.app.sequence_export import sequence_files
from ctdrill.engine.case import PreparedCase, prepare_case
from ctdrill.engine.settings import DEFAULTS, ExportSettings
from ctdrill.engine.summarize import JobSummary
from ctdrill.imaging.plan.types import plan_warnings


def write_case(
    case: PreparedCase,
    out_dir: Path,
    *,
    progress: Callable[[int, int, str], None] | None = None,
    extra_files: Mapping[str, bytes | str] | None = None,
    done: Sequence[JobSummary] | None = None,
) -> list[Path]:
    """Write a computed case into ``out_dir`` (replaced whole): one trajectory's files into
    ``out_dir``; several, the table ``out_dir/trajectories.csv`` (one row per trajectory, or
    per drill of a sequence) and, with ``per_trajectory``, each one's files into
    ``out_dir/<plan name>/``; a drill sequence, one folder per drill beside its listing
    ``summary.json`` (:mod:`ctdrill.app.sequence_export`). ``done``: the jobs' summaries when
    computed already. Returns the written files."""
    several = len(case.plans) > 1
    extra = dict(extra_files or {})
    files = not several or case.settings.per_trajectory  # several: the table, files if asked
    for seq, sub in case.sequences if files else ():
        extra |= sequence_files(seq, sub, case.context)
    return write_exports(
        case.jobs,
        out_dir,
        case.context,
        files=files,
        table=several,
        progress=progress,
        extra_files=extra,
        done=done,
    )


def export_case(
    dicom: Path,
    plan_paths: Sequence[Path],
    out_dir: Path,
    settings: ExportSettings = DEFAULTS,
    *,
    progress: Callable[[int, int, str], None] | None = None,
    extra_files: Mapping[str, bytes | str] | None = None,
    warn: Callable[[str, str], None] | None = None,
) -> list[Path]:
    """Export every trajectory of ``plan_paths`` on the CT in ``dicom`` with ``settings``
    (:func:`~ctdrill.engine.case.prepare_case`, then :func:`write_case`).

    Parameters
    ----------
    settings : every option (:class:`~ctdrill.engine.settings.ExportSettings`).
    progress : called with (done, total, name) while computing and writing.
    extra_files : more files (relative path -> content) written in the same atomic swap.
    warn : called with (code, message), once the files are written, for what the terminal
        must show (``no_landmarks``).

    Returns
    -------
    The written files.
    """
    case = prepare_case(dicom, plan_paths, settings, progress=progress)
    with jit.job(len(case.plans)):  # what prepare_case chose (ctdrill.jit.job)
        written = write_case(case, out_dir, progress=progress, extra_files=extra_files)
    if warn is not None:
        for plan in case.plans:
            for w in plan_warnings(plan):
                if w.code == "no_landmarks":
                    warn(w.code, w.message)
    return written
