"""Run the benchmark modules and write ``docs/benchmarks.md``.

Usage: ``python -m bench [--quick] [--only NAME ...] [--out docs/benchmarks.md]``.

Every module runs in this one process, one after the other, so peers inside a module are
measured side by side under the same conditions. A module that fails is reported in the file
with its traceback and makes the exit status 1; the others still run.
"""

from __future__ import annotations

import argparse
import importlib
import os
import pkgutil
import sys
import time
import traceback
from pathlib import Path

import bench
from bench.report import DEFAULT_FIGURE_DIR, FIGURE_DIR_ENV, ROOT, Section, machine_info

DEFAULT_OUT = ROOT / "docs" / "benchmarks.md"

HEADER = """\
# ctdrill benchmarks

Written by `make bench` (which runs `python -m bench` under `xvfb-run` with the allocator
settings below); do not edit by hand, edit the modules in `bench/`. Every figure is the median
over repeats with its inter-quartile range in brackets; peers are measured side by side in the
same process run. Each section says how to reproduce it with one command; with `--quick` the
same code runs at toy sizes (the smoke test `tests/test_bench_smoke.py`), and its numbers mean
nothing.

Allocator: glibc returns freed memory to the kernel lazily on these VMs, so a fresh 300 MB
allocation can cost 0.3-0.7 s of page faults. `make bench` sets `MALLOC_TRIM_THRESHOLD_` (16 GiB:
never trim) and `MALLOC_MMAP_THRESHOLD_` (32 MiB: smaller blocks come from the heap and are
reused), so repeated runs measure the code, not the kernel's page zeroing. Without them, first
runs of the loaders are slower by about that much.
"""


def discover() -> list[str]:
    """Names of the benchmark modules, ``bench_*``, sorted."""
    return sorted(
        info.name for info in pkgutil.iter_modules(bench.__path__) if info.name.startswith("bench_")
    )


def _snapshot(folder: Path) -> dict[Path, bytes]:
    return {p: p.read_bytes() for p in sorted(folder.glob("*.png"))} if folder.is_dir() else {}


def _divert_figures(before: dict[Path, bytes], figure_dir: Path) -> dict[str, Path]:
    """Move figures a module wrote into ``docs/benchmarks/`` over to ``figure_dir``.

    Used when the report goes elsewhere (``--out`` in a temporary folder): the committed
    figures are restored byte for byte. Returns old name -> new path.
    """
    moved: dict[str, Path] = {}
    for path in sorted(DEFAULT_FIGURE_DIR.glob("*.png")) if DEFAULT_FIGURE_DIR.is_dir() else []:
        data = path.read_bytes()
        if before.get(path) == data:
            continue
        target = figure_dir / path.name
        target.write_bytes(data)
        moved[path.name] = target
        if path in before:
            path.write_bytes(before[path])
        else:
            path.unlink()
    return moved


def _link(fig: str, figure_dir: Path, out_dir: Path) -> str:
    """Path of figure ``fig`` relative to the report's folder (Markdown image link)."""
    path = Path(fig)
    if not path.is_absolute():
        path = ROOT / path
    if not path.exists() and (figure_dir / path.name).exists():
        path = figure_dir / path.name
    return os.path.relpath(path, out_dir)


def _run_module(name: str, quick: bool) -> tuple[Section, float, bool]:
    t0 = time.perf_counter()
    try:
        module = importlib.import_module(f"bench.{name}")
        section: Section = module.run(quick=quick)
        ok = True
    except Exception:  # a failing module is reported, and the others still run
        section = Section(
            title=f"{name}: FAILED",
            markdown="The module raised:\n\n```\n" + traceback.format_exc() + "```",
            shortfalls=(f"`{name}` failed to run; see its section.",),
        )
        ok = False
    return section, time.perf_counter() - t0, ok


def main(argv: list[str] | None = None) -> int:
    """Run the modules, write the report; 0 when every module ran, else 1."""
    parser = argparse.ArgumentParser(prog="python -m bench")
    parser.add_argument("--quick", action="store_true", help="toy sizes, few repeats (smoke)")
    parser.add_argument("--only", nargs="*", default=None, help="module names, e.g. bench_load")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT)
    args = parser.parse_args(argv)
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

    t_start = time.perf_counter()
    results: list[tuple[str, Section, float]] = []
    all_ok = True
    for name in names:
        before = _snapshot(DEFAULT_FIGURE_DIR) if divert else {}
        section, seconds, ok = _run_module(name, args.quick)
        all_ok &= ok
        if divert:
            moved = _divert_figures(before, figure_dir)
            figs = tuple(str(moved.get(Path(f).name, f)) for f in section.figures)
            section = Section(section.title, section.markdown, figs, section.shortfalls)
        results.append((name, section, seconds))
        print(f"{name}: {seconds:.1f} s", file=sys.stderr)
    total_s = time.perf_counter() - t_start

    mode = "quick (smoke: toy sizes, numbers meaningless)" if args.quick else "full"
    text = [HEADER, "## Machine and settings", "", machine_info()]
    text += [f"- Mode: {mode}; total run time {total_s:.0f} s", ""]
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
