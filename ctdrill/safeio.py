"""Reading user-named input files safely: regular files only, bounded size, bounded JSON.

Every room reads files a user names (plans, markups, masks, calibration sets, recordings,
operator scripts). A path that is a FIFO blocks ``open`` forever; ``/dev/zero`` reads until
memory runs out; a JSON document nested 1000 deep raises ``RecursionError`` and an integer of
4300+ digits ``ValueError`` from the standard library; a key given twice in one object silently
takes its last value (a ``margin_mm`` of 2.0 then 0.0 ran with 0). These helpers refuse each of
them with the caller's own input-error type, naming the file and what to do, before anything
is used.

This module belongs to no room: ``imaging``, ``model``, ``haptics`` and ``app`` all use it, and
it imports nothing of theirs.
"""

from __future__ import annotations

import io
import json
import os
import re
import stat
from typing import Any

#: Largest JSON document read (plans, markups, calibration sets), bytes.
MAX_JSON_BYTES = 64 * 1024 * 1024
#: Deepest nesting of arrays and objects accepted in a JSON document (a plan needs 4).
MAX_JSON_DEPTH = 64

ErrorType = type[Exception]


def regular_file_size(path: str | os.PathLike[str], *, what: str, error: ErrorType) -> int:
    """Size in bytes of ``path`` after checking, without opening it, that it is a regular file.

    Parameters
    ----------
    path : the file a user named.
    what : what the file is for, used in the message (``"plan file"``, ``"mask"``).
    error : the exception type raised (the caller's room's input error).

    Raises
    ------
    error : the path is missing, not a regular file (folder, FIFO, device, socket) or
        cannot be examined.
    """
    try:
        st = os.stat(path)
    except FileNotFoundError as exc:
        raise error(f"{path}: {what} not found; check the path") from exc
    except (OSError, ValueError) as exc:
        raise error(f"{path}: cannot examine the {what} ({_reason(exc)}); check the path") from exc
    if not stat.S_ISREG(st.st_mode):
        kind = _kind(st.st_mode)
        raise error(f"{path}: the {what} is {kind}, not a regular file; name a file")
    if st.st_dev in _pseudo_devices():
        raise error(
            f"{path}: the {what} is a kernel pseudo-file (/proc, /sys), not a data file; "
            "name a file"
        )
    return int(st.st_size)


#: Kernel pseudo-file systems: their "regular files" (``/proc/self/mem``, ``/sys/...``) are
#: not data (a size of 0 or 4096 that says nothing, reads that fail or never end).
_PSEUDO_ROOTS = ("/proc", "/sys")


def _pseudo_devices() -> frozenset[int]:
    out = set()
    for root in _PSEUDO_ROOTS:
        try:
            out.add(os.stat(root).st_dev)
        except OSError:
            continue
    return frozenset(out)


def open_regular(path: str | os.PathLike[str], *, what: str, error: ErrorType) -> io.BufferedReader:
    """``path`` opened for binary reading, refused unless the opened file is a regular file.

    The file is opened with ``O_NONBLOCK`` (opening a FIFO or a device never waits) and the
    *opened descriptor* is examined with ``fstat``: a path swapped for a FIFO, a device or a
    folder between any earlier check and this open is refused, never read. Kernel pseudo-files
    (``/proc``, ``/sys``: ``/proc/self/mem`` claims to be a regular file) are refused too.
    Every reader of a file a user names opens it here.

    Parameters
    ----------
    path : the file a user named.
    what : what the file is for, used in the message (``"plan file"``, ``"mask"``).
    error : the exception type raised (the caller's room's input error).

    Returns
    -------
    A binary file object positioned at 0 (close it; ``with`` works).
    """
    flags = os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_NOCTTY", 0) | getattr(os, "O_CLOEXEC", 0)
    try:
        fd = os.open(path, flags)
    except FileNotFoundError as exc:
        raise error(f"{path}: {what} not found; check the path") from exc
    except IsADirectoryError as exc:
        raise error(f"{path}: the {what} is a folder, not a regular file; name a file") from exc
    except (OSError, ValueError) as exc:
        raise error(f"{path}: cannot open the {what} ({_reason(exc)}); check the path") from exc
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise error(
                f"{path}: the {what} is {_kind(st.st_mode)}, not a regular file; name a file"
            )
        if st.st_dev in _pseudo_devices():
            raise error(
                f"{path}: the {what} is a kernel pseudo-file (/proc, /sys), not a data file; "
                "name a file"
            )
        fh = os.fdopen(fd, "rb")
        assert isinstance(fh, io.BufferedReader)
        return fh
    except BaseException:
        os.close(fd)
        raise


