"""``ctdrill report``: the PDF of a case, stage by stage (issue 16: "a few seconds").

Cases: the bundled demo (80 x 100 x 80 voxels, one trajectory, its arch and implant) and, in
full mode, the real Philips head CT of ``../shared/data`` (512 x 512 x 28, 5 mm slices) with a
plan of two trajectories in the skull wall along an arch drawn on it (``REAL_PLAN``; the head
phantom has no jaw, so its anterior skull stands in for the alveolar ridge). Each repeat runs
:func:`ctdrill.app.report.build.write_report` in this process (imports already done), with
its own :class:`~ctdrill.app.report.timing.Timings`; the table gives each stage's median. In
full mode the whole command is also timed once per case in a fresh process
(``python -m ctdrill.app.cli report``: its imports, VTK's off-screen context included).
"""

from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from bench.report import Section, headline_row, table
from ctdrill.app.report.build import write_report
from ctdrill.app.report.timing import Timings

ROOT = Path(__file__).resolve().parents[1]
DEMO = ROOT / "assets" / "demo"
REAL_CT = ROOT.parent / "shared" / "data" / "dcmqa_ct_Philips_phantom_notilt_5mm"
GOAL_S = 5.0
#: Fresh ``ctdrill report`` processes timed per case (full mode).
FRESH_RUNS = 3
#: The arch: the anterior skull wall's mid-line at z = 766.21 mm (the ring of bone above 300 HU
#: on that slice, every 10 degrees about its centre), LPS mm.
REAL_ARCH_XY = (
    (-71.6, 114.6), (-69.3, 102.8), (-66.7, 90.4), (-62.9, 77.2), (-59.6, 60.3), (-52.2, 43.2),
    (-40.0, 27.9), (-23.1, 18.9), (-4.1, 18.9), (14.6, 20.5), (31.2, 29.4), (43.2, 44.6),
    (49.5, 62.6), (53.6, 78.1), (58.5, 90.3), (61.0, 102.8), (62.9, 114.7),
)  # fmt: skip
REAL_Z_MM = 766.21
IMPLANT = {
    "name": "tapered 4.1 x 11.5",
    "diameter_mm": 4.1,
    "length_mm": 11.5,
    "apex_diameter_mm": 3.0,
    "apex": "round",
}
#: Two vertical trajectories into the wall from above (entry in air at z = 790 mm), a canal
#: along the arch 2 mm below their targets.
REAL_PLAN = {
    "format": "ctdrill-plan/1",
    "coordinate_system": "LPS",
    "trajectories": [
        {
            "name": "front",
            "entry_mm": [-4.1, 19.0, 790.0],
            "target_mm": [-4.1, 19.0, 768.0],
            "drill": {"diameter_mm": 2.0, "tip_length_mm": 0.6},
            "implant": IMPLANT,
        },
        {
            "name": "left",
            "entry_mm": [14.6, 20.6, 790.0],
            "target_mm": [14.6, 20.6, 768.0],
            "drills": [{"diameter_mm": 2.0}, {"diameter_mm": 2.8}],
            "implant": IMPLANT,
        },
    ],
    "landmarks": [
        {
            "name": "canal",
            "kind": "canal",
            "radius_mm": 1.2,
            "points_mm": [[x, y, REAL_Z_MM - 2.0] for x, y in REAL_ARCH_XY[5:12]],
        }
    ],
    "arch_mm": [[x, y, REAL_Z_MM] for x, y in REAL_ARCH_XY],
}


def real_plan(root: Path) -> Path:
    """``REAL_PLAN`` written under ``root``."""
    path = root / "philips_arch.json"
    path.write_text(json.dumps(REAL_PLAN), encoding="utf-8")
    return path


