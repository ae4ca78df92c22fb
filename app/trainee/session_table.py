"""``table.json``: what a session was assessed against, kept with its trace.

A rehearsal's folder holds the force table the device ran (its rows, step, stop and the goal)
and what the plan measures the session against (planned depth, max safe depth, goal, the
clearance along the path) with the plan's hash. ``ctdrill assess`` recomputes the assessment
from ``session.csv`` and this file alone (:func:`recompute`), never from ``summary.json``.

A blind trial's session keeps its force table **sealed** (``table_sealed``, with the trial it
is bound to as ``trial``: the exercise's id and the trial's name; no ``table``): its cutting
forces would give the bone's class away to anyone opening the file. It is sealed as the
trial's key is (:func:`ctdrill.app.exercise.seal.seal_bytes`, bound to the exercise, the trial
and the plan's hash), so an edited table, or one copied from another trial, does not open.
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import math
import zlib
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ctdrill.app.csv_cells import csv_text
from ctdrill.app.errors import AppInputError
from ctdrill.app.exercise.seal import SealError, seal_bytes, trial_binding, unseal_bytes
from ctdrill.haptics.assessment import ASSESSMENT_FIELDS, Assessment, AssessmentContext, Assessor
from ctdrill.haptics.profile_table import ProfileTable, ProfileTableError
from ctdrill.haptics.session import SESSION_COLUMNS
from ctdrill.safeio import loads_json

TABLE_FILE = "table.json"
TABLE_FORMAT = "ctdrill-session-table/1"
#: When the window showed what (optional): ``time_s`` of the newest sample shown and
#: ``shown_s``, the session time it was on screen.
DISPLAY_FILE = "display.csv"
DISPLAY_COLUMNS = ("time_s", "shown_s")
#: Two values of a field agree within these (the summary's rounding of the same computation).
_TOLERANCE = {"score": 0.051, "reaction_ms": 0.051, "display_lag_ms": 0.051}
_DEFAULT_TOLERANCE = 1.5e-3
#: A sealed table larger than this once opened is refused, bytes (a real one is well under 1 MB).
_SEALED_MAX_BYTES = 64 << 20


class SessionTraceError(AppInputError):
    """A session whose files cannot be assessed, or whose summary disagrees with its trace."""


def _floats(values: np.ndarray) -> list[float]:
    return [float(v) for v in np.asarray(values, dtype=np.float64)]


def table_doc(
    table: ProfileTable,
    context: AssessmentContext,
    plan_sha256: str,
    *,
    trial: tuple[str, str] | None = None,
) -> dict[str, Any]:
    """``table.json``'s document (float32 table values written exactly); ``trial`` (a blind
    trial's exercise id and name): the force table sealed to it (module docstring)."""
    safe = context.max_safe_depth_mm
    doc = {
        "format": TABLE_FORMAT,
        "plan_sha256": plan_sha256,
        "planned_depth_mm": context.planned_depth_mm,
        "max_safe_depth_mm": safe if math.isfinite(safe) else None,
        "goal_depth_mm": context.goal_depth_mm,
        "clearance_depth_mm": _floats(context.clearance_depth_mm),
        "clearance_mm": _floats(context.clearance_mm),
        "table": {
            "depth_step_mm": table.depth_step_mm,
            "stop_depth_mm": table.stop_depth_mm,
            "goal_depth_mm": table.goal_depth_mm,
            "ke_per_mm_s": table.ke_per_mm_s,
            "freqs_hz": _floats(table.freqs_hz),
            "s0_n": _floats(table.s0_n),
            "s1_n": _floats(table.s1_n),
            "s2_n": _floats(table.s2_n),
        },
    }
    if trial is not None:
        binding = trial_binding(trial[0], trial[1], plan_sha256)
        data = zlib.compress(json.dumps(doc.pop("table"), allow_nan=False).encode("utf-8"), 9)
        nonce = hashlib.sha256(binding.encode("utf-8") + b"\0" + data).digest()[:15]
        doc["trial"] = {"exercise_id": trial[0], "trial": trial[1]}
        doc["table_sealed"] = seal_bytes(data, binding=binding, nonce=nonce)
    return doc


