"""The ``ctdrill`` command line: one subcommand per module in :mod:`ctdrill.app.commands`.

Every subcommand module exposes ``register(subparsers) -> None``; the parser it adds sets
``func`` (``Callable[[argparse.Namespace], int]``). Bad input raises one of the packages'
``*InputError`` types and becomes one ``error:`` line on stderr with exit code 2; anything
else is a bug and keeps its traceback (exit code 1).
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

from ctdrill.app.errors import INPUT_ERRORS

#: Subcommands in the order ``ctdrill --help`` lists them.
COMMANDS: tuple[str, ...] = (
    "inspect",
    "phantom",
    "export",
    "report",
    "batch",
    "plan",
    "suggest",
    "panorama",
    "demo",
    "calibrate",
    "rehearse",
    "teleop",
    "assess",
    "exercise",
    "class",
    "emulate",
    "gui",
    "warmup",
)


#: Subcommands whose module has another name (``class`` is a Python keyword).
_MODULES = {"class": "classroom"}


def command_module(command: str) -> str:
    """The module under ctdrill.app.commands that defines ``command``."""
    return _MODULES.get(command, command)


class _Parser(argparse.ArgumentParser):
    """Argument parser whose usage errors follow the ``error:`` / exit 2 contract."""

    def error(self, message: str) -> None:  # type: ignore[override]
        sys.stderr.write(f"error: {self.prog}: {message} (see '{self.prog} --help')\n")
        raise SystemExit(2)


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    """Return the full ``ctdrill`` parser with every available subcommand (``only``: with
    that one alone, which parses its own command line the same; the others' modules are not
    imported, 20-30 ms of a fresh ``ctdrill export``)."""
    parser = _Parser(
        prog="ctdrill",
        description="Rehearse a dental-implant osteotomy on the patient's own CT.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True
    for name in COMMANDS if only is None else (only,):
        try:
            module = importlib.import_module(f"ctdrill.app.commands.{command_module(name)}")
        except ModuleNotFoundError as exc:
            # A command module not written yet: tests/test_cli.py fails until each exists.
            if exc.name != f"ctdrill.app.commands.{command_module(name)}":
                raise
            continue
        module.register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``ctdrill`` with ``argv`` (default: ``sys.argv[1:]``) and return the exit code.

    SIGTERM and SIGHUP are taken as Ctrl-C (:mod:`ctdrill.interrupts`): exit ``128 + signal``
    (130 Ctrl-C, 143 SIGTERM, 129 SIGHUP), the command's records written as after Ctrl-C.
    """
    from ctdrill.interrupts import exit_code_of, install, signal_name, signum_of

    install()
    try:
        words = sys.argv[1:] if argv is None else list(argv)
        only = words[0] if words and words[0] in COMMANDS else None
        args = build_parser(only).parse_args(words)
    except KeyboardInterrupt as exc:  # Ctrl-C while the command starts: no traceback either
        sys.stderr.write(f"error: interrupted ({signal_name(signum_of(exc))})\n")
        return exit_code_of(exc)
    _ignore_file_size_signal()
    try:
        from ctdrill.app.exercise.blind import guard_args

        guard_args(args)  # a blind trial's plan or CT: what this command may do with it
        code: int = args.func(args)
    except INPUT_ERRORS as exc:
        sys.stderr.write(f"error: {exc}\n")
        return 2
    except OSError as exc:
        # The operating system refused a path the user gave (name too long, permission, a
        # full disk): bad input or environment, not a bug.
        where = f"{exc.filename}: " if exc.filename else ""
        reason = exc.strerror or str(exc)
        sys.stderr.write(f"error: {where}{reason}; check the path and its permissions\n")
        return 2
    except KeyboardInterrupt as exc:
        sys.stderr.write(f"error: interrupted ({signal_name(signum_of(exc))})\n")
        return exit_code_of(exc)
    return code


def _ignore_file_size_signal() -> None:
    """Let a file-size limit (``ulimit -f``) surface as ``EFBIG``, an ``error:`` line naming
    the file, instead of ``SIGXFSZ`` killing the process mid-write (the default action)."""
    import signal
    import threading

    if hasattr(signal, "SIGXFSZ") and threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
