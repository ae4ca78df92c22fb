"""Smoke test of ``make bench``: every benchmark module runs in quick mode and reports numbers.

Also the report helpers on inputs with known answers.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

import bench.report
from bench.__main__ import discover
from bench.bench_scaling import goal_rows
from bench.report import (
    FIGURE_DIR_ENV,
    Timing,
    figure_path,
    loglog_slope,
    profile_top,
    table,
    time_pair,
    time_round,
)
from bench.scaling_load import READERS, LoadRow

ROOT = Path(__file__).resolve().parents[1]
FIGURES = ROOT / "docs" / "benchmarks"
#: The areas issue 8 asks for; each must have its module.
REQUIRED = ("bench_export", "bench_load", "bench_model", "bench_sampling", "bench_scaling")
NUMBER_CELL = re.compile(r"^\|(?:[^|\n]*\|)*\s*[-+]?\d+(?:\.\d+)?(?:e[-+]?\d+)?\b[^|\n]*\|", re.M)


def _sections(text: str) -> dict[str, str]:
    """Module name -> its section's text, found by the section's reproduce line."""
    out = {}
    for chunk in text.split("\n## ")[1:]:
        found = re.search(r"Reproduce: `python -m bench --only (bench_\w+)`", chunk)
        if found:
            out[found.group(1)] = chunk
    return out


def _snapshot() -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(FIGURES.glob("*.png"))}


@pytest.mark.gui  # bench_gui opens the window: run under a display (make test uses Xvfb)
@pytest.mark.timeout(960)
@pytest.mark.bench_smoke
def test_quick_bench_writes_every_section_with_numbers(tmp_path: Path) -> None:
    before = _snapshot()
    modules = discover()
    out = tmp_path / "benchmarks.md"
    proc = subprocess.run(
        [sys.executable, "-m", "bench", "--quick", "--jobs", "3", "--out", str(out)],
        cwd=ROOT,
        env=dict(os.environ),
        capture_output=True,
        text=True,
        timeout=900,  # a hang guard only: 210 s measured on 2 cores at load 10
    )
    assert proc.returncode == 0, proc.stderr[-4000:]
    text = out.read_text(encoding="utf-8")
    assert set(REQUIRED) <= set(modules)
    sections = _sections(text)
    assert sorted(sections) == modules, "a module's section is missing from the report"
    for name, chunk in sections.items():
        assert "FAILED" not in chunk.splitlines()[0], f"{name} failed:\n{chunk[:3000]}"
        assert "|---" in chunk, f"{name}: no table"
        assert NUMBER_CELL.search(chunk), f"{name}: no table row with a number"
    for header in ("## Machine and settings", "## Where ctdrill is slower"):
        assert header in text
    for key in ("numpy ", "SimpleITK ", "MALLOC_TRIM_THRESHOLD_", "MALLOC_MMAP_THRESHOLD_"):
        assert key in text
    links = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", text)
    assert "benchmarks/load_scaling.png" in links and "benchmarks/path_scaling.png" in links
    for link in links:
        assert (out.parent / link).is_file(), f"figure {link} linked but not written"
    # The committed figures are left alone: the quick run writes beside its own report.
    after = _snapshot()
    for name in {Path(link).name for link in links}:
        assert after.get(name) == before.get(name), f"docs/benchmarks/{name} was overwritten"
    # every module says how long it took (the quick run's cost is read there, not asserted:
    # a time limit would fail on a loaded host; the subprocess timeout is the hang guard)
    per_module = dict(re.findall(r"^(bench_\w+): ([\d.]+) s$", proc.stderr, re.M))
    assert sorted(per_module) == modules, proc.stderr[-2000:]


def test_unknown_module_is_one_line_error(tmp_path: Path) -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "bench", "--only", "bench_nope", "--out", str(tmp_path / "b.md")],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 2
    assert proc.stderr.startswith("error: unknown benchmark module") and "bench_nope" in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "b.md").exists()


def test_timing_from_known_samples() -> None:
    t = Timing.from_samples([4.0, 1.0, 3.0, 2.0, 5.0])
    assert (t.median_s, t.p25_s, t.p75_s, t.min_s, t.repeats) == (3.0, 2.0, 4.0, 1.0, 5)
    assert t.fmt("ms") == "3e+03 ms [2e+03-4e+03]"
    assert Timing.from_samples([0.0125]).fmt("ms") == "12.5 ms [12.5-12.5]"


def test_loglog_slope_recovers_power_laws() -> None:
    x = [1.0, 10.0, 100.0, 1000.0]
    assert loglog_slope(x, [3.0 * v for v in x]) == pytest.approx(1.0)
    assert loglog_slope(x, [0.5 * v**2 for v in x]) == pytest.approx(2.0)
    assert loglog_slope(x, [7.0 for _ in x]) == pytest.approx(0.0, abs=1e-12)


def test_table_is_markdown() -> None:
    assert table(["a", "b"], [[1, "x"], [2.5, "y"]]) == (
        "| a | b |\n|---|---|\n| 1 | x |\n| 2.5 | y |"
    )


def test_figure_path_follows_the_environment(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv(FIGURE_DIR_ENV, str(tmp_path / "figs"))
    assert figure_path("x.png") == tmp_path / "figs" / "x.png"
    assert (tmp_path / "figs").is_dir()


def _busy() -> int:
    return sum(i * i for i in range(20000))


def test_profile_top_lists_functions_by_own_time_with_their_calls() -> None:
    # The order of functions of similar cost depends on the host (timer, CPU): the test checks
    # what does not: the row format, the call counts, and the rows sorted by own time.
    text = profile_top(lambda: [_busy() for _ in range(5)], n=50)
    lines = text.splitlines()
    assert lines[0] == "| function | calls | own ms | cumulative ms |"
    rows = [line.strip("|").split("|") for line in lines[2:]]
    by_name = {cells[0].strip(): cells for cells in rows}
    busy = [name for name in by_name if name.endswith("(_busy)`")]
    assert len(busy) == 1 and "test_bench_smoke.py" in busy[0]
    assert int(by_name[busy[0]][1]) == 5
    own = [float(cells[2]) for cells in rows]
    assert own == sorted(own, reverse=True)
    assert len(profile_top(lambda: [_busy() for _ in range(5)], n=2).splitlines()) == 2 + 2


def test_parallel_modules_only_in_quick_mode(tmp_path: Path) -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "bench", "--jobs", "2", "--out", str(tmp_path / "b.md")],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 2
    assert proc.stderr.startswith("error: --jobs") and len(proc.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "b.md").exists()


def _record_gc(monkeypatch: pytest.MonkeyPatch, calls: list[str]) -> None:
    """``gc.collect`` as the timers call it, recorded in ``calls`` instead of run: a full
    collection costs ~2 s of CPU late in the suite's process, whose heap is large."""
    monkeypatch.setattr(bench.report.gc, "collect", lambda: calls.append("gc"))


