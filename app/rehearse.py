"""Headless rehearsal: CT + plan -> force table -> a device session -> session.csv, summary.json.

``ctdrill rehearse`` and the tests call :func:`rehearse`; the GUI calls the same pieces
(:func:`open_device`, :func:`ctdrill.haptics.run.run_session`, :func:`rehearsal_summary`).

Records: the output folder is written whole or not at all
(:func:`ctdrill.app.records.atomic_output_dir`): the previous session stays as it was until the
new one replaces it. Before ARM (bad input, a device that does not answer or refuses the table)
nothing is written. Once the device was armed, ``summary.json`` is always written, with
``complete`` and, when the session did not run its course, ``outcome`` and ``reason``.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from ctdrill.app.errors import AppInputError
from ctdrill.app.exercise.aids import AidLevel
from ctdrill.app.exercise.trials import blind_summary, check_session_plan, find_trial
from ctdrill.app.igtl.frames import StreamGeometry, parse_target
from ctdrill.app.igtl.stream import IgtlStream
from ctdrill.app.records import atomic_output_dir, write_file
from ctdrill.app.session_run import (
    AssessmentObserver,
    CsvObserver,
    RehearsalSession,
    SessionObserver,
    StreamObserver,
    rehearsal_summary,
    summary_json,
)
from ctdrill.app.trainee.exam import (
    ExamSetup,
    assessment_context,
    exam_at_surface,
    exam_setup,
    plan_hash,
)
from ctdrill.app.trainee.session_table import TABLE_FILE, table_text
from ctdrill.engine.case import case_context
from ctdrill.engine.grey import hu_sigma_uncertainty, map_volume
from ctdrill.engine.path import PathResult, plan_path
from ctdrill.engine.plans import one_trajectory, plan_calibration
from ctdrill.engine.settings import DEFAULTS, GreyMapSpec
from ctdrill.engine.summarize import CaseContext
from ctdrill.engine.verdict import PlanVerdict, plan_verdict
from ctdrill.haptics.assessment import AssessmentContext, Assessor
from ctdrill.haptics.device import Device
from ctdrill.haptics.profile_table import ProfileTable
from ctdrill.haptics.session import parse_fault, parse_operator
from ctdrill.haptics.spec import DeviceSpec
from ctdrill.imaging import load_ct
from ctdrill.imaging.dicom.grey import GreyToHu
from ctdrill.interrupts import exit_code_for_signal, held

#: Exit code of a session that ended on a device fault or a host error (STOP, DISARM sent).
EXIT_DEVICE_FAULT = 3
#: Exit code of a session interrupted with Ctrl-C (STOP, DISARM sent, records written);
#: SIGTERM and SIGHUP are taken as Ctrl-C and exit 143 and 129 (``128 + signal``).
EXIT_INTERRUPTED = 130


@dataclass(frozen=True, eq=False)
class RehearsalTable:
    """The uploaded table and where it came from: ``path`` is the plan's own (guarded) path;
    in exam mode ``exam`` holds the table without the margin's wall (then ``table`` is its);
    ``verdict`` is the trajectory's (the warnings its summary lists, as the export's)."""

    table: ProfileTable
    path: PathResult
    case: CaseContext
    grey_map: GreyToHu | None = None
    exam: ExamSetup | None = None
    verdict: PlanVerdict | None = None

    @property
    def context(self) -> AssessmentContext:
        """What the session is measured against (its assessment)."""
        return assessment_context(self.path, None if self.exam is None else self.exam.path)


def load_table(
    dicom: Path,
    plan_file: Path | Sequence[Path],
    *,
    interpolate_gaps: bool = False,
    grey: GreyMapSpec | None = None,
    trajectory: str | None = None,
    exam: bool = False,
    exam_surface: bool = False,
    hu_sigma: float | None = None,
) -> RehearsalTable:
    """Load the CT and the plan (one file, or several merged into one trajectory), compute
    the path and adapt its profile to a device table.

    ``interpolate_gaps`` interpolates across slice gaps the drill crosses instead of refusing
    (the path's warnings then say so); ``grey`` maps grey values to HU (``--grey-to-hu``);
    ``trajectory`` picks one of several by name or number (``load_one_plan``); ``exam``
    uploads the exam's table (:func:`ctdrill.app.trainee.exam.exam_setup`; ``exam_surface``:
    its wall at the nearest landmark's surface, as on the robot); ``case`` is what the export's
    summary of the same CT, map and ``hu_sigma`` (``--hu-sigma``) shares.
    """
    volume, grey_map = map_volume(load_ct(dicom), grey)
    case = case_context(volume, grey_map, replace(DEFAULTS, hu_sigma=hu_sigma))
    plan = one_trajectory(
        [plan_file] if isinstance(plan_file, Path) else plan_file, trajectory=trajectory
    )
    whole = plan
    if not plan.earlier_drills:  # with an implant: to its apex plus the drill's tip
        plan = plan.drilled(0)
    path = plan_path(volume, plan, plan_calibration(plan), interpolate_gaps=interpolate_gaps)
    verdict = None if plan.earlier_drills else plan_verdict(volume, whole, path=path)
    if exam:
        setup = exam_setup(
            volume, plan, path, interpolate_gaps=interpolate_gaps, at_surface=exam_surface
        )
        return RehearsalTable(setup.table, path, case, grey_map, setup, verdict)
    table = ProfileTable.from_profile(path.profile, path.stop_depth_mm)
    return RehearsalTable(table, path, case, grey_map, verdict=verdict)


def open_device(spec: DeviceSpec, *, seed: int = 0) -> Device:
    """Open the device ``spec`` names (:meth:`ctdrill.haptics.spec.DeviceSpec.open`)."""
    return spec.open(seed=seed)


def rehearse(
    *,
    dicom: Path,
    plan: Path | Sequence[Path],
    out: Path,
    operator: str,
    duration_s: float,
    device: str | DeviceSpec = "sim",
    faults: Sequence[str] = (),
    seed: int = 0,
    interpolate_gaps: bool = False,
    hu_sigma: float | None = None,
    grey: GreyMapSpec | None = None,
    trajectory: str | None = None,
    exam: bool = False,
    notice: Callable[[str], None] | None = None,
    igtl: str | None = None,
    on_warning: Callable[[str], None] | None = None,
    aids: AidLevel | None = None,
) -> dict[str, Any]:
    """Run one rehearsal and write ``OUT/session.csv`` and ``OUT/summary.json`` (whole).

    ``aids``: a level of the stop-yourself exercise (:mod:`ctdrill.app.exercise.aids`): the
    summary's ``mode`` is the level's and ``aids`` says which aids were on; a level without
    the wall runs in exam mode. One drill at a time (a drill sequence is refused).

    ``trajectory`` picks one trajectory of several plan files by name or number; ``exam``
    removes the margin's wall (simulator only: refused with any other device; docs/rehearse.md);
    ``notice`` receives a line when the host retracts a handle a previous session left deep.
    ``igtl`` (``HOST:PORT``) streams the session to an OpenIGTLink server
    (:mod:`ctdrill.app.igtl`, docs/slicer.md; the simulator then runs at the wall clock's
    pace): ``summary.json`` gains ``igtl``; a failed connection is one call of ``on_warning``.

    A plan with a drill sequence runs one session per drill
    (:mod:`ctdrill.app.rehearse_sequence`: ``OUT/drill_k/`` and a listing ``summary.json``);
    ``igtl`` then streams every drill's session through one connection.

    Returns the summary written. Raises an input error (exit 2, nothing written) for bad
    input and for a device that fails before it was armed.
    """
    if not (math.isfinite(duration_s) and 0.0 < duration_s <= 3600.0):
        raise AppInputError(f"--duration-s {duration_s}: give 0 < seconds <= 3600")
    op = parse_operator(operator)
    spec = device if isinstance(device, DeviceSpec) else DeviceSpec.parse(device)
    hu_sigma_uncertainty(hu_sigma)  # a bad --hu-sigma is refused before anything loads
    fault_specs = [parse_fault(f) for f in faults]
    target = None if igtl is None else parse_target(igtl)
    whole = one_trajectory([plan] if isinstance(plan, Path) else plan, trajectory=trajectory)
    if aids is not None:
        if len(whole.drills) > 1:
            raise AppInputError(
                f"--aids {aids.name}: the stop-yourself exercise drills one drill; give a plan "
                "with its final drill alone"
            )
        exam = exam or not aids.wall
    if len(whole.drills) > 1:  # a drill sequence: one session per drill (exam: each drill's)
        from ctdrill.app.rehearse_sequence import rehearse_sequence

        return rehearse_sequence(
            dicom=dicom,
            plan=whole,
            out=out,
            operator=op,
            duration_s=duration_s,
            device=spec,
            faults=fault_specs,
            seed=seed,
            interpolate_gaps=interpolate_gaps,
            grey=grey,
            hu_sigma=hu_sigma,
            exam=exam,
            igtl=target,
            on_warning=on_warning,
        )
    card = find_trial([plan] if isinstance(plan, Path) else plan)  # a blind trial's card
    loaded = load_table(
        dicom,
        plan,
        interpolate_gaps=interpolate_gaps,
        grey=grey,
        trajectory=trajectory,
        exam=exam,
        exam_surface=exam_at_surface(spec),
        hu_sigma=hu_sigma,
    )
    if card is not None:
        check_session_plan(card, plan_hash(loaded.path.plan), where=str(plan))
    with atomic_output_dir(out, keep_unfinished=True) as stage, contextlib.ExitStack() as late:
        observers: list[SessionObserver] = [
            CsvObserver(stage / "session.csv"),
            AssessmentObserver(Assessor(loaded.context, loaded.table)),
        ]
        if target is not None:
            geometry = StreamGeometry.of_plan(loaded.path.plan)
            stream = IgtlStream(target, geometry, on_warning=on_warning, pace=not spec.paced)
            observers.append(StreamObserver(stream))
        session = RehearsalSession(
            lambda: open_device(spec, seed=seed),
            loaded.table,
            op,
            duration_s,
            observers,
            faults=fault_specs,
            seed=seed,
            notice=notice,
            # the session has ended: a signal now no longer cuts its records short
            ended=lambda: late.enter_context(held(reraise=False)),
        )
        result, records = session.run()
        summary = rehearsal_summary(
            result,
            loaded.path,
            loaded.table,
            operator=op.spec,
            device=spec.label,
            duration_s=duration_s,
            seed=seed,
            context=loaded.case,
            assessment=records["assessment"],
            exam=loaded.exam,
            verdict=loaded.verdict,
        )
        if "igtl" in records:
            summary["igtl"] = records["igtl"]
        if aids is not None:
            summary.update(aids.summary())
        if card is not None:
            summary = blind_summary(summary, card)
        write_file(stage / "summary.json", summary_json(summary))
        write_file(
            stage / TABLE_FILE,
            table_text(
                loaded.table,
                loaded.context,
                str(summary["plan_sha256"]),
                trial=None if card is None else (card.exercise_id, card.trial),
            ),
        )
    return summary


def ending_message(summary: dict[str, Any]) -> str:
    """One line on how an incomplete session ended and what the device was sent."""
    host = [f for f in summary.get("faults", []) if f.get("source") == "host"]
    sent = "STOP and DISARM were not sent"
    if host:
        last = host[-1]
        if last.get("stop_acknowledged") and last.get("disarm_acknowledged"):
            sent = "the device acknowledged STOP and DISARM"
        else:
            why = last.get("stop_error") or last.get("disarm_error") or "no answer"
            sent = f"STOP and DISARM were sent but not both acknowledged ({why})"
            if not last.get("stop_acknowledged") and "not sent" in str(why):
                sent = f"STOP and DISARM were not sent ({why})"
    return f"the session ended early ({summary.get('reason')}); {sent}"


def exit_code(summary: dict[str, Any]) -> int:
    """0 for a complete session, 3 after a device fault or host error, ``128 + signal`` after
    an interrupt: 130 Ctrl-C (SIGINT), 143 SIGTERM, 129 SIGHUP (the host's event names it)."""
    if summary.get("complete"):
        return 0
    if summary.get("outcome") != "interrupted":
        return EXIT_DEVICE_FAULT
    host = [f for f in summary.get("faults", []) if f.get("source") == "host"]
    return exit_code_for_signal(host[-1].get("signal") if host else None)
