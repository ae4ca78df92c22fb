"""Find the DICOM image files under a path and read their headers (never the pixels).

A file is DICOM when it has the 128-byte preamble followed by ``DICM``. A file without a
preamble is accepted only when it starts like a DICOM dataset (a group 0x0002 or 0x0008 tag) and
then parses with the tags an image needs; anything else is ignored as not DICOM. Headers are read
with ``stop_before_pixels``; the byte offset of uncompressed pixel data is recorded so that the
pixels can later be read straight into the volume.

What a header holds becomes planes in :mod:`ctdrill.imaging.dicom.planes`; the plane and scan
types (:class:`SliceHeader`, :class:`Skipped`, :class:`ScanResult`) live in
:mod:`ctdrill.imaging.dicom.slice_header` and are importable from here too.
"""

from __future__ import annotations

import collections
import os
import stat
import struct
import warnings
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from ctdrill.imaging.dicom.fastheader import HeaderCorruptError, read_fast_header
from ctdrill.imaging.dicom.planes import classify
from ctdrill.imaging.dicom.slice_header import (
    EXPLICIT_VR_LITTLE_ENDIAN,
    IMPLICIT_VR_LITTLE_ENDIAN,
    MULTIFRAME_CT_SOP_CLASSES,
    ScanResult,
    Skipped,
    SliceHeader,
)
from ctdrill.imaging.errors import ImagingInputError
from ctdrill.safeio import open_regular

#: At most this many bytes are announced to the kernel for read-ahead per scan.
PREFETCH_BYTES = 1 << 30
_PIXEL_TAG = b"\xe0\x7f\x10\x00"
_LONG_VRS = {b"OB", b"OW", b"OF", b"OD", b"OL", b"OV", b"UN", b"SQ", b"UC", b"UR", b"UT", b"SV"}


class DiscoveryInputError(ImagingInputError):
    """The path holds no readable DICOM image."""


#: A DICOM file this many levels below a folder (or less) makes it a series folder
#: (PATIENT/STUDY/SERIES/IM: level 3; a DICOMDIR: level 1).
NEAR_TOP_LEVELS = 4
#: A folder holding more entries than this (files and folders, on its own file system)
#: without a DICOM file near the top is refused: a file-system root or a home folder.
MAX_ENTRIES_WITHOUT_DICOM = 20_000
#: Most files whose first bytes the check reads.
MAX_FILES_EXAMINED = 2_000


def check_series_folder(path: Path) -> None:
    """Refuse a folder that is not a series folder, before walking all of it.

    The folder is examined breadth first, on its own file system (links to folders and other
    mounts are not entered, as ``find -xdev``). A non-empty regular file at most
    :data:`NEAR_TOP_LEVELS` levels down that starts like DICOM (:func:`_looks_like_dicom`;
    the first :data:`MAX_FILES_EXAMINED` files are read) makes it a series folder. Without
    one, a folder of more than :data:`MAX_ENTRIES_WITHOUT_DICOM` entries is refused: ``/``
    or a home folder would otherwise be walked whole (150 s and more); a smaller one is left
    to the scan, which says what it found.

    The file system's root and the user's home folder are refused whatever they hold.

    Raises
    ------
    DiscoveryInputError
        The root or a home folder, or more than :data:`MAX_ENTRIES_WITHOUT_DICOM` entries and
        no DICOM file near the top.
    """
    if not path.is_dir():
        return
    if _is_root_or_home(path):
        raise DiscoveryInputError(
            f"{path}: not a series folder: it is the file system's root or a home folder, "
            "whatever lies under it; name the folder of one series (or one of its files)"
        )
    device = path.stat().st_dev
    queue = collections.deque([(path, 1)])
    read = entries = 0
    while queue:
        folder, level = queue.popleft()
        try:
            with os.scandir(folder) as it:
                listed = sorted(it, key=lambda e: e.name)
        except OSError:
            continue  # an unreadable folder: the scan reports it (files_unreadable)
        for entry in listed:
            entries += 1
            if entries > MAX_ENTRIES_WITHOUT_DICOM:
                raise DiscoveryInputError(
                    f"{path}: not a series folder: it holds more than "
                    f"{MAX_ENTRIES_WITHOUT_DICOM} files and folders and no DICOM file in its "
                    f"top {NEAR_TOP_LEVELS} levels; name the folder of one series (or one of "
                    "its files)"
                )
            try:
                if entry.is_dir(follow_symlinks=False):
                    if entry.stat(follow_symlinks=False).st_dev == device:
                        queue.append((Path(entry.path), level + 1))
                elif (
                    level <= NEAR_TOP_LEVELS
                    and read < MAX_FILES_EXAMINED
                    and entry.is_file()
                    and entry.stat().st_size > 0
                ):
                    read += 1
                    if _looks_like_dicom(Path(entry.path)) is not False:
                        return
            except OSError:
                pass