def table_text(
    table: ProfileTable,
    context: AssessmentContext,
    plan_sha256: str,
    *,
    trial: tuple[str, str] | None = None,
) -> str:
    """``table.json``'s text (``trial``: :func:`table_doc`)."""
    return json.dumps(table_doc(table, context, plan_sha256, trial=trial), allow_nan=False) + "\n"


def _unsealed_table(where: str, doc: Mapping[str, Any]) -> object:
    """The force table a blind trial's ``table.json`` holds sealed."""
    trial, plan = doc.get("trial"), doc.get("plan_sha256")
    if not isinstance(trial, dict) or not all(
        isinstance(trial.get(k), str) for k in ("exercise_id", "trial")
    ):
        raise SessionTraceError(f"{where}: trial (the exercise_id and trial sealed to) is missing")
    if not isinstance(plan, str):
        raise SessionTraceError(f"{where}: plan_sha256 is missing")
    binding = trial_binding(trial["exercise_id"], trial["trial"], plan)
    try:
        data = unseal_bytes(doc.get("table_sealed"), binding=binding)  # type: ignore[arg-type]
        inflate = zlib.decompressobj()
        text = inflate.decompress(data, _SEALED_MAX_BYTES)
        if inflate.unconsumed_tail or not inflate.eof:
            raise SealError("sealed data: not a whole table, or too large")
    except (SealError, zlib.error) as exc:
        raise SessionTraceError(f"{where}: table_sealed: {exc}") from exc
    return loads_json(
        text.decode("utf-8", "replace"), where=where, what="sealed table", error=SessionTraceError
    )


def _number(where: str, doc: Mapping[str, Any], key: str, *, nullable: bool = False) -> float:
    value = doc.get(key)
    if value is None and nullable:
        return math.inf
    if isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value):
        return float(value)
    raise SessionTraceError(f"{where}: {key} = {value!r} is not a finite number")


def _array(where: str, doc: Mapping[str, Any], key: str) -> np.ndarray:
    value = doc.get(key)
    if not isinstance(value, list) or not all(
        isinstance(v, int | float) and not isinstance(v, bool) for v in value
    ):
        raise SessionTraceError(f"{where}: {key} is not a list of numbers")
    arr = np.asarray(value, dtype=np.float64)
    if not np.all(np.isfinite(arr)):
        raise SessionTraceError(f"{where}: {key} holds a value that is not finite")
    return arr


def read_table(where: str, data: bytes) -> tuple[ProfileTable, AssessmentContext, str]:
    """``(table, context, plan hash)`` of a ``table.json``.

    Raises
    ------
    SessionTraceError
        Not a session table, a missing or bad value.
    """
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise SessionTraceError(f"{where}: not UTF-8 text") from exc
    doc = loads_json(text, where=where, what="session table", error=SessionTraceError)
    if not isinstance(doc, dict) or doc.get("format") != TABLE_FORMAT:
        raise SessionTraceError(
            f"{where}: not a session table ({TABLE_FORMAT}); rehearse the session again"
        )
    t = _unsealed_table(where, doc) if "table_sealed" in doc else doc.get("table")
    if not isinstance(t, dict):
        raise SessionTraceError(f"{where}: table is missing")
    depth, clearance = (_array(where, doc, k) for k in ("clearance_depth_mm", "clearance_mm"))
    if depth.shape != clearance.shape or (depth.size and np.any(np.diff(depth) <= 0.0)):
        raise SessionTraceError(
            f"{where}: clearance_depth_mm and clearance_mm must be equally long, depths rising"
        )
    goal = t.get("goal_depth_mm")
    try:
        table = ProfileTable(
            depth_step_mm=_number(where, t, "depth_step_mm"),
            s0_n=_array(where, t, "s0_n"),
            s1_n=_array(where, t, "s1_n"),
            s2_n=_array(where, t, "s2_n"),
            ke_per_mm_s=_number(where, t, "ke_per_mm_s"),
            freqs_hz=_array(where, t, "freqs_hz"),
            stop_depth_mm=_number(where, t, "stop_depth_mm"),
            goal_depth_mm=None if goal is None else _number(where, t, "goal_depth_mm"),
        )
    except ProfileTableError as exc:
        raise SessionTraceError(f"{where}: {exc}") from exc
    context = AssessmentContext(
        planned_depth_mm=_number(where, doc, "planned_depth_mm"),
        max_safe_depth_mm=_number(where, doc, "max_safe_depth_mm", nullable=True),
        goal_depth_mm=_number(where, doc, "goal_depth_mm"),
        clearance_depth_mm=depth,
        clearance_mm=clearance,
    )
    plan = doc.get("plan_sha256")
    if not isinstance(plan, str) or not plan:
        raise SessionTraceError(f"{where}: plan_sha256 is missing")
    return table, context, plan


