"""Rehearsing a drill sequence: one device session per drill, in drilling order.

A plan with ``drills`` (pilot 2.0 mm, then 2.8, 3.5 ...) rehearses as the surgeon drills it:
drill ``k`` gets its own table (its own profile and stop depth, :mod:`ctdrill.engine.sequence`),
the device is opened, armed with it, driven by the same operator for ``duration_s`` and
closed: **one session per drill** (a drill change is a new upload and ARM, as on the real
device). The hole drill ``k`` leaves for the next is as deep as its tip **actually reached**
in its session (``max_drill_mm``, at most its stop depth unless the device overran it), not its
planned or stop depth: a push too weak or a session too short leaves a shallower pilot hole,
and the next drill meets the bone below it with its full lip.

Every drill's table is computed once before the first ARM, with the stop depths as reached
depths, so bad input is refused before anything runs; each later drill is recomputed from the
depths actually reached. A session that does not complete (a device fault, Ctrl-C) ends the
sequence: the drills after it are not run, and the summary says so. ``--fault`` times are
session times and apply to every session.

Records (whole or not at all): ``OUT/drill_k/session.csv`` and ``OUT/drill_k/summary.json`` per
drill run (the single-drill rehearsal's files with the drill's own ``assessment``, plus
``inner_holes``), and ``OUT/summary.json`` (``"format": "ctdrill-rehearsal-sequence/1"``) with
the session fields of the final drill run, ``complete`` for the whole sequence, the faults of
every session (each with its ``drill``), ``drills``: one entry per drill run (with its score),
``plan_sha256`` of the whole plan and ``assessment``: the sequence's, with the same fields,
combined from the drills' (:func:`ctdrill.haptics.assessment.combine_assessments`).

Exam mode (simulation only, as for one drill): every drill's table runs beyond the plan
(:func:`ctdrill.app.trainee.exam.exam_setup` on the drill alone, around the holes before it),
so each drill can pass the max safe depth and the assessments record it.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator, Sequence
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ctdrill.app.igtl.frames import IgtlTarget, StreamDrill, StreamGeometry
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
from ctdrill.engine.grey import map_volume
from ctdrill.engine.path import PathResult
from ctdrill.engine.plans import plan_calibration
from ctdrill.engine.record import to_json as record_json
from ctdrill.engine.sequence import drill_folder, drill_path, holes_before, plan_sequence
from ctdrill.engine.settings import DEFAULTS, GreyMapSpec
from ctdrill.engine.stop import stop_words
from ctdrill.engine.summarize import drill_step
from ctdrill.engine.summary import TrajectorySummary
from ctdrill.haptics.assessment import Assessor, combine_assessments
from ctdrill.haptics.profile_table import ProfileTable
from ctdrill.haptics.session import FaultSpec, Operator
from ctdrill.haptics.spec import DeviceSpec
from ctdrill.imaging import load_ct
from ctdrill.imaging.plan.types import Plan
from ctdrill.interrupts import Interrupted, held, signal_name

if TYPE_CHECKING:
    from ctdrill.app.igtl.stream import IgtlStream

SEQUENCE_FORMAT = "ctdrill-rehearsal-sequence/1"


def reached_depth_mm(session: dict[str, Any]) -> float:
    """The depth a drill's session reached: its deepest drill position, mm (>= 0)."""
    return max(0.0, float(session["max_drill_mm"]))


