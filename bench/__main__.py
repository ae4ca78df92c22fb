"""Run the benchmark modules and write ``docs/benchmarks.md``.

Usage: ``python -m bench [--quick [--jobs N]] [--only NAME ...] [--out docs/benchmarks.md]``.

Each module runs in a fresh process of its own, one after the other (no allocator, page or
GUI state carried from one module to the next); peers inside a module are measured side by
side in that process. A module that fails (an exception, or a crash of a native library) is
reported in the file with the end of its error output and makes the exit status 1; the others
still run.
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib
import json
import os
import pkgutil
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import bench
from bench.report import (
    DEFAULT_FIGURE_DIR,
    FIGURE_DIR_ENV,
    HEADLINE_COLUMNS,
    ROOT,
    Section,
    machine_info,
    table,
)

DEFAULT_OUT = ROOT / "docs" / "benchmarks.md"

HEADER = """\
# ctdrill benchmarks

Written by `make bench` (which runs `python -m bench` under `xvfb-run` with the allocator
settings below); do not edit by hand, edit the modules in `bench/`. Every figure is the median
over repeats with its inter-quartile range in brackets; peers are measured side by side in the
same run of the same process. Each module runs in a fresh process of its own. Each section says
how to reproduce it with one command; with `--quick` the same code runs at toy sizes (the smoke
test `tests/test_bench_smoke.py`), and its numbers mean nothing. The machine is a shared 2-core
VM: compare ratios measured side by side, not absolute times across runs.

Allocator: on these VMs freed memory goes back to the host after 1-3 s, so a fresh 300 MB
allocation can cost 0.3-0.7 s of page faults. `make bench` sets `MALLOC_TRIM_THRESHOLD_`
(16 GiB: glibc never trims the heap) and `MALLOC_MMAP_THRESHOLD_` (32 MiB: blocks below it come
from the heap and are reused), so that repeats measure the code rather than the host's paging.
"""


def discover() -> list[str]:
    """Names of the benchmark modules, ``bench_*``, sorted."""
    return sorted(
        info.name for info in pkgutil.iter_modules(bench.__path__) if info.name.startswith("bench_")
    )


def _snapshot(folder: Path) -> dict[Path, bytes]:
    return {p: p.read_bytes() for p in sorted(folder.glob("*.png"))} if folder.is_dir() else {}


def _divert_figures(
    figures: tuple[str, ...], before: dict[Path, bytes], figure_dir: Path
) -> tuple[str, ...]:
    """Move a module's own figures that it wrote into ``docs/benchmarks/`` to ``figure_dir``.

    For a module that writes there whatever ``--out`` says: when the report goes elsewhere
    (a quick run into a temporary folder), the committed figure is restored byte for byte.
    Only the figures the section names are touched. Returns the section's figure paths.
    """
    out = []
    for fig in figures:
        path = Path(fig) if Path(fig).is_absolute() else ROOT / fig
        if path.parent.resolve() != DEFAULT_FIGURE_DIR.resolve() or not path.is_file():
            out.append(fig)
            continue
        target = figure_dir / path.name
        target.write_bytes(path.read_bytes())
        if path in before:
            path.write_bytes(before[path])
        else:
            path.unlink()
        out.append(str(target))
    return tuple(out)


def _link(fig: str, figure_dir: Path, out_dir: Path) -> str:
    """Path of figure ``fig`` relative to the report's folder (Markdown image link)."""
    path = Path(fig)
    if not path.is_absolute():
        path = ROOT / path
    if not path.exists() and (figure_dir / path.name).exists():
        path = figure_dir / path.name
    return os.path.relpath(path, out_dir)


def _child(name: str, quick: bool, section_out: Path) -> int:
    """In a fresh process: run one module and write its section as JSON."""
    module = importlib.import_module(f"bench.{name}")
    section: Section = module.run(quick=quick)
    section_out.write_text(json.dumps(dataclasses.asdict(section)), encoding="utf-8")
    return 0


def _run_module(name: str, quick: bool) -> tuple[Section, float, bool]:
    """Run module ``name`` in its own process; a crash or exception becomes a FAILED section."""
    with tempfile.TemporaryDirectory(prefix="ctdrill-bench-") as tmp:
        section_out = Path(tmp) / "section.json"
        cmd = [sys.executable, "-m", "bench", "--child", name, "--section-out", str(section_out)]
        t0 = time.perf_counter()
        proc = subprocess.run(
            cmd + (["--quick"] if quick else []),
            cwd=ROOT,
            stderr=subprocess.PIPE,
            text=True,
        )
        seconds = time.perf_counter() - t0
        if proc.returncode == 0 and section_out.is_file():
            raw = json.loads(section_out.read_text(encoding="utf-8"))
            section = Section(
                title=raw["title"],
                markdown=raw["markdown"],
                figures=tuple(raw["figures"]),
                shortfalls=tuple(raw["shortfalls"]),
                headline=tuple(tuple(row) for row in raw.get("headline", ())),
            )
            return section, seconds, True
    tail = "\n".join(proc.stderr.strip().splitlines()[-40:])
    section = Section(
        title=f"{name}: FAILED",
        markdown=f"The module's process exited with status {proc.returncode}:\n\n```\n"
        + tail
        + "\n```",
        shortfalls=(f"`{name}` failed to run; see its section.",),
    )
    return section, seconds, False


