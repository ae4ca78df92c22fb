"""One rehearsal session, whoever runs it: open the device, run the host loop, let every
observer see the rows and the telemetry, close the device and the observers.

``ctdrill rehearse`` (one trajectory, and each drill of a sequence) and the window's session
process run a :class:`RehearsalSession`; what each records is an observer
(:class:`SessionObserver`): ``session.csv`` (:class:`CsvObserver`), the assessment
(:class:`AssessmentObserver`), the OpenIGTLink stream (:class:`StreamObserver`), the window's
queue (its own observer in :mod:`ctdrill.app.gui.session_process`). An observer's
:meth:`~SessionObserver.close` returns what it adds to ``summary.json`` (``assessment``,
``igtl``), so a new record of a session is one observer, attached where the session is run.
The summary itself is :func:`rehearsal_summary`'s (one for every caller).
"""

from __future__ import annotations

import contextlib
import json
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

from ctdrill.app.readout import push_summary, wall_summary
from ctdrill.app.session_csv import SessionCsv
from ctdrill.app.trainee.exam import ExamSetup, plan_hash
from ctdrill.app.trainee.kinds import mode_of, operator_kind_of
from ctdrill.engine.path import PathResult
from ctdrill.engine.rehearsal_summary import RehearsalSummary, rehearsal_plan_summary
from ctdrill.engine.summarize import CaseContext
from ctdrill.engine.verdict import PlanVerdict
from ctdrill.haptics.assessment import Assessor
from ctdrill.haptics.device import Device, TelemetrySample
from ctdrill.haptics.hands import Hand
from ctdrill.haptics.profile_table import ProfileTable
from ctdrill.haptics.run import SessionResult, run_session
from ctdrill.haptics.session import FaultSpec, Operator, Row

if TYPE_CHECKING:
    from ctdrill.app.igtl.stream import IgtlStream


class SessionObserver(Protocol):
    """What a session tells a record of it (module docstring)."""

    def rows(self, rows: list[Row]) -> None:
        """A block's ``session.csv`` rows."""
        ...

    def samples(self, block: list[TelemetrySample]) -> None:
        """A block's telemetry (every field)."""
        ...

    def close(self) -> dict[str, Any]:
        """The session ended (however): release, and what the record adds to the summary."""
        ...


class CsvObserver:
    """``session.csv`` at ``path``, written and flushed block by block."""

    def __init__(self, path: Path) -> None:
        self._csv = SessionCsv(path)

    def rows(self, rows: list[Row]) -> None:
        self._csv.write(rows)

    def samples(self, block: list[TelemetrySample]) -> None:
        """Not recorded here."""

    def close(self) -> dict[str, Any]:
        self._csv.close()
        return {}


class AssessmentObserver:
    """The session's ``assessment`` (:class:`~ctdrill.haptics.assessment.Assessor`);
    ``if_armed``: none when the device was never armed (the window's)."""

    def __init__(self, assessor: Assessor, *, if_armed: bool = False) -> None:
        self.assessor = assessor
        self.if_armed = if_armed

    def rows(self, rows: list[Row]) -> None:
        """Read from the telemetry, not the rows."""

    def samples(self, block: list[TelemetrySample]) -> None:
        self.assessor.add(block)

    def close(self) -> dict[str, Any]:
        if self.if_armed and self.assessor.t0 is None:  # never armed: nothing to assess
            return {}
        return {"assessment": self.assessor.result().to_json()}


class StreamObserver:
    """The OpenIGTLink stream (:class:`~ctdrill.app.igtl.stream.IgtlStream`); ``owned``: the
    session closes it and its report becomes ``igtl`` (a drill sequence's one stream is closed
    by the sequence)."""

    def __init__(self, stream: IgtlStream, *, owned: bool = True) -> None:
        self.stream = stream
        self.owned = owned

    def rows(self, rows: list[Row]) -> None:
        """Streamed from the telemetry."""

    def samples(self, block: list[TelemetrySample]) -> None:
        self.stream.observe(block)

    def close(self) -> dict[str, Any]:
        return {"igtl": self.stream.close().to_json()} if self.owned else {}


