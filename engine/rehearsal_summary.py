"""A rehearsal's ``summary.json`` as one typed value: the session, the export's summary of the
same plan, and how the session was run.

:class:`RehearsalSummary` embeds the plan's :class:`~ctdrill.engine.summary.TrajectorySummary`
built by the export's own code (:func:`rehearsal_plan_summary` calls
:func:`ctdrill.engine.summarize.job_summary`), so every field of the export's ``summary.json``
(``site``, ``stop_depth_mm``, ``max_safe_depth_mm``, ``binding_landmark``,
``min_clearance_mm``, the implant's outcome, ``warnings`` ...) is in the rehearsal's with the
same value, and a field added to the export's summary reaches the rehearsal's with no edit
here. Only ``plot`` (whether ``force.png`` was written beside it) is the export's alone.

The session's own fields (:meth:`ctdrill.haptics.run.SessionResult.to_json`) come first, then
the plan's, then ``rehearsal`` (:data:`REHEARSAL_FORMAT`) and the run's (operator, device,
``session_duration_s``, readouts, ``exam``, ``assessment`` ...). The session's stop, which is
also a plan key, is written as ``device_stop_depth_mm`` (:data:`DEVICE_KEYS`): the stop the
device enforced (the plan's ``stop_depth_mm`` to float32; in exam mode past it).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any

from ctdrill.engine.path import PathResult
from ctdrill.engine.summarize import CaseContext, job_summary
from ctdrill.engine.summary import REHEARSAL_FORMAT, PlanOutcome, TrajectorySummary
from ctdrill.engine.verdict import PlanVerdict

#: Session keys the plan's summary also has, written under another name: the stop the device
#: was given (the plan's to float32; in exam mode past it) beside the plan's ``stop_depth_mm``.
DEVICE_KEYS = {"stop_depth_mm": "device_stop_depth_mm"}


@dataclass(frozen=True)
class RehearsalSummary:
    """One rehearsal's ``summary.json`` (module docstring).

    Attributes
    ----------
    session : the device session's fields (``complete``, ``max_drill_mm``, ``faults`` ...).
    plan : the export's summary of the plan the session ran (``format`` ``ctdrill-export/1``).
    run : how it was run and what it measured, in order (``operator``, ``device``,
        ``session_duration_s``, ``seed``, ``profile_steps``, readouts, ``exam``,
        ``plan_sha256``, ``recorded_at``, ``assessment``, ``igtl``).
    """

    session: Mapping[str, Any]
    plan: TrajectorySummary
    run: Mapping[str, Any]

    @property
    def outcome(self) -> PlanOutcome:
        """The plan's outcome (the export's)."""
        return self.plan.outcome

    def to_json(self) -> dict[str, Any]:
        """The ``summary.json`` document."""
        plan = self.plan.to_json()
        doc = {DEVICE_KEYS.get(k, k): v for k, v in self.session.items()}
        doc.update(plan)
        doc["rehearsal"] = REHEARSAL_FORMAT
        doc.update((k, v) for k, v in self.run.items() if k not in plan)
        return doc


def rehearsal_plan_summary(
    path: PathResult, context: CaseContext, verdict: PlanVerdict | None = None
) -> TrajectorySummary:
    """The export's summary of ``path`` on the case ``context`` (the export's code, its
    values), without ``plot`` (no ``force.png`` beside a rehearsal)."""
    return replace(job_summary(path, context, verdict).summary, plot=None)
