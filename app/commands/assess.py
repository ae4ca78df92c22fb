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
    p.add_argument("--trainee", default=None, metavar="ID", help="whose sessions")
    p.add_argument(
        "--answer",
        action="extend",
        nargs="+",
        default=[],
        metavar="CLASS",
        help="the bone class (D1-D4) the trainee names for a blind trial's session; once per "
        "SESSION_DIR, in order (docs/exercises.md)",
    )
    p.add_argument(
        "--merge",
        type=Path,
        nargs="+",
        default=[],
        metavar="STATION_DB",
        help="merge these station records into --db (idempotent: sessions are keyed by "
        "their content hash)",
    )
    p.add_argument(
        "--class",
        dest="class_file",
        type=Path,
        default=None,
        metavar="CLASS_FILE",
        help="the class file (ctdrill-class/1) whose roster names the experts: a trainee it "
        "lists as an expert is stored as one, and --out ranks against the roster's experts",
    )
    p.add_argument(
        "--expert",
        action="store_true",
        help="deprecated (name experts in the class file, --class): tag the stored sessions "
        "as an expert's",
    )
    p.add_argument(
        "--out", type=Path, default=None, metavar="DIR", help="write the learning curve here"
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Store the sessions, then write the learning curve (when asked)."""
    from ctdrill.app.trainee.curve import write_learning_curve
    from ctdrill.app.trainee.record import check_trainee, open_record, record_sessions

    if args.merge:
        if args.sessions or args.out is not None or args.answer or args.expert:
            raise AppInputError(
                "--merge merges station records into --db: give it without SESSION_DIR, "
                "--answer, --expert or --out"
            )
        return _merge(args)
    if not args.sessions and args.out is None:
        raise AppInputError(
            "assess: give SESSION_DIR... to store sessions, or --out DIR for the learning curve"
        )
    if args.trainee is None:
        raise AppInputError("assess: give --trainee ID (whose sessions)")
    if args.answer:
        if not args.sessions:
            raise AppInputError("--answer names a blind session's bone: give its SESSION_DIR")
        return _answer(args)
    if args.expert and not args.sessions:
        raise AppInputError("--expert tags stored sessions: give the SESSION_DIR... to store")
    trainee = check_trainee(args.trainee)
    experts = None if args.class_file is None else _roster_experts(args.class_file)
    expert = args.expert or (experts is not None and trainee in experts)
    if args.expert:
        sys.stderr.write(
            "note: --expert is deprecated: the instructor names experts in the class file "
            "(--class CLASS_FILE, roster.experts)\n"
        )
    if args.sessions:
        for entry, stored in record_sessions(
            args.db, args.sessions, trainee=trainee, expert=expert
        ):
            what = "stored" if stored else "already in the record"
            sys.stdout.write(
                f"{entry.folder}: {what} (session {entry.session_hash[:12]}, score "
                f"{entry.assessment['score']:.1f})\n"
            )
    if args.out is not None:
        record = open_record(args.db, create=False)
        try:
            files = write_learning_curve(record, trainee, args.out, experts=experts)
        finally:
            record.close()
        sys.stdout.write(f"wrote {', '.join(str(f) for f in files)}\n")
    return 0


def _answer(args: argparse.Namespace) -> int:
    """Store blind sessions with the classes named for them."""
    from ctdrill.app.trainee.answers import answer_sessions

    for entry, stored, answer, earlier in answer_sessions(
        args.db, args.sessions, args.answer, trainee=args.trainee, expert=args.expert
    ):
        what = "stored" if stored else "already in the record"
        said = (
            f"answered {answer.answer}"
            if earlier is None
            else f"already answered {earlier} (the first answer stands; {answer.answer} ignored)"
        )
        sys.stdout.write(
            f"{entry.folder}: {what} (session {entry.session_hash[:12]}, {answer.exercise} "
            f"{answer.trial}); {said}\n"
        )
    return 0


def _merge(args: argparse.Namespace) -> int:
    """Merge station records into ``--db``."""
    from ctdrill.app.trainee.merge import merge_records

    for count in merge_records(args.db, args.merge):
        extra = f", {count.conflicts} stored for another trainee here" if count.conflicts else ""
        sys.stdout.write(
            f"{count.source}: {count.sessions} sessions, {count.added} new, "
            f"{count.answers_added} answers new{extra}\n"
        )
    return 0


def _roster_experts(path: Path) -> frozenset[str]:
    """The experts a class file's roster names (trainee ids in their stored form)."""
    from ctdrill.app.classroom.class_file import load_class

    return frozenset(load_class(path).experts)
