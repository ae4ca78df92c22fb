"""The outputs of ``ctdrill suggest`` (docs/suggest.md): ``candidates.csv``, ``suggest.json``
and, when a candidate is feasible, ``best.plan.json`` (the input plan with the best axis,
through the plan writer), all in one atomic swap; and the lines the terminal shows."""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ctdrill.app.csv_cells import csv_text, text_cell
from ctdrill.app.records import OUTPUT_NAMES, atomic_output_dir, write_file
from ctdrill.app.search.alternatives import Alternative, alternatives_csv, keeps_text
from ctdrill.app.search.candidates import SURFACE_SEARCH_MM
from ctdrill.app.search.suggest import Suggestion
from ctdrill.imaging.plan.write import plan_document
from ctdrill.text import printable

#: Files ``ctdrill suggest`` writes (an existing --out holding only these may be replaced).
SUGGEST_NAMES = frozenset({"candidates.csv", "best.plan.json", "suggest.json", "alternatives.csv"})

CSV_COLUMNS = (
    "rank",
    "candidate",
    "entry_x_mm",
    "entry_y_mm",
    "entry_z_mm",
    "target_x_mm",
    "target_y_mm",
    "target_z_mm",
    "offset_mm",
    "tilt_deg",
    "body_hu",
    "body_term",
    "crest_cortical",
    "apex_cortical",
    "score",
    "max_safe_depth_mm",
    "max_safe_depth_capped",
    "min_clearance_mm",
    "binding_landmark",
    "stop_reason",
    "passed",
    "checked",
    "implant_clearance_mm",
    "min_wall_mm",
    "wall_balance",
    "problems",
    "feasible",
    "reason",
)


def _num(value: float, digits: int = 6) -> str:
    return "" if not math.isfinite(value) else f"{value:.{digits}f}"


def candidates_csv(s: Suggestion) -> str:
    """``candidates.csv``: one row per candidate, best first (coordinates LPS mm, written to
    round-trip exactly)."""
    c, sc = s.candidates, s.scores
    rows = []
    for rank, i in enumerate(s.order, start=1):
        rows.append(
            [
                rank,
                int(i),
                *(repr(float(v)) for v in c.entries_lps[i]),
                *(repr(float(v)) for v in c.targets_lps[i]),
                _num(float(c.offset_mm[i])),
                _num(float(c.tilt_deg[i])),
                _num(float(sc.body_hu[i]), 3),
                _num(float(sc.body_term[i])),
                _num(float(sc.crest_cortical[i])),
                _num(float(sc.apex_cortical[i])),
                _num(float(sc.total[i])),
                _num(float(s.max_safe_depth_mm[i])),
                str(bool(s.max_safe_depth_capped[i])).lower(),
                _num(float(s.min_clearance_mm[i])),
                text_cell(printable(s.binding[i])),
                text_cell(s.stop_reason[i]),
                str(bool(s.passed[i])).lower(),
                str(bool(s.checked[i])).lower(),
                _num(float(s.implant_clearance_mm[i])),
                _num(float(s.min_wall_mm[i])),
                _num(float(s.wall_balance[i])),
                text_cell(s.problems[i]),
                str(bool(s.feasible[i])).lower(),
                text_cell(printable(s.reason[i])),
            ]
        )
    return csv_text(CSV_COLUMNS, rows)


def summary_doc(s: Suggestion) -> dict[str, Any]:
    """``suggest.json``: settings, counts, the best candidate and the planned axis's rank."""
    best = s.best_index
    return {
        "format": "ctdrill-suggest/1",
        "plan": printable(s.plan.name),
        "planned_depth_mm": s.plan.planned_depth_mm,
        "radius_mm": s.space.radius_mm,
        "cone_deg": s.space.cone_deg,
        "count": s.space.count,
        "seed": s.space.seed,
        "sampling": "halton-4d" if s.space.seed is None else "halton-4d-shifted",
        "surface_search_mm": SURFACE_SEARCH_MM,
        "objective": s.objective.to_json(),
        "score_body": printable(s.body),
        "check": {"wanted": s.check.wanted, "max_checked": s.check.max_checked},
        "n_passed": s.n_passed,
        "n_checked": s.n_checked,
        "n_feasible": s.n_feasible,
        "best_candidate": best,
        "best_score": None if best is None else float(s.scores.total[best]),
        "planned_rank": s.rank_of(0),
        "planned_feasible": bool(s.feasible[0]),
        "planned_score": _json_num(float(s.scores.total[0])),
        "best_implant_clearance_mm": None
        if best is None
        else _json_num(float(s.implant_clearance_mm[best])),
        "best_min_wall_mm": None if best is None else _json_num(float(s.min_wall_mm[best])),
        "evaluate_s": round(s.evaluate_s, 4),
        "check_s": round(s.check_s, 4),
        "total_s": round(s.total_s, 4),
        "notes": [printable(n) for n in s.notes],
    }


