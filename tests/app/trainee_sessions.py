"""Session folders made from a real rehearsal for the trainee record's tests: the trace changed
and the summary's assessment recomputed from it (as ``ctdrill rehearse`` would have written it),
so ``ctdrill assess`` accepts them as other sessions."""

from __future__ import annotations

import csv
import io
import json
import shutil
from pathlib import Path
from typing import Any

from ctdrill.app.trainee.session_table import TABLE_FILE, read_table, recompute


def rewrite(
    real: Path,
    dest: Path,
    when: str,
    *,
    depth_scale: float = 1.0,
    hand_scale: float = 1.0,
    rest_rows: int = 0,
    summary: dict[str, Any] | None = None,
) -> Path:
    """A copy of the session ``real`` at ``dest`` recorded at ``when``: its drill and handle
    depths times ``depth_scale``, the hand's force times ``hand_scale``, then ``rest_rows``
    rows of the hand resting (1 ms apart) appended; the assessment recomputed; ``summary``
    keys merged into its ``summary.json``."""
    shutil.copytree(real, dest)
    lines = (dest / "session.csv").read_text().splitlines()
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(lines[0].split(","))
    row: list[str] = []
    for line in lines[1:]:
        row = line.split(",")
        t, master, drill, force, state, hand = row
        writer.writerow(
            [
                t,
                f"{float(master) * depth_scale:.5f}",
                f"{float(drill) * depth_scale:.5f}",
                force,
                state,
                f"{float(hand) * hand_scale:.4f}",
            ]
        )
    if row:
        for k in range(1, rest_rows + 1):
            drill = f"{float(row[2]) * depth_scale:.5f}"
            writer.writerow(
                [f"{float(row[0]) + k * 1e-3:.4f}", drill, drill, "0.0000", row[4], "0.0000"]
            )
    (dest / "session.csv").write_text(out.getvalue())
    table, context, _ = read_table(str(dest), (dest / TABLE_FILE).read_bytes())
    doc = json.loads((dest / "summary.json").read_text())
    doc["assessment"] = recompute(str(dest), out.getvalue(), table, context).to_json()
    doc["recorded_at"] = when
    doc.update(summary or {})
    (dest / "summary.json").write_text(json.dumps(doc, indent=2) + "\n")
    return dest