@dataclass
class RehearsalSession:
    """One session on ``device`` (opened by ``open_device()``, closed when it ends) with its
    observers; :meth:`run` returns the session's result and what the observers add to the
    summary (their keys, in observer order).

    The other fields are :func:`ctdrill.haptics.run.run_session`'s.
    """

    open_device: Callable[[], Device]
    table: ProfileTable
    operator: Operator
    duration_s: float
    observers: Sequence[SessionObserver] = ()
    faults: Sequence[FaultSpec] = ()
    seed: int = 0
    hand: Hand | None = None
    notice: Callable[[str], None] | None = None
    should_stop: Callable[[], bool] | None = None
    until: Callable[[], bool] | None = None
    #: Called once the session has ended, before the observers close (the CLI holds its
    #: signals there so that the records are written whole).
    ended: Callable[[], object] | None = None
    records: dict[str, Any] = field(default_factory=dict)

    def _rows(self, rows: list[Row]) -> None:
        for o in self.observers:
            o.rows(rows)

    def _samples(self, block: list[TelemetrySample]) -> None:
        for o in self.observers:
            o.samples(block)

    def run(self, device: Device | None = None) -> tuple[SessionResult, dict[str, Any]]:
        """Run the session (on ``device`` when given, already open; else its own, opened and
        closed here); the observers are closed however it ends."""
        own = device is None
        dev = self.open_device() if device is None else device
        with contextlib.ExitStack() as stack:
            stack.callback(self._close_observers)
            if own:
                stack.callback(dev.close)
            result = run_session(
                dev,
                self.table,
                self.operator,
                self.duration_s,
                faults=self.faults,
                seed=self.seed,
                sink=self._rows,
                on_samples=self._samples,
                hand=self.hand,
                notice=self.notice,
                should_stop=self.should_stop,
                until=self.until,
            )
            if self.ended is not None:
                self.ended()
        return result, self.records

    def _close_observers(self) -> None:
        for o in self.observers:
            self.records.update(o.close())


def rehearsal_summary(
    session: SessionResult | dict[str, Any],
    path: PathResult,
    table: ProfileTable,
    *,
    context: CaseContext,
    operator: str,
    device: str,
    duration_s: float,
    seed: int,
    assessment: dict[str, Any] | None = None,
    exam: ExamSetup | None = None,
    verdict: PlanVerdict | None = None,
) -> dict[str, Any]:
    """The one ``summary.json`` of a rehearsal (CLI, drill sequence and window): a
    :class:`~ctdrill.engine.rehearsal_summary.RehearsalSummary` of the session's fields, the
    export's summary of ``path`` on the case ``context`` (every field, the same values), and
    how the session was run: ``operator``, ``device``, ``session_duration_s``, ``seed``,
    ``profile_steps``; for a ``push:N`` operator the readouts of
    :func:`ctdrill.app.readout.push_summary` (the model's time to the stop against the
    session's, a push too weak to cut); at the stop the wall's account
    (:func:`ctdrill.app.readout.wall_summary`); ``exam`` (exam mode: the device's stop and why
    there, or ``{"enabled": false}``), ``operator_kind`` and ``mode``
    (:mod:`ctdrill.app.trainee.kinds`), ``plan_sha256``, ``recorded_at`` (UTC) and the session's
    ``assessment`` (:meth:`ctdrill.haptics.assessment.Assessment.to_json`), when given. The
    warnings are ``verdict``'s (the trajectory's, as the export lists them), when given."""
    fields = dict(session.to_json() if isinstance(session, SessionResult) else session)
    run: dict[str, Any] = {
        "operator": operator,
        "device": device,
        "session_duration_s": duration_s,
        "seed": seed,
        "profile_steps": table.n_steps,
    }
    run.update(push_summary(fields, table, operator, duration_s))
    run.update(wall_summary(fields))
    run["exam"] = {"enabled": False} if exam is None else exam.to_json()
    run["operator_kind"] = operator_kind_of(operator, device)
    run["mode"] = mode_of(run)
    run["plan_sha256"] = plan_hash(path.plan)
    run["recorded_at"] = datetime.now(UTC).isoformat(timespec="seconds")
    if assessment is not None:
        run["assessment"] = assessment
    plan_summary = rehearsal_plan_summary(path, context, verdict)
    return RehearsalSummary(fields, plan_summary, run).to_json()


def summary_json(summary: dict[str, Any]) -> str:
    """``summary.json``'s text: valid JSON, a number that is not finite written as null (the
    host records no untrusted telemetry; this keeps any other value from breaking the file)."""
    return json.dumps(_finite(summary), indent=2, allow_nan=False) + "\n"


def _finite(value: Any) -> Any:
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite(v) for v in value]
    return value