def main(argv: list[str] | None = None) -> int:
    """Run the modules, write the report; 0 when every module ran, else 1."""
    parser = argparse.ArgumentParser(prog="python -m bench")
    parser.add_argument("--quick", action="store_true", help="toy sizes, few repeats (smoke)")
    parser.add_argument("--only", nargs="*", default=None, help="module names, e.g. bench_load")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT)
    parser.add_argument(
        "--jobs", type=int, default=1, help="modules run at a time (only with --quick)"
    )
    parser.add_argument("--child", help=argparse.SUPPRESS)
    parser.add_argument("--section-out", type=Path, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        return _child(args.child, args.quick, args.section_out)
    if args.jobs < 1 or (args.jobs > 1 and not args.quick):
        print(
            "error: --jobs must be 1, or more only with --quick (timings interfere)",
            file=sys.stderr,
        )
        return 2
    available = discover()
    names = available if not args.only else args.only
    unknown = [n for n in names if n not in available]
    if unknown:
        print(
            f"error: unknown benchmark module(s) {unknown}; choose from {available}",
            file=sys.stderr,
        )
        return 2
    out: Path = args.out.resolve()
    out_dir = out.parent
    out_dir.mkdir(parents=True, exist_ok=True)
    figure_dir = out_dir / "benchmarks"
    figure_dir.mkdir(parents=True, exist_ok=True)
    os.environ[FIGURE_DIR_ENV] = str(figure_dir)
    divert = figure_dir.resolve() != DEFAULT_FIGURE_DIR.resolve()

    def one(name: str) -> tuple[str, Section, float, bool]:
        before = _snapshot(DEFAULT_FIGURE_DIR) if divert else {}
        section, seconds, ok = _run_module(name, args.quick)
        if divert:
            figs = _divert_figures(section.figures, before, figure_dir)
            section = Section(
                section.title, section.markdown, figs, section.shortfalls, section.headline
            )
        print(f"{name}: {seconds:.1f} s", file=sys.stderr)
        return name, section, seconds, ok

    t_start = time.perf_counter()
    with ThreadPoolExecutor(max_workers=args.jobs) as pool:
        done = list(pool.map(one, names))
    total_s = time.perf_counter() - t_start
    results = [(name, section, seconds) for name, section, seconds, _ in done]
    all_ok = all(ok for *_, ok in done)

    mode = "quick (smoke: toy sizes, numbers meaningless)" if args.quick else "full"
    if args.jobs > 1:
        mode += f", {args.jobs} modules at a time"
    text = [HEADER, "## Machine and settings", "", machine_info()]
    text += [f"- Mode: {mode}; total run time {total_s:.0f} s", ""]
    headline = [row for _, s, _ in results for row in s.headline]
    if headline:
        text += ["## Headline", "", table(HEADLINE_COLUMNS, headline), ""]
    shortfalls = [(s.title, line) for _, s, _ in results for line in s.shortfalls]
    text += ["## Where ctdrill is slower than a peer or misses a goal", ""]
    if shortfalls:
        text += [f"- **{title}**: {line}" for title, line in shortfalls]
    else:
        text.append("- No module reported a shortfall in this run.")
    silent = [n for n, s, _ in results if not s.shortfalls]
    if silent:
        text += [
            "",
            "Modules that state no shortfall of their own (read their tables): "
            + ", ".join(f"`{n}`" for n in silent)
            + ".",
        ]
    text.append("")
    for name, section, seconds in results:
        text += [f"## {section.title}", ""]
        text += [
            f"Reproduce: `python -m bench --only {name}` "
            f"(this section took {seconds:.0f} s; module `bench/{name}.py`).",
            "",
            section.markdown.strip(),
            "",
        ]
        for fig in section.figures:
            text += [f"![{Path(fig).stem}]({_link(fig, figure_dir, out_dir)})", ""]
    out.write_text("\n".join(text), encoding="utf-8")
    if not any(figure_dir.iterdir()):
        figure_dir.rmdir()
    print(f"wrote {out}", file=sys.stderr)
    return 0 if all_ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