def read_bytes_bounded(
    path: str | os.PathLike[str], *, what: str, error: ErrorType, max_bytes: int
) -> bytes:
    """The bytes of a regular file of at most ``max_bytes``, refused otherwise.

    The size is checked before reading and the read stops one byte past the limit, so a file
    that grows meanwhile is refused too.
    """
    with open_regular(path, what=what, error=error) as fh:
        size = os.fstat(fh.fileno()).st_size
        if size > max_bytes:
            raise error(
                f"{path}: the {what} holds {size} bytes, more than the {max_bytes} accepted; "
                "check that this is the right file"
            )
        try:
            data = fh.read(max_bytes + 1)
        except OSError as exc:
            raise error(
                f"{path}: cannot read the {what} ({_reason(exc)}); check its permissions"
            ) from exc
    if len(data) > max_bytes:
        raise error(f"{path}: the {what} grew past {max_bytes} bytes while being read")
    return data


def load_json(
    path: str | os.PathLike[str],
    *,
    what: str,
    error: ErrorType,
    max_bytes: int = MAX_JSON_BYTES,
    max_depth: int = MAX_JSON_DEPTH,
) -> Any:
    """Parse a UTF-8 JSON file, refusing non-regular files, oversize, deep nesting, huge ints.

    Parameters
    ----------
    path : the JSON file.
    what : what the file is for, used in messages.
    error : the exception type raised.
    max_bytes : largest file accepted.
    max_depth : deepest nesting of arrays/objects accepted (checked before parsing, so the
        parser never recurses past it).

    Returns
    -------
    The parsed document (``dict``, ``list``, ...). ``NaN`` and ``Infinity`` are refused, and
    so is a key given twice in one object (the message names the key and the file).
    """
    data = read_bytes_bounded(path, what=what, error=error, max_bytes=max_bytes)
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise error(
            f"{path}: the {what} is not UTF-8 text ({exc.reason} at byte {exc.start})"
        ) from exc
    return loads_json(text, where=str(path), what=what, error=error, max_depth=max_depth)


def loads_json(
    text: str, *, where: str, what: str, error: ErrorType, max_depth: int = MAX_JSON_DEPTH
) -> Any:
    """Parse JSON text with the checks of :func:`load_json`; ``where`` names it in messages."""
    depth = json_nesting_depth(text)
    if depth > max_depth:
        raise error(
            f"{where}: the {what} nests arrays/objects {depth} deep (at most {max_depth}); "
            "this is not a document ctdrill writes or reads"
        )

    def _constant(name: str) -> Any:
        raise ValueError(f"{name} is not a JSON number")

    try:
        return json.loads(text, parse_constant=_constant, object_pairs_hook=_unique_keys)
    except DuplicateKeyError as exc:
        raise error(
            f"{where}: the {what} gives the key {exc.key!r} twice in one object "
            f"({_short(exc.first)}, then {_short(exc.second)}); JSON readers disagree on which "
            "one counts, so keep one"
        ) from None
    except json.JSONDecodeError as exc:
        raise error(
            f"{where}: the {what} is not valid JSON (line {exc.lineno}, column {exc.colno}: "
            f"{exc.msg}); fix the file"
        ) from exc
    except (ValueError, RecursionError) as exc:
        # ValueError: an integer beyond the interpreter's digit limit, NaN/Infinity.
        raise error(f"{where}: the {what} holds a value that cannot be read ({exc})") from exc


class DuplicateKeyError(ValueError):
    """A JSON object gives one key twice (raised while parsing)."""

    def __init__(self, key: str, first: object, second: object) -> None:
        super().__init__(f"key {key!r} given twice")
        self.key, self.first, self.second = key, first, second


def _unique_keys(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    """``object_pairs_hook`` building an object, refusing a key given twice."""
    out: dict[str, Any] = {}
    for key, value in pairs:
        if key in out:
            raise DuplicateKeyError(key, out[key], value)
        out[key] = value
    return out


def _short(value: object, limit: int = 40) -> str:
    """A value for a message: its JSON text, cut to ``limit`` characters."""
    text = json.dumps(value, ensure_ascii=False)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def json_nesting_depth(text: str) -> int:
    """Deepest nesting of ``[``/``{`` in JSON text, brackets inside strings ignored."""
    depth = best = 0
    for match in _BRACKET_OR_STRING.finditer(text):
        token = match.group(0)
        if token in "[{":
            depth += 1
            best = max(best, depth)
        elif token in "]}":
            depth -= 1
    return best


#: A JSON string (skipped whole, escapes included) or one bracket.
_BRACKET_OR_STRING = re.compile(r'"(?:[^"\\]|\\.)*"?|[\[\]{}]')


def _kind(mode: int) -> str:
    if stat.S_ISDIR(mode):
        return "a folder"
    if stat.S_ISFIFO(mode):
        return "a named pipe (FIFO)"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a regular file"


def _reason(exc: BaseException) -> str:
    if isinstance(exc, OSError) and exc.strerror:
        return exc.strerror
    return str(exc)