def _cli(ct: Path, plan: Path, out: Path) -> tuple[float, float]:
    """Wall and CPU time (user + system) of ``ctdrill report`` in a fresh process, s."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    cmd = [sys.executable, "-m", "ctdrill.app.cli", "report", "--dicom", str(ct)]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    done = subprocess.run(
        [*cmd, "--plan", str(plan), "--out", str(out)], env=env, capture_output=True, text=True
    )
    elapsed = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        raise RuntimeError(f"ctdrill report failed ({done.returncode}): {done.stderr[-400:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return elapsed, cpu


def _fresh(ct: Path, plan: Path, out: Path, runs: int) -> tuple[float, float]:
    """Median wall and CPU seconds of ``runs`` fresh ``ctdrill report`` processes."""
    samples = [_cli(ct, plan, out) for _ in range(runs)]
    return (
        float(np.median([w for w, _ in samples])),
        float(np.median([c for _, c in samples])),
    )


def run(quick: bool) -> Section:
    """Time the report of the demo (and, in full mode, of the real CT) stage by stage."""
    repeats = 1 if quick else 5
    rows: list[list[str]] = []
    headline = []
    shortfalls: list[str] = []
    stages: list[str] = []
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        cases = [("demo (80 x 100 x 80)", DEMO / "ct", DEMO / "plan.json")]
        if not quick:
            cases.append(
                ("real head CT (512 x 512 x 28), 2 trajectories", REAL_CT, real_plan(root))
            )
        per_case = []
        for name, ct, plan in cases:
            samples: list[Timings] = []
            pages = 0
            for _ in range(repeats):
                t = Timings()
                _, pages = write_report(ct, [plan], root / "r.pdf", timings=t)
                samples.append(t)
            for t in samples:
                stages += [s for s in t.stages if s not in stages]
            med = {s: float(np.median([t.stages.get(s, 0.0) for t in samples])) for s in stages}
            total = float(np.median([sum(t.stages.values()) for t in samples]))
            load0 = os.getloadavg()[0]
            fresh = None if quick else _fresh(ct, plan, root / "cli.pdf", FRESH_RUNS)
            load = 0.5 * (load0 + os.getloadavg()[0])
            per_case.append((name, pages, med, total, fresh, load))
        for name, pages, med, total, fresh, load in per_case:
            rows.append(
                [
                    name,
                    str(pages),
                    *(f"{med.get(s, 0.0):.2f}" for s in stages),
                    f"{total:.2f}",
                    "-" if fresh is None else f"{fresh[0]:.2f}",
                    "-" if fresh is None else f"{fresh[1]:.2f}",
                    f"{load:.1f}",
                ]
            )
            headline.append(
                headline_row(
                    f"ctdrill report, {name}",
                    f"{total:.2f} s"
                    + ("" if fresh is None else f" ({fresh[0]:.2f} s fresh process)"),
                    goal=f"a few seconds (<= {GOAL_S:g} s)",
                )
            )
            if fresh is not None and fresh[0] > GOAL_S:
                shortfalls.append(
                    f"`ctdrill report` of the {name} took {fresh[0]:.2f} s as a fresh process "
                    f"(goal <= {GOAL_S:g} s) at load {load:.1f} on the 2 cores; its CPU time "
                    f"was {fresh[1]:.2f} s (imports, matplotlib's text layout, the panorama)"
                )
    md = table(
        [
            "case",
            "pages",
            *(f"{s} (s)" for s in stages),
            "total (s)",
            "command (s)",
            "command CPU (s)",
            "load",
        ],
        rows,
    )
    md += (
        f"\n\nMedians of {repeats} report(s) per case in one process (imports done); "
        f"'command' is the median of {FRESH_RUNS} runs of `ctdrill report` (the default "
        "clinical report, as a user runs it) in a fresh process (imports included), its wall "
        "and its CPU time (user + system: what the work costs when the 2 cores are shared); "
        "'load' is the load average while they ran. The real head CT's plan has two implants "
        f"(issue 37's goal: <= {GOAL_S:g} s as a fresh process)."
        f" Mode: {'quick' if quick else 'full'}."
    )
    return Section(
        title="Report (ctdrill report)",
        markdown=md,
        headline=tuple(headline),
        shortfalls=tuple(shortfalls),
    )
