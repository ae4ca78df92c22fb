"""``ctdrill warmup``: compile the search kernels into numba's disk cache once, after install."""

from __future__ import annotations

import argparse
from typing import Any


def register(subparsers: Any) -> None:
    """Add the ``warmup`` subcommand."""
    p = subparsers.add_parser(
        "warmup",
        help="compile the search kernels once (makes suggest ~30x faster)",
        description=(
            "Compile the batched search kernels (numba) into the disk cache, once per install "
            "(about 20-100 s). Without it 'ctdrill suggest' takes the NumPy path: the same "
            "answers, about 30 times slower; it says so. See docs/search.md for where the "
            "cache lives (NUMBA_CACHE_DIR)."
        ),
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Compile (or load) every search kernel; exit 2 without numba."""
    from ctdrill.app.search.warmup import main

    return main([])
