"""The export of a drill sequence: ``OUT/drill_1/``, ``OUT/drill_2/`` ... and ``OUT/summary.json``.

Each drill's folder holds the usual four files of its own path (its profile cut around the
holes before it, its clearance and stop); the top-level ``summary.json``
(``"format": "ctdrill-sequence/1"``, :class:`~ctdrill.engine.summary.SequenceSummary`) carries
the plan-level part of the export summary, taken from the final drill, whose stop rules the
plan, and ``drills``: one entry per drill in drilling order (its folder, geometry, stop depth
and reason, peak and mean force, the holes it cut around). The warnings are every drill's,
each once. Written in the same atomic swap as the drills' files
(:func:`ctdrill.app.export.write_exports`).
"""

from __future__ import annotations

from ctdrill.app.export import summary_json
from ctdrill.engine.sequence import SequenceResult
from ctdrill.engine.summarize import CaseContext, sequence_summary


def sequence_files(seq: SequenceResult, subdir: str, context: CaseContext) -> dict[str, str]:
    """``{subdir/summary.json: text}`` for :func:`~ctdrill.app.export.write_exports`'
    ``extra_files``."""
    name = f"{subdir}/summary.json" if subdir else "summary.json"
    return {name: summary_json(sequence_summary(seq, context))}
