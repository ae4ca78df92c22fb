"""Run every benchmark module and write ``docs/benchmarks.md``.

Usage: ``python -m bench [--quick] [--only NAME ...] [--out docs/benchmarks.md]``.
"""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys
import time
from pathlib import Path

import bench
from bench.report import Section, machine_info

ROOT = Path(__file__).resolve().parents[1]


def discover() -> list[str]:
    """Names of the benchmark modules, ``bench_*``, sorted."""
    return sorted(
        info.name for info in pkgutil.iter_modules(bench.__path__) if info.name.startswith("bench_")
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench")
    parser.add_argument("--quick", action="store_true", help="small sizes, few repeats (smoke)")
    parser.add_argument("--only", nargs="*", default=None, help="module names, e.g. bench_load")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "benchmarks.md")
    args = parser.parse_args(argv)
    names = discover() if not args.only else args.only
    sections: list[Section] = []
    for name in names:
        t0 = time.perf_counter()
        module = importlib.import_module(f"bench.{name}")
        section: Section = module.run(quick=args.quick)
        sections.append(section)
        print(f"{name}: {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    text = [
        "# ctdrill benchmarks",
        "",
        "Written by `make bench` (`python -m bench`); every figure is the median over repeats",
        "with its inter-quartile range in brackets, peers measured side by side in the same run.",
        "",
        machine_info(),
        "",
    ]
    for section in sections:
        text += [f"## {section.title}", "", section.markdown.strip(), ""]
        text += [f"![{Path(fig).stem}]({fig})" for fig in section.figures]
        text.append("")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text("\n".join(text), encoding="utf-8")
    print(f"wrote {args.out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
