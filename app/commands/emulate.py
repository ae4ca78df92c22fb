"""``ctdrill emulate --pty-link PATH``: the device emulator at real time on a pseudo-terminal."""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import Any

from ctdrill.app.errors import AppInputError


def register(subparsers: Any) -> None:
    """Add the ``emulate`` subcommand."""
    p = subparsers.add_parser(
        "emulate",
        help="run the haptic device emulator on a pseudo-terminal",
        description=(
            "Open a pseudo-terminal, link PATH to it and run the device (renderer at 10 kHz "
            "device time, force controller and a simulated master) at real time until "
            "SIGTERM/SIGINT; the link is removed on exit. A PATH another running emulator "
            "serves (its lock PATH.lock is held) or that links to a pty in use is refused; "
            "only a stale link is replaced. Connect with "
            "'ctdrill rehearse --device serial:PATH'."
        ),
    )
    p.add_argument("--pty-link", type=Path, required=True, metavar="PATH", help="symlink to create")
    p.add_argument(
        "--duration-s",
        type=float,
        default=None,
        help="stop after this long (default: run until killed)",
    )
    p.add_argument("--start-mm", type=float, default=0.0, help="initial master depth, mm")
    p.add_argument(
        "--core",
        choices=("python", "c"),
        default="python",
        help=(
            "the device core: python (haptics/emulator.py) or c (the reference firmware, "
            "firmware/, compiled with the system C compiler on first use; its ticks paced in "
            "compiled code); both speak the same protocol (default: python)"
        ),
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Serve until killed; print the loop's statistics."""
    from ctdrill.haptics.realtime import serve_pty

    if args.duration_s is not None and not (
        math.isfinite(args.duration_s) and args.duration_s > 0.0
    ):
        raise AppInputError(f"--duration-s {args.duration_s}: give a positive number of seconds")
    if not math.isfinite(args.start_mm):
        raise AppInputError(f"--start-mm {args.start_mm}: give a finite depth in mm")
    stats = serve_pty(
        args.pty_link, duration_s=args.duration_s, start_mm=args.start_mm, core=args.core
    )
    sys.stderr.write(f"emulator stopped: {stats.summary()}\n")
    return 0