def test_time_pair_alternates_and_times_each_peer(monkeypatch: pytest.MonkeyPatch) -> None:
    calls: list[str] = []
    _record_gc(monkeypatch, calls)
    a, b = time_pair(lambda: calls.append("a"), lambda: calls.append("b"), repeats=3, warmup=1)
    # the warm-up round untimed, then a garbage collection before each timed call
    assert calls == ["a", "b"] + ["gc", "a", "gc", "b"] * 3
    assert a.repeats == b.repeats == 3
    assert 0.0 <= a.min_s <= a.median_s and 0.0 <= b.min_s <= b.median_s


def test_time_round_runs_peers_in_turn_with_the_hook_before_each(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    calls: list[str] = []
    _record_gc(monkeypatch, calls)
    got = time_round(
        {"x": lambda: calls.append("x"), "y": lambda: calls.append("y")},
        repeats=2,
        warmup=0,
        before_each=lambda: calls.append("-"),
    )
    assert calls == ["-", "gc", "x", "-", "gc", "y"] * 2
    assert sorted(got) == ["x", "y"] and got["x"].repeats == 2


def _row(
    slices: int, warm: tuple[float, float, float], cold: tuple[float, float, float]
) -> LoadRow:
    def timings(values: tuple[float, float, float]) -> dict[str, Timing]:
        return {n: Timing.from_samples([v]) for n, v in zip(READERS, values, strict=True)}

    peak = dict.fromkeys(READERS, 1.0)
    return LoadRow(slices, float(slices), timings(warm), timings(cold), peak)


def test_loading_goals_are_judged_from_the_medians() -> None:
    # (load_series, SimpleITK, raw) seconds.
    met = _row(100, warm=(0.04, 0.1, 0.01), cold=(0.1, 0.25, 0.08))
    slow = _row(300, warm=(0.06, 0.1, 0.01), cold=(0.3, 0.4, 0.1))
    rows, misses = goal_rows([met, slow])
    assert rows[0][1:6] == ["0.40", "0.40", "1.25", "0.32", "met"]
    assert rows[1][1:5] == ["0.60", "0.75", "3.00", "0.25"]
    assert misses == [
        "300 slices: warm vs SimpleITK 0.60 x (goal <= 0.5 x)",
        "300 slices: cold vs SimpleITK 0.75 x (goal <= 0.5 x)",
        "300 slices: cold vs raw 3.00 x (goal <= 1.5 x)",
    ]
    # When the raw bytes alone take more than half SimpleITK's time, the line says so.
    floor = _row(100, warm=(0.04, 0.1, 0.01), cold=(0.2, 0.3, 0.2))
    _, floor_misses = goal_rows([floor])
    assert floor_misses == [
        "100 slices: cold vs SimpleITK 0.67 x (goal <= 0.5 x) (even the raw read of the bytes "
        "takes 0.67 x SimpleITK's cold time here: the disk, not the parser, sets this floor)"
    ]


def test_import_log_is_grouped_by_top_level_package() -> None:
    from bench.bench_startup import import_self_times_s

    log = (
        "import time: self [us] | cumulative | imported package\n"
        "import time:       100 |        100 |     numpy._core\n"
        "import time:      2000 |       2100 |   numpy\n"
        "import time:       300 |       2400 | ctdrill.app.export\n"
        "unrelated line\n"
    )
    got = import_self_times_s(log)
    assert got.keys() == {"numpy", "ctdrill"}
    assert got["numpy"] == pytest.approx(2100e-6)
    assert got["ctdrill"] == pytest.approx(300e-6)