def _is_root_or_home(path: Path) -> bool:
    """True for the file system's root (``/``) and the user's home folder, links resolved.

    Neither is a series folder even when a DICOM file lies near its top (a series left in a
    temporary folder would otherwise make ``/`` one); a mounted disc is not refused here."""
    try:
        where = path.resolve()
        home = Path.home().resolve()
    except (OSError, RuntimeError):
        return False
    return where == Path(where.anchor) or where == home


def iter_files(path: Path, unreadable: list[Path] | None = None) -> Iterator[Path]:
    """Every non-directory entry under ``path`` (or ``path`` itself), in a stable order.

    Folders that cannot be listed (permission denied) are appended to ``unreadable`` when
    given, so that a caller can say so instead of loading part of a series silently.
    """
    if not path.is_dir():  # one file (or a pipe or device: the caller checks before opening)
        yield path
        return

    def _onerror(exc: OSError) -> None:
        if unreadable is not None:
            unreadable.append(Path(exc.filename) if exc.filename else path)

    for root, dirs, files in os.walk(path, onerror=_onerror):
        dirs.sort()
        for name in sorted(files):
            yield Path(root) / name


def _is_regular_file(path: Path) -> bool:
    """True when ``path`` (links followed) is a regular file; never opens it."""
    try:
        return stat.S_ISREG(os.stat(path).st_mode)
    except OSError:
        return False


def _looks_like_dicom(path: Path) -> bool | None:
    """True: preamble + DICM; None: maybe a preamble-less dataset; False: not DICOM.

    Raises
    ------
    OSError
        The file cannot be opened or read (e.g. permission denied).
    """
    with open_regular(path, what="DICOM file", error=OSError) as fh:
        head = fh.read(132)
    if len(head) == 132 and head[128:132] == b"DICM":
        return True
    if len(head) >= 8 and head[:2] in (b"\x02\x00", b"\x08\x00"):
        return None
    return False


def _pixel_offset(fh: Any, implicit: bool) -> tuple[int | None, int | None, bool]:
    """(offset, declared length) of native pixel data at the file position, and presence."""
    pos = fh.tell()
    head = fh.read(12)
    if len(head) < 8 or head[:4] != _PIXEL_TAG:
        return None, None, False
    if implicit:
        length = struct.unpack("<I", head[4:8])[0]
        start = pos + 8
    elif head[4:6] in _LONG_VRS:
        length = struct.unpack("<I", head[8:12])[0]
        start = pos + 12
    else:
        length = struct.unpack("<H", head[6:8])[0]
        start = pos + 8
    if length == 0xFFFFFFFF:
        return None, None, True  # encapsulated
    return start, length, length > 0


#: Exceptions pydicom raises (often lazily, on first access) for a damaged header, besides its
#: own ``InvalidDicomError`` and ``BytesLengthException`` (:func:`_pydicom_header`).
_HEADER_ERRORS = (
    OSError,
    ValueError,
    EOFError,
    struct.error,
    TypeError,
    KeyError,
    AttributeError,
    IndexError,
    OverflowError,
    NotImplementedError,
    MemoryError,
    RecursionError,
)