def rehearse_sequence(
    *,
    dicom: Path,
    plan: Plan,
    out: Path,
    operator: Operator,
    duration_s: float,
    device: DeviceSpec,
    faults: Sequence[FaultSpec],
    seed: int,
    interpolate_gaps: bool,
    grey: GreyMapSpec | None,
    hu_sigma: float | None,
    exam: bool = False,
    igtl: IgtlTarget | None = None,
    on_warning: Callable[[str], None] | None = None,
) -> dict[str, Any]:
    """Run every drill of ``plan`` on its own session and write the records (module docstring).

    ``grey`` and ``hu_sigma`` are the rehearsal's grey-to-HU map and ``--hu-sigma``; each
    drill is one :class:`~ctdrill.app.session_run.RehearsalSession` summarised by
    :func:`~ctdrill.app.session_run.rehearsal_summary`, so one drill's records are exactly a
    rehearsal's; ``exam``
    runs every drill in exam mode (on hardware its wall at the landmark's surface); ``igtl`` streams
    every drill's session through one connection (:meth:`IgtlStream.start_drill`: the
    ``Drill`` message names each), the top ``summary.json`` gaining ``igtl``.
    """
    volume, grey_map = map_volume(load_ct(dicom), grey)
    case = case_context(volume, grey_map, replace(DEFAULTS, hu_sigma=hu_sigma))
    calibration = plan_calibration(plan)
    options = {"interpolate_gaps": interpolate_gaps}
    # every drill computed before the first ARM: bad input is refused before anything runs
    first = plan_sequence(volume, plan, calibration, interpolate_gaps=interpolate_gaps)
    runs: list[tuple[PathResult, dict[str, Any], float]] = []
    with (
        atomic_output_dir(out, keep_unfinished=True) as stage,
        _streaming(igtl, first.steps[0].plan, on_warning, device) as stream,
        held(reraise=False) as signals,  # outside the sessions, a signal ends the sequence
    ):
        for k in range(len(plan.drills)):
            if signals.caught:  # Ctrl-C, SIGTERM or SIGHUP between two sessions
                if not runs:
                    raise Interrupted(signals.caught[0])  # nothing armed: nothing written
                break
            reached = [r for _, _, r in runs]
            path = (
                first.steps[0]
                if k == 0
                else drill_path(
                    volume, plan, k, calibration, reached, implant=first.steps[0].implant, **options
                )  # the same implant body for every drill, as the export's sequence has it
            )
            setup: ExamSetup | None = None
            if exam:
                holes = holes_before(plan, reached)
                setup = exam_setup(
                    volume,
                    plan.for_drill(k),
                    path,
                    inner_holes=holes,
                    at_surface=exam_at_surface(device),
                    **options,
                )
                table = setup.table
            else:
                table = ProfileTable.from_profile(path.profile, path.stop_depth_mm)
            context = assessment_context(path, None if setup is None else setup.path)
            folder = stage / drill_folder(k)
            folder.mkdir()
            observers: list[SessionObserver] = [
                CsvObserver(folder / "session.csv"),
                AssessmentObserver(Assessor(context, table)),
            ]
            if stream is not None:
                number = (k + 1, len(plan.drills))
                drill = StreamDrill(*number, path.plan.drill.diameter_mm, drill_folder(k))
                stream.start_drill(StreamGeometry.of_plan(path.plan), drill)
                observers.append(StreamObserver(stream, owned=False))  # one for the sequence
            session = RehearsalSession(
                lambda: device.open(seed=seed),
                table,
                operator,
                duration_s,
                observers,
                faults=faults,
                seed=seed,
            )
            with signals.released():  # the session handles them (STOP, DISARM)
                result, records = session.run()
            doc = rehearsal_summary(
                result,
                path,
                table,
                operator=operator.spec,
                device=device.label,
                duration_s=duration_s,
                seed=seed,
                context=case,
                assessment=records["assessment"],
                exam=setup,
            )
            write_file(folder / "summary.json", summary_json(doc))
            write_file(folder / TABLE_FILE, table_text(table, context, str(doc["plan_sha256"])))
            runs.append((path, doc, reached_depth_mm(doc)))
            if not doc.get("complete"):
                break
        top = rehearsed_sequence_summary(plan, runs)
        if signals.caught and len(runs) < len(plan.drills) and runs[-1][1].get("complete"):
            _mark_interrupted(top, signal_name(signals.caught[0]))  # the sequence broke there
        if stream is not None:
            top["igtl"] = stream.close().to_json()
        write_file(stage / "summary.json", summary_json(top))
    return top


@contextlib.contextmanager
def _streaming(
    igtl: IgtlTarget | None,
    first: Plan,
    on_warning: Callable[[str], None] | None,
    device: DeviceSpec,
) -> Iterator[IgtlStream | None]:
    """The sequence's one stream (None without ``igtl``), closed however the sequence ends
    (closing twice is harmless: the report is taken from the first)."""
    if igtl is None:
        yield None
        return
    from ctdrill.app.igtl.stream import IgtlStream

    geometry = StreamGeometry.of_plan(first)
    stream = IgtlStream(igtl, geometry, on_warning=on_warning, pace=not device.paced)
    try:
        yield stream
    finally:
        stream.close()


