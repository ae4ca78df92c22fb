"""Outputs that appear whole or not at all: an output folder swapped into place, atomic files.

Every command that writes records (``export``, ``rehearse``, ``calibrate --out``, the GUI's
export) writes through this module, so that a reader (a person, a script, the next command)
sees the old output or the new one, never a mix, and a failure leaves the old output as it
was.

:func:`atomic_output_dir` yields a temporary sibling folder to write into. When the block
ends normally every file and folder in it is flushed to disk (``fsync``) and the folder takes
the place of the output folder:

1. a first output (no folder yet): ``rename(staging, out)``, atomic;
2. an existing folder: ``renameat2(staging, out, RENAME_EXCHANGE)`` swaps the two names in one
   atomic step (Linux 3.15+, ext4/xfs/btrfs/tmpfs), then the old folder, now under the staging
   name, is removed. Readers see the old folder or the new one and never a missing one;
3. where the file system cannot exchange (``EINVAL``/``ENOSYS``: some network or FUSE file
   systems): the old folder is renamed aside, the new one renamed in, the old one removed.
   Between those two renames the output folder is absent for a moment (a reader sees no
   folder, never a mix of files).

Crash windows (``kill -9``, power loss) and what remains:

* before the swap: the output folder is the old one, untouched; the half-written staging
  folder is left over;
* after the swap, before the old folder is removed: the output folder is the new one, whole;
  the old content is left over under a staging name;
* (fallback 3 only) between the two renames: no output folder; the old one is left over under
  an ``old`` name.

Leftovers carry the writing process's id (``.OUT.ctdrill-new-PID-XXXX``,
``.OUT.ctdrill-old-PID-XXXX``). The next write to the same output removes those whose process
is gone (a live one is another run in progress and is left alone) and, in the third window,
renames the old folder back first: after any crash the output is the old folder or the new
one, whole. Staging folders of the earlier export code (``.OUT.staging-XXXX``) are removed
too. Files and folders are ``fsync``-ed before the swap and the parent folder after it, so
the same holds after a power loss on a file system that honours ``fsync``.

The swap replaces the whole folder: files of an earlier output that the new one does not
write disappear with it. So that ``--out ~/Desktop`` can never wipe a folder of other files,
an existing output folder is replaced only when it is empty or holds nothing but files named
in ``owned_names`` (the names ctdrill writes); anything else is refused before anything is
written.

Writing errors become :class:`OutputWriteError` (exit 2, one ``error:`` line) naming the
final file: a full disk (``ENOSPC``, ``EDQUOT``) and a file-size limit (``EFBIG``, e.g.
``ulimit -f``/``RLIMIT_FSIZE``; the CLI ignores ``SIGXFSZ`` so that the limit surfaces as
``EFBIG`` instead of killing the process).
"""

from __future__ import annotations

import contextlib
import ctypes
import errno
import os
import re
import secrets
import shutil
import stat
import sys
from collections.abc import Callable, Collection, Iterator
from pathlib import Path

from ctdrill.app.errors import AppInputError

#: File names ctdrill writes into output folders (export, rehearse): an existing folder
#: holding only these (at any depth) may be replaced by a new output.
OUTPUT_NAMES: frozenset[str] = frozenset(
    {"force.csv", "profile.csv", "summary.json", "force.png", "session.csv", "trajectories.csv"}
    | {"table.json", "display.csv"}  # a session's table (ctdrill assess), the window's display
)

_NEW = "ctdrill-new"
_OLD = "ctdrill-old"
_TMP = "ctdrill-tmp"
_RENAME_EXCHANGE = 2
_AT_FDCWD = -100


class OutputWriteError(AppInputError):
    """An output could not be written (full disk, size limit, permissions): nothing changed."""


def _reason(exc: OSError) -> str:
    """What to do about a failed write, by errno."""
    if exc.errno in (errno.ENOSPC, errno.EDQUOT):
        return "the disk is full (or the quota is used up); free space or write elsewhere"
    if exc.errno == errno.EFBIG:
        return (
            "the file exceeds the file-size limit (ulimit -f / RLIMIT_FSIZE); "
            "raise the limit or write elsewhere"
        )
    if exc.errno in (errno.EACCES, errno.EPERM, errno.EROFS):
        return f"{exc.strerror or exc}; check the folder's permissions or write elsewhere"
    return f"{exc.strerror or exc}; check the path"


def _error(path: Path | str, exc: OSError) -> OutputWriteError:
    return OutputWriteError(f"{path}: cannot write it: {_reason(exc)}")


def write_file(path: Path, data: bytes | str) -> None:
    """Write ``data`` (``str`` as UTF-8) to a new file ``path``, naming it in any error.

    Use it for the files of an :func:`atomic_output_dir` staging folder: a failed ``write``
    then reports the file, which a bare ``OSError`` from ``write`` does not.
    """
    raw = data.encode("utf-8") if isinstance(data, str) else data
    try:
        with open(path, "wb") as fh:
            fh.write(raw)
    except OSError as exc:
        raise OSError(exc.errno, exc.strerror, str(path)) from exc


