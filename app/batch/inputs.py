"""What a row reads and what it wrote: the identities that make a row's output "complete".

A row is complete (``docs/batch.md``, "Resume") when three things hold:

1. its **fingerprint** (:func:`ctdrill.app.batch.task.fingerprint`, computed before the row
   runs) is unchanged: SHA-256 over the export options, the ctdrill version, the CT (every
   file under the row's DICOM folder, or the volume file and a detached header's data file:
   :func:`volume_files`, by relative path and content) and the plan path (a file or a
   folder) by content;
2. every **input the row read** besides those is unchanged: the mask files (a detached
   header's data file too) and the calibration sets its plans name (a bundled set too),
   recorded by the worker before it exports (:func:`row_inputs`), each by
   :func:`file_identity`;
3. every **output** it wrote is there as written: the marker lists each file's size and
   SHA-256 (:func:`output_digests`), checked at resume (:func:`outputs_intact`), so a
   truncated or damaged ``summary.json`` is redone instead of failing forever.

Every file is identified by its content (SHA-256), whatever its size: an edit that keeps the
size and the timestamp (``cp -p``, ``rsync -t``) is seen, a ``touch`` or a copy is not a
change. Size and modification time decide nothing; within one batch a file already hashed is
not hashed again while its device, inode, size and change times are those it was hashed
with (:func:`content_sha256`; the memo is cleared at every batch's start).
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

#: SHA-256 of files hashed in this batch, by what identifies the file on its disk meanwhile:
#: (path, device, inode, size, mtime_ns, ctime_ns) -> hex digest (:func:`content_sha256`).
_DIGESTS: dict[tuple[str, int, int, int, int, int], str] = {}


def forget_digests() -> None:
    """Start a batch with no memo of file contents: every file is hashed again."""
    _DIGESTS.clear()


def content_sha256(path: Path) -> str:
    """SHA-256 of ``path``'s bytes, hex; hashed once per batch while the file's device,
    inode, size and change times stay those it was hashed with (a rewrite changes its ctime,
    which no ``touch`` or ``cp -p`` can set back)."""
    st = path.stat()
    key = (os.path.abspath(path), st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns)
    digest = _DIGESTS.get(key)
    if digest is None:
        digest = _DIGESTS[key] = _sha256(path)
    return digest


def file_identity(path: Path) -> str:
    """``size:sha256:HEX`` of a file's content, whatever its size (a folder: ``tree:`` and
    the SHA-256 of every file under it by relative path, size and content)."""
    if path.is_dir():
        h = hashlib.sha256()
        add_tree(h, "tree", path)
        return "tree:" + h.hexdigest()
    return f"{path.stat().st_size}:sha256:{content_sha256(path)}"


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with path.open("rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _walk(root: Path) -> list[Path]:
    if not root.is_dir():
        return [root]
    out: list[Path] = []
    for dirpath, dirnames, filenames in os.walk(root):
        dirnames.sort()
        out += [Path(dirpath) / f for f in sorted(filenames)]
    return out


def add_tree(h: Any, kind: str, root: Path) -> None:
    """Feed ``h`` every file under ``root`` (or ``root`` itself): relative path, size and the
    SHA-256 of its content (:func:`content_sha256`)."""
    for path in _walk(root):
        st = path.stat()
        rel = path.relative_to(root).as_posix() if path != root else path.name
        h.update(f"{kind}\0{rel}\0{st.st_size}\0".encode())
        h.update(content_sha256(path).encode())
        h.update(b"\n")


def volume_files(path: Path) -> tuple[Path, ...]:
    """The files reading ``path`` opens: a NIfTI, NRRD or MetaImage file and, for a detached
    header (``.nhdr``, ``.mhd``), its data file
    (:func:`ctdrill.imaging.volumes.sniff.files_read`); ``(path,)`` for a folder or any other
    file (a DICOM file, a ``.npy`` mask)."""
    if path.is_dir():
        return (path,)
    from ctdrill.imaging.errors import ImagingInputError
    from ctdrill.imaging.volumes.sniff import files_read

    try:
        return files_read(path, error=ImagingInputError)
    except (ImagingInputError, OSError):
        return (path,)


def row_inputs(plan: Path, calibration: str | None) -> list[Path]:
    """Every file a row reads besides its series and plan path: the mask files of its plans'
    landmarks and the calibration sets it uses (``calibration``, the ``--calibration``
    override, or each plan's own, a bundled set included).

    Raises the readers' input errors for a plan or calibration that cannot be read (the
    row's export then reports the same).
    """
    from ctdrill.engine.plans import plan_calibration_key
    from ctdrill.imaging.plan.load import load_plan_set
    from ctdrill.model.calibration import resolve_calibration_path

    plans = load_plan_set([plan])
    found: dict[str, Path] = {}
    for p in plans:
        for lm in p.landmarks:
            source = getattr(lm, "source", "")  # a mask landmark's file
            for f in volume_files(Path(source)) if source else ():
                found.setdefault(os.path.abspath(f), f)
        key = calibration if calibration is not None else plan_calibration_key(p)
        cal = resolve_calibration_path(key)
        found.setdefault(os.path.abspath(cal), cal)
    return list(found.values())


def input_records(paths: Sequence[Path], base: Path) -> list[list[str]]:
    """``[path relative to base, identity]`` of each input (the marker's ``inputs``)."""
    return [[os.path.relpath(os.path.abspath(p), base), file_identity(p)] for p in paths]


def inputs_unchanged(records: object, base: Path) -> bool:
    """Every recorded input still has its identity (False for a malformed record)."""
    if not isinstance(records, list):
        return False
    for rec in records:
        if not (isinstance(rec, list) and len(rec) == 2 and all(isinstance(x, str) for x in rec)):
            return False
        try:
            if file_identity(base / rec[0]) != rec[1]:
                return False
        except OSError:
            return False
    return True


def output_digests(folder: Path, *, skip: str) -> list[list[Any]]:
    """``[relative path, size, sha256]`` of every file under ``folder`` but ``skip``."""
    out: list[list[Any]] = []
    for path in _walk(folder):
        rel = path.relative_to(folder).as_posix()
        if rel == skip:
            continue
        out.append([rel, path.stat().st_size, _sha256(path)])
    return out


def outputs_intact(records: object, folder: Path) -> bool:
    """Every recorded output is there with its size and content (False when none is)."""
    if not isinstance(records, list) or not records:
        return False
    for rec in records:
        if not (
            isinstance(rec, list)
            and len(rec) == 3
            and isinstance(rec[0], str)
            and isinstance(rec[1], int)
            and isinstance(rec[2], str)
        ):
            return False
        rel = Path(rec[0])
        if rel.is_absolute() or ".." in rel.parts:
            return False
        path = folder / rel
        try:
            if not path.is_file() or path.stat().st_size != rec[1] or _sha256(path) != rec[2]:
                return False
        except OSError:
            return False
    return True