def _json_num(value: float) -> float | None:
    return value if math.isfinite(value) else None


def summary_lines(s: Suggestion) -> list[str]:
    """What the terminal shows after a search."""
    out = [f"note: {n}" for n in s.notes]
    best = s.best_index
    sc = s.scores.total
    out.append(
        f"{s.n_passed} of {s.candidates.size} candidates pass the final drill's margins; "
        f"{s.n_checked} checked exactly, {s.n_feasible} feasible; evaluation "
        f"{s.evaluate_s:.2f} s, exact check {s.check_s:.2f} s, search {s.total_s:.2f} s"
    )
    if best is not None:
        c = s.candidates
        out.append(
            f"best: candidate {best}, score {sc[best]:.4f} (offset {c.offset_mm[best]:.2f} mm, "
            f"tilt {c.tilt_deg[best]:.1f} deg)" + _safety_text(s, best)
        )
    planned = f"{sc[0]:.4f}" if math.isfinite(float(sc[0])) else "none"
    state = "feasible" if s.feasible[0] else f"not feasible: {s.reason[0]}"
    out.append(f"planned axis (candidate 0): rank {s.rank_of(0)}, score {planned}, {state}")
    return out


def alternative_lines(alts: Sequence[Alternative]) -> list[str]:
    """What the terminal says of the alternatives (no feasible axis)."""
    if not alts:
        return ["no axis is feasible, and the library has no shorter or narrower implant to try"]
    good = [a for a in alts if a.verdict.feasible]
    if not good:
        return [
            f"no axis is feasible; none of the {len(alts)} shorter or narrower implants at the "
            "planned site is either (alternatives.csv)"
        ]
    a = good[0]
    return [
        f"no axis is feasible; {len(good)} of {len(alts)} shorter or narrower implants at the "
        f"planned site are (alternatives.csv), e.g. {a.spec.name!r} ({a.change}): " + keeps_text(a)
    ]


def _safety_text(s: Suggestion, index: int) -> str:
    parts = []
    clear, wall = float(s.implant_clearance_mm[index]), float(s.min_wall_mm[index])
    if math.isfinite(clear):
        parts.append(f"implant clearance {clear:.1f} mm")
    if math.isfinite(wall):
        parts.append(f"thinnest bone wall {wall:.1f} mm")
    return f"; {', '.join(parts)}" if parts else ""


def write_suggestion(
    s: Suggestion, out_dir: str | Path, alternatives: Sequence[Alternative] | None = None
) -> list[Path]:
    """Write the outputs into ``out_dir`` in one atomic swap; returns the final paths.
    ``alternatives`` (given when no axis is feasible) go into ``alternatives.csv``."""
    files: dict[str, str] = {"candidates.csv": candidates_csv(s)}
    if alternatives is not None:
        files["alternatives.csv"] = alternatives_csv(alternatives)
    best = s.best_plan()
    final = Path(out_dir)
    if best is not None:
        doc = plan_document(best, out_dir=final.resolve())
        files["best.plan.json"] = json.dumps(doc, indent=2) + "\n"
    files["suggest.json"] = json.dumps(summary_doc(s), indent=2) + "\n"
    with atomic_output_dir(out_dir, owned_names=OUTPUT_NAMES | SUGGEST_NAMES) as staging:
        for name, text in files.items():
            write_file(staging / name, text)
    return [final / name for name in files]