def _alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True  # another user's live process
    return True


def _leftover_re(name: str, kinds: str) -> re.Pattern[str]:
    return re.compile(rf"\.{re.escape(name)}\.({kinds})-(\d+)-[0-9a-f]+\Z")


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    else:
        with contextlib.suppress(OSError):
            path.unlink()


def clean_leftovers(
    out: Path, *, keep_unfinished: bool = False, notice: Callable[[str], None] | None = None
) -> list[Path]:
    """Remove what crashed writes of ``out`` left beside it; restore a set-aside old folder.

    Only leftovers of processes that are gone are touched. An unfinished output (a staging
    folder with files in it: a run killed before its swap) is never removed without a word:
    ``notice`` (default: a ``note:`` line on stderr) says so, and with ``keep_unfinished`` (a
    rehearsal's ``session.csv`` is a session's only record) it is kept instead, renamed to the
    visible ``NAME.unfinished-PID-XXXX`` beside ``out``. Returns the paths removed.
    """
    say = notice or _note
    out = Path(os.path.abspath(out))
    parent, name = out.parent, out.name
    pattern = _leftover_re(name, f"{_NEW}|{_OLD}|{_TMP}")
    legacy = f".{name}.staging-"
    removed: list[Path] = []
    try:
        entries = sorted(parent.iterdir())
    except OSError:
        return removed
    for entry in entries:
        match = pattern.match(entry.name)
        if match is None:
            if entry.name.startswith(legacy) and entry.is_dir():
                _remove(entry)
                removed.append(entry)
            continue
        pid = int(match.group(2))
        if _alive(pid):
            continue
        if match.group(1) == _OLD and not os.path.lexists(out):
            with contextlib.suppress(OSError):
                os.rename(entry, out)  # the fallback swap died between its two renames
                continue
        unfinished = match.group(1) == _NEW and _has_files(entry)
        if unfinished and keep_unfinished:
            kept = parent / f"{name}.unfinished-{entry.name[len(name) + len(_NEW) + 3 :]}"
            try:
                os.rename(entry, kept)
            except OSError:
                pass
            else:
                say(
                    f"an earlier run (process {pid}, no longer running) left an unfinished "
                    f"output beside {out}; kept as {kept}"
                )
                continue
        _remove(entry)
        removed.append(entry)
        if unfinished:
            say(
                f"removed the unfinished output an earlier run (process {pid}, no longer "
                f"running) left at {entry}"
            )
    return removed


def _has_files(folder: Path) -> bool:
    """``folder`` is a folder with at least one file somewhere in it."""
    if not folder.is_dir() or folder.is_symlink():
        return False
    return any(files for _, _, files in os.walk(folder))


def _note(text: str) -> None:
    sys.stderr.write(f"note: {text}\n")


def _foreign_files(folder: Path, owned: Collection[str]) -> list[Path]:
    found: list[Path] = []
    for root, dirs, files in os.walk(folder):
        dirs.sort()
        links = [d for d in dirs if os.path.islink(os.path.join(root, d))]
        found.extend(Path(root) / d for d in links)  # a link to a folder is not ours
        for f in sorted(files):
            if f not in owned:
                found.append(Path(root) / f)
                if len(found) >= 3:
                    return found
    return found


def _fsync_path(path: Path, *, directory: bool) -> None:
    flags = os.O_RDONLY | (os.O_DIRECTORY if directory else 0)
    fd = os.open(path, flags)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _fsync_tree(top: Path) -> None:
    """fsync every regular file and folder under ``top`` (files first, folders bottom-up)."""
    for root, dirs, files in os.walk(top, topdown=False):
        for f in files:
            p = Path(root) / f
            if stat.S_ISREG(os.lstat(p).st_mode):
                try:
                    _fsync_path(p, directory=False)
                except OSError as exc:
                    raise OSError(exc.errno, exc.strerror, str(p)) from exc
        del dirs
        _fsync_path(Path(root), directory=True)