def read_headers(
    path: Path, *, ct_only: bool = True, fast: bool = True
) -> list[SliceHeader] | Skipped | None:
    """Header(s) of one file: a list of planes, a :class:`Skipped`, or None when not DICOM.

    Raises ``OSError`` when the file cannot be opened at all (permission denied): the caller
    counts it as unreadable, never as "not DICOM".

    ``ct_only=False`` also returns the planes of non-CT images (used to test decoding).
    ``fast=False`` forces pydicom instead of :mod:`ctdrill.imaging.dicom.fastheader` (tests
    compare).
    """
    kind = _looks_like_dicom(path)
    if kind is False:
        return None
    if kind is True and fast:
        try:
            got = read_fast_header(path)
        except HeaderCorruptError as exc:
            return Skipped(path, f"corrupt DICOM header ({exc})")
        if got is not None and str(got.tags.get("SOPClassUID", "")) not in (
            MULTIFRAME_CT_SOP_CLASSES
        ):
            return classify(
                path,
                got.tags,
                got.transfer_syntax,
                (got.pixel_offset, got.pixel_length, got.has_pixels, got.file_size),
                ct_only,
            )
    return _pydicom_header(path, kind, ct_only)


def _pydicom_header(
    path: Path, kind: bool | None, ct_only: bool
) -> list[SliceHeader] | Skipped | None:
    """:func:`read_headers` by pydicom (imported here: 0.2 s, which the fast reader's files,
    most CT series, never need)."""
    from pydicom import dcmread
    from pydicom.errors import BytesLengthException, InvalidDicomError
    from pydicom.uid import DeflatedExplicitVRLittleEndian

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            with open_regular(path, what="DICOM file", error=OSError) as fh:
                ds = dcmread(fh, stop_before_pixels=True, force=kind is None)
                implicit, little = ds.original_encoding
                offset, length, has_pixels = _pixel_offset(fh, bool(implicit))
            if kind is None and not ("SOPClassUID" in ds and "Rows" in ds and "Columns" in ds):
                return None
            meta = getattr(ds, "file_meta", None)
            ts = str(meta.get("TransferSyntaxUID", "")) if meta is not None else ""
            if not ts:
                ts = IMPLICIT_VR_LITTLE_ENDIAN if implicit else EXPLICIT_VR_LITTLE_ENDIAN
            if not little:
                offset = length = None
            if ts == DeflatedExplicitVRLittleEndian:
                # The file position is in the deflated stream: ask the inflated dataset.
                full = dcmread(path)
                offset = length = None
                has_pixels = "PixelData" in full or "FloatPixelData" in full
            size = path.stat().st_size
            return classify(path, ds, ts, (offset, length, has_pixels, size), ct_only)
    except (InvalidDicomError, BytesLengthException, *_HEADER_ERRORS) as exc:
        if kind is None:
            return None
        return Skipped(path, f"unreadable DICOM header ({type(exc).__name__})")


def _prefetch(files: list[Path]) -> None:
    """Ask the kernel to start reading every file now, so that cold reads overlap."""
    advise = getattr(os, "posix_fadvise", None)
    if advise is None:
        return
    budget = PREFETCH_BYTES
    for file in files:
        try:
            fd = os.open(file, os.O_RDONLY)
        except OSError:
            continue
        try:
            size = os.fstat(fd).st_size
            if size <= budget:
                advise(fd, 0, size, os.POSIX_FADV_WILLNEED)
                budget -= size
        except OSError:
            pass
        finally:
            os.close(fd)
        if budget <= 0:
            return


def scan(path: str | Path) -> ScanResult:
    """Read the headers of every DICOM file under ``path``.

    Raises
    ------
    DiscoveryInputError
        ``path`` does not exist.
    """
    root = Path(path)
    if not root.exists():
        raise DiscoveryInputError(f"{root}: no such file or folder; give a DICOM series folder")
    check_series_folder(root)
    headers: list[SliceHeader] = []
    skipped: list[Skipped] = []
    not_dicom: list[Path] = []
    files: list[Path] = []
    unreadable: list[Path] = []
    for file in iter_files(root, unreadable):
        if _is_regular_file(file):
            files.append(file)
        else:  # a pipe, device or socket would block or never end: never open it
            skipped.append(Skipped(file, "not a regular file (pipe, device or socket)"))
    _prefetch(files)
    for file in files:
        try:
            got = read_headers(file)
        except OSError:
            unreadable.append(file)
            continue
        if got is None:
            not_dicom.append(file)
        elif isinstance(got, Skipped):
            skipped.append(got)
        else:
            headers.extend(got)
    return ScanResult(tuple(headers), tuple(skipped), tuple(not_dicom), tuple(unreadable))