def _mark_interrupted(top: dict[str, Any], signal: str) -> None:
    """A sequence interrupted between two drills' sessions (every session run ended whole)."""
    message = f"interrupted ({signal}) between drills"
    top["complete"] = False
    top["outcome"] = "interrupted"
    top["reason"] = f"interrupted: {message}"
    top["faults"].append(
        {
            "drill": top["drills_run"],
            "source": "host",
            "kind": "interrupted",
            "message": message,
            "signal": signal,
        }
    )


def rehearsed_sequence_summary(
    plan: Plan, runs: Sequence[tuple[PathResult, dict[str, Any], float]]
) -> dict[str, Any]:
    """The top-level ``summary.json`` of a rehearsed sequence (module docstring)."""
    last = runs[-1][1]
    n = len(plan.drills)
    done = len(runs) == n
    top: dict[str, Any] = {"format": SEQUENCE_FORMAT}
    top.update(last)
    top["format"] = SEQUENCE_FORMAT  # in the first place, over the drill's own
    top.pop("rehearsal", None)  # the listing, not one session
    top.pop("drill", None)
    top.pop("inner_holes", None)
    top["complete"] = done and all(doc.get("complete") for _, doc, _ in runs)
    if not done:  # the final drill never ran: the plan's stop is not known from this session
        top["stop_depth_mm"] = None
        top["device_stop_depth_mm"] = None
        top["stop_reason"] = None
    top["drills_planned"] = n
    top["drills_run"] = len(runs)
    top["faults"] = [
        {"drill": k + 1, **fault} for k, (_, doc, _) in enumerate(runs) for fault in doc["faults"]
    ]
    # every drill's warnings once, as the export's listing gives them
    top["warnings"] = list(
        {(w["code"], w["message"]): w for _, doc, _ in runs for w in doc["warnings"]}.values()
    )
    top["plan_sha256"] = plan_hash(plan)
    top["assessment"] = combine_assessments(
        [doc["assessment"] for _, doc, _ in runs],
        drills_planned=n,
        planned_depth_mm=float(top["planned_depth_mm"]),
    ).to_json()
    top["final_drill"] = n
    top["drills"] = [
        {
            # the export's listing entry of this drill (the same code, from its summary)
            **record_json(drill_step(k, TrajectorySummary.from_json(doc))),
            # the stop the device enforced (in exam mode past the plan, as the drill's own
            # summary.json says; stop_reason stays the plan's reason for its guarded stop)
            "device_stop_depth_mm": doc["device_stop_depth_mm"],
            "exam_stop_basis": doc["exam"].get("stop_basis"),
            "max_drill_mm": doc["max_drill_mm"],
            "reached_depth_mm": reached,
            "max_force_cmd_n": doc.get("max_force_cmd_n"),
            "complete": doc.get("complete"),
            "score": doc["assessment"]["score"],
        }
        for k, (_, doc, reached) in enumerate(runs)
    ]
    return top


def _stop_why(drill: dict[str, Any]) -> str:
    basis = drill.get("exam_stop_basis")
    return f"exam: {basis}" if basis else stop_words(drill["stop_reason"], form="code")


def sequence_lines(summary: dict[str, Any], out: Path) -> list[str]:
    """What ``ctdrill rehearse`` prints of a sequence: one line per drill run, then the files."""
    n = summary["drills_planned"]
    lines = [
        f"drill {d['drill']}/{n} ({d['diameter_mm']:g} mm): stop depth "
        f"{d['device_stop_depth_mm']:.2f} "
        f"mm ({_stop_why(d)}), reached {d['reached_depth_mm']:.2f} mm"
        for d in summary["drills"]
    ]
    if summary["drills_run"] < n:
        lines.append(f"{summary['drills_run']} of {n} drills run: the sequence ended early")
    lines.append(f"wrote {out}/drill_*/session.csv, summary.json and {out}/summary.json")
    return lines