def _exchange(a: Path, b: Path) -> bool:
    """Atomically swap the names ``a`` and ``b``; False where the system cannot."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        fn = libc.renameat2
    except (OSError, AttributeError):
        return False
    fn.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    fn.restype = ctypes.c_int
    if fn(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE) == 0:
        return True
    err = ctypes.get_errno()
    if err in (errno.EINVAL, errno.ENOSYS, errno.ENOTSUP, errno.EXDEV):
        return False
    raise OSError(err, os.strerror(err), str(b))


def _swap_in(staging: Path, out: Path, token: str) -> None:
    if not os.path.lexists(out):
        os.rename(staging, out)
        return
    if _exchange(staging, out):
        _remove(staging)  # now the old output
        return
    aside = out.parent / f".{out.name}.{_OLD}-{os.getpid()}-{token}"
    os.rename(out, aside)
    try:
        os.rename(staging, out)
    except OSError:
        os.rename(aside, out)
        raise
    _remove(aside)


def _final(path_text: object, staging: Path, out: Path) -> str | None:
    """The final path of a staging file named in an error; None for a path outside it."""
    if not path_text:
        return str(out)
    p = Path(os.path.abspath(os.fsdecode(path_text)))  # type: ignore[arg-type]
    if p == out:
        return str(out)
    try:
        return str(out / p.relative_to(staging))
    except ValueError:
        return None


@contextlib.contextmanager
def atomic_output_dir(
    out_dir: str | os.PathLike[str],
    *,
    owned_names: Collection[str] = OUTPUT_NAMES,
    what: str = "--out",
    keep_unfinished: bool = False,
    notice: Callable[[str], None] | None = None,
) -> Iterator[Path]:
    """Yield a temporary sibling folder of ``out_dir``; on success swap it into its place.

    Parameters
    ----------
    out_dir : the output folder (created with its parents if missing; a symbolic link is
        followed, the folder it names is replaced).
    owned_names : file names an existing ``out_dir`` may hold to be replaced (default: the
        names of ctdrill's export and rehearsal outputs).
    what : how messages name the folder (the option that gave it).
    keep_unfinished, notice : what becomes of an earlier run's unfinished output
        (:func:`clean_leftovers`).

    Yields
    ------
    The empty staging folder (``.NAME.ctdrill-new-PID-XXXX`` beside ``out_dir``). Write every
    file into it (:func:`write_file` names the file in errors).

    Raises
    ------
    OutputWriteError : ``out_dir`` is a file, holds files ctdrill did not write, or writing
        failed (full disk, size limit, permissions); the message names the final file.
        On any error (this or the caller's), the staging folder is removed and ``out_dir``
        is left exactly as it was.
    """
    out = Path(os.path.realpath(out_dir))
    if out.parent == out:
        raise OutputWriteError(f"{what} {out_dir}: cannot replace the root folder; name a folder")
    if os.path.lexists(out) and not out.is_dir():
        raise OutputWriteError(f"{what} {out_dir}: exists and is not a folder; choose a folder")
    if out.is_dir():
        foreign = _foreign_files(out, owned_names)
        if foreign:
            names = ", ".join(str(p.relative_to(out)) for p in foreign)
            raise OutputWriteError(
                f"{what} {out_dir}: the folder holds files ctdrill did not write ({names}); "
                "choose a new or empty folder (the output replaces the folder's content)"
            )
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputWriteError(
            f"{what} {out_dir}: cannot create the folder: {_reason(exc)}"
        ) from exc
    clean_leftovers(out, keep_unfinished=keep_unfinished, notice=notice)
    token = secrets.token_hex(4)
    staging = out.parent / f".{out.name}.{_NEW}-{os.getpid()}-{token}"
    try:
        staging.mkdir()
    except OSError as exc:
        raise _error(out, exc) from exc
    try:
        yield staging
        _fsync_tree(staging)
        _swap_in(staging, out, token)
        _fsync_path(out.parent, directory=True)
    except OSError as exc:
        _remove(staging)
        final = _final(exc.filename, staging, out)
        if final is None:
            raise  # not a write of ours (the caller read something): its own error
        raise _error(final, exc) from exc
    except BaseException:
        _remove(staging)
        raise


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes, *, what: str = "") -> Path:
    """Replace ``path`` with ``data`` atomically: a temporary sibling, fsync, ``os.replace``.

    A reader sees the old file or the new one; a crash leaves the old file (and a temporary
    ``.NAME.ctdrill-tmp-PID-XXXX`` removed by the next write of ``path``). The parent folder
    is created if missing; an existing file keeps its permission bits.

    Parameters
    ----------
    path : the file (a symbolic link is followed: the file it names is replaced).
    data : the new content.
    what : how messages name the file (e.g. ``"--out"``), prefixed to the path.

    Returns
    -------
    The path written (links resolved).

    Raises
    ------
    OutputWriteError : ``path`` is a folder, or writing failed (full disk, size limit,
        permissions); ``path`` is then unchanged.
    """
    label = f"{what} {path}" if what else str(path)
    target = Path(os.path.realpath(path))
    if target.is_dir():
        raise OutputWriteError(f"{label}: is a folder; give a file path")
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputWriteError(f"{label}: cannot create its folder: {_reason(exc)}") from exc
    clean_leftovers(target)
    tmp = target.parent / f".{target.name}.{_TMP}-{os.getpid()}-{secrets.token_hex(4)}"
    try:
        mode = stat.S_IMODE(os.stat(target).st_mode) if target.exists() else None
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
        try:
            view = memoryview(data)
            while view:
                view = view[os.write(fd, view) :]
            if mode is not None:
                os.fchmod(fd, mode)
            os.fsync(fd)
        finally:
            os.close(fd)
        os.replace(tmp, target)
        _fsync_path(target.parent, directory=True)
    except OSError as exc:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise OutputWriteError(f"{label}: cannot write it: {_reason(exc)}") from exc
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise
    return target


def atomic_write_text(
    path: str | os.PathLike[str], text: str, *, what: str = "", encoding: str = "utf-8"
) -> Path:
    """:func:`atomic_write_bytes` of ``text`` encoded (UTF-8 by default)."""
    return atomic_write_bytes(path, text.encode(encoding), what=what)
