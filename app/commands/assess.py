"""``ctdrill assess``: store rehearsals' assessments in a trainee record; a learning curve."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from ctdrill.app.errors import AppInputError


def register(subparsers: Any) -> None:
    """Add the ``assess`` subcommand."""
    p = subparsers.add_parser(
        "assess",
        help="store rehearsals in a trainee record (SQLite); write a trainee's learning curve",
        description=(
            "With SESSION_DIR...: store each rehearsal's assessment (its summary.json "
            "'assessment', written by ctdrill rehearse or the window) in the trainee record "
            "FILE, one row per session (a drill sequence's folder is one session, its listing's "
            "assessment; the same session stored twice stays one row), each in "
            "one transaction. With --out DIR: write the trainee's learning_curve.csv, "
            "learning_curve.png and percentiles.csv (against the sessions tagged --expert on "
            "the same plan). Both may be given. docs/rehearse.md describes the record."
        ),
    )
    p.add_argument(
        "sessions", type=Path, nargs="*", metavar="SESSION_DIR", help="rehearsal output folders"
    )
    p.add_argument("--db", type=Path, required=True, metavar="FILE", help="the trainee record")
    p.add_argument("--trainee", required=True, metavar="ID", help="whose sessions")
    p.add_argument("--expert", action="store_true", help="tag the stored sessions as an expert's")
    p.add_argument(
        "--out", type=Path, default=None, metavar="DIR", help="write the learning curve here"
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Store the sessions, then write the learning curve (when asked)."""
    from ctdrill.app.trainee.curve import write_learning_curve
    from ctdrill.app.trainee.record import check_trainee, open_record, record_sessions

    if not args.sessions and args.out is None:
        raise AppInputError(
            "assess: give SESSION_DIR... to store sessions, or --out DIR for the learning curve"
        )
    if args.expert and not args.sessions:
        raise AppInputError("--expert tags stored sessions: give the SESSION_DIR... to store")
    trainee = check_trainee(args.trainee)
    if args.sessions:
        for entry, stored in record_sessions(
            args.db, args.sessions, trainee=trainee, expert=args.expert
        ):
            what = "stored" if stored else "already in the record"
            sys.stdout.write(
                f"{entry.folder}: {what} (session {entry.session_hash[:12]}, score "
                f"{entry.assessment['score']:.1f})\n"
            )
    if args.out is not None:
        record = open_record(args.db, create=False)
        try:
            files = write_learning_curve(record, trainee, args.out)
        finally:
            record.close()
        sys.stdout.write(f"wrote {', '.join(str(f) for f in files)}\n")
    return 0