def recompute(
    where: str,
    csv_text: str,
    table: ProfileTable,
    context: AssessmentContext,
    display_text: str | None = None,
) -> Assessment:
    """The assessment of a ``session.csv`` (and the window's ``display.csv``) on ``table``.

    Raises
    ------
    SessionTraceError
        A header or row that is not ``session.csv``'s (older logs without the hand's force
        cannot be assessed: rehearse again).
    """
    assessor = Assessor(context, table)
    reader = csv.reader(io.StringIO(csv_text))
    header = next(reader, None)
    if header is None or tuple(header[: len(SESSION_COLUMNS)]) != SESSION_COLUMNS:
        raise SessionTraceError(
            f"{where}: session.csv does not start with {','.join(SESSION_COLUMNS)} (a log "
            "written before sessions were assessed from their trace): rehearse it again"
        )
    for lineno, row in enumerate(reader, start=2):
        try:
            assessor.add_cells(row)
        except (ValueError, IndexError) as exc:
            raise SessionTraceError(
                f"{where}: session.csv line {lineno} is not a session row ({exc})"
            ) from exc
    if display_text is not None:
        rows = csv.reader(io.StringIO(display_text))
        if tuple(next(rows, ())) != DISPLAY_COLUMNS:
            raise SessionTraceError(f"{where}: display.csv does not start with time_s,shown_s")
        for lineno, row in enumerate(rows, start=2):
            try:
                sample, shown = float(row[0]), float(row[1])
            except (ValueError, IndexError) as exc:
                raise SessionTraceError(
                    f"{where}: display.csv line {lineno} is not two numbers"
                ) from exc
            if not (math.isfinite(sample) and math.isfinite(shown)):
                raise SessionTraceError(f"{where}: display.csv line {lineno} is not finite")
            assessor.shown(sample, shown)
    return assessor.result()


def _agree(name: str, claimed: object, computed: object) -> bool:
    if computed is None or isinstance(computed, bool) or isinstance(claimed, bool):
        return claimed == computed and type(claimed) is type(computed)
    if not isinstance(claimed, int | float) or not isinstance(computed, int | float):
        return False
    return abs(float(claimed) - float(computed)) <= _TOLERANCE.get(name, _DEFAULT_TOLERANCE)


def first_disagreement(
    claimed: Mapping[str, Any], computed: Mapping[str, Any]
) -> tuple[str, object, object] | None:
    """``(field, claimed, recomputed)`` of the first assessment field (in
    :data:`ASSESSMENT_FIELDS` order) where ``claimed`` (the summary's) differs from the trace's,
    or None."""
    for name in ASSESSMENT_FIELDS:
        if name not in claimed or not _agree(name, claimed[name], computed[name]):
            return name, claimed.get(name), computed[name]
    return None


def display_csv(display: Sequence[tuple[float, float]]) -> str | None:
    """``display.csv`` of the window's log ``(time_s, shown_s)`` (None: an empty log)."""
    if not display:
        return None
    return csv_text(DISPLAY_COLUMNS, [[f"{t:.4f}", f"{w:.4f}"] for t, w in display])


def with_display(
    assessment: dict[str, Any] | None,
    session_csv: str,
    table: ProfileTable,
    context: AssessmentContext,
    display: Sequence[tuple[float, float]],
) -> dict[str, Any] | None:
    """A window session's assessment: ``assessment`` (the control loop's) without a display
    log, else recomputed from its ``session.csv`` text and the log (:func:`recompute`: the
    reaction from when the breakthrough was shown, a lag over 100 ms flagged), so the summary
    agrees with the files ``ctdrill assess`` reads."""
    text = display_csv(display)
    if text is None or assessment is None:
        return assessment
    return recompute("window", session_csv, table, context, text).to_json()
